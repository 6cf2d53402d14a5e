//! Step-size guidance: the linearisation finds the known frequencies, and
//! the suggested step gives the requested frequency error.

use lagrangian::guidance::{GuidanceError, Rule, linearize, suggest_step};
use lagrangian::prelude::*;
use lagrangian::{Event, Plan};

#[derive(Clone)]
struct Spring {
    k: f64,
}

#[lagrangian]
impl Spring {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] - 0.5 * self.k * q[0] * q[0]
    }
}

/// Two masses, a soft and a stiff spring (frequencies 1 and 40).
#[derive(Clone)]
struct TwoScales;

#[lagrangian]
impl TwoScales {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) - 0.5 * q[0] * q[0] - 0.5 * 1600.0 * q[1] * q[1]
    }
}

struct Inverted;

#[lagrangian]
impl Inverted {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] - 4.0 * q[0].cos()
    }
}

struct Free;

#[lagrangian]
impl Free {
    fn lagrangian(&self, _q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0]
    }
}

#[test]
fn the_linearisation_finds_frequencies_and_growth_rates() {
    let lin = linearize(&TwoScales, 0.0, [0.3, 0.01], [0.0, 0.0]).unwrap();
    assert_eq!(lin.frequencies.len(), 2);
    assert!((lin.frequencies[0] - 40.0).abs() < 1e-6 && (lin.frequencies[1] - 1.0).abs() < 1e-6, "{lin:?}");
    assert!((lin.fastest - 40.0).abs() < 1e-6);
    // The inverted pendulum at the top grows at rate 2.
    let lin = linearize(&Inverted, 0.0, [0.0], [0.0]).unwrap();
    assert!(lin.frequencies.is_empty() && (lin.growth_rates[0] - 2.0).abs() < 1e-6, "{lin:?}");
    assert_eq!(suggest_step(&Free, (0.0, [0.0], [1.0]), Rule::midpoint(), 1e-4), Err(GuidanceError::NoTimeScale));
    assert!(matches!(
        suggest_step(&Spring { k: 1.0 }, (0.0, [1.0], [0.0]), Rule::midpoint(), 0.0),
        Err(GuidanceError::InvalidTolerance { .. })
    ));
    assert!(matches!(linearize(&Spring { k: 1.0 }, 0.0, [f64::NAN], [0.0]), Err(GuidanceError::NoAcceleration)));
}

/// The period measured by zero crossings: its relative error is the
/// tolerance asked for (within 15%, the next term of the series), for the
/// midpoint rule and Galerkin s = 2.
#[test]
fn the_suggested_step_gives_the_requested_frequency_error() {
    let k: f64 = 256.0; // ω = 16: the spring ran at ωh ≈ 16 with h = 1
    let omega = k.sqrt();
    for tol in [1e-3, 1e-5] {
        let advice = suggest_step(&Spring { k }, (0.0, [1.0], [0.0]), Rule::midpoint(), tol).unwrap();
        assert!((advice.linearization.fastest - omega).abs() < 1e-6);
        let mut sim = Integrator::new(Spring { k }, Midpoint, advice.h).start(0.0, [1.0], [0.0]).unwrap();
        let period = measured_period(sim.solve(Plan::until(20.0).every(0).event(Event::new(|_, q, _| q[0]))).unwrap());
        let error = (2.0 * std::f64::consts::PI / omega - period).abs() / period;
        println!("midpoint, tol {tol:e}: h = {:.3e}, ωh = {:.3e}, period error {error:.3e}", advice.h, advice.omega_h);
        assert!((error / tol - 1.0).abs() < 0.15, "tol {tol}: error {error}");

        let advice = suggest_step(&Spring { k }, (0.0, [1.0], [0.0]), Rule::galerkin_gauss(2), tol).unwrap();
        let mut sim = GalerkinIntegrator::new(Spring { k }, Galerkin::<2, 2>::gauss(), advice.h)
            .start(0.0, [1.0], [0.0])
            .unwrap();
        let plan = Plan::until(20.0).every(0).dense(lagrangian::DenseKind::Quintic).event(Event::new(|_, q, _| q[0]));
        let period = measured_period(sim.solve(plan).unwrap());
        let error = (2.0 * std::f64::consts::PI / omega - period).abs() / period;
        println!(
            "galerkin s = 2, tol {tol:e}: h = {:.3e}, ωh = {:.3e}, period error {error:.3e}",
            advice.h, advice.omega_h
        );
        assert!((error / tol - 1.0).abs() < 0.15, "tol {tol}: error {error}");
    }
}

/// The mean period from the first to the last zero crossing.
fn measured_period(sol: lagrangian::Solution) -> f64 {
    let (first, last) = (sol.events[0].t, sol.events.last().unwrap().t);
    2.0 * (last - first) / (sol.events.len() - 1) as f64
}
