//! The explicit time-transformed splitting stops with a typed error where it
//! loses the orbit (a radial Kepler infall with `f'(x) = x^{−1/2}`, which no
//! step σ resolves), keeps the collision orbit the logarithmic form passes,
//! and names the cause of a start at the singularity. The implicit driver's
//! errors name the fictitious time `s`.
#![allow(missing_docs)]

use lagrangian_runtime::time_transform::{ExplicitTimeTransformed, RadiusPower, TimeFunction, TimeTransformed};
use lagrangian_runtime::{Composition, Error, Lagrangian, Midpoint, Scalar, Separability};

/// Kepler, `L = ½|v|² + 1/|q|`.
#[derive(Clone, Debug)]
struct Kepler;
impl Lagrangian<2> for Kepler {
    const AUTONOMOUS: bool = true;
    const CYCLIC: [bool; 2] = [false; 2];
    const SEPARABILITY: Separability = Separability::ConstantMass;
    fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 2], v: [D; 2]) -> D {
        (v[0] * v[0] + v[1] * v[1]) * 0.5 + (q[0] * q[0] + q[1] * q[1]).sqrt().recip()
    }
}

/// The collision time of the fall from r = 1 at rest: π/(2√2).
const COLLISION: f64 = 1.110_720_734_539_591_6;

#[test]
fn a_radial_infall_with_a_square_root_time_function_is_a_typed_error() {
    for composition in [None, Some(Composition::KAHAN_LI8)] {
        for sigma in [0.2, 0.05, 0.01] {
            let mut b = ExplicitTimeTransformed::new(Kepler, TimeFunction::Power(0.5), sigma);
            if let Some(c) = composition {
                b = b.composition(c);
            }
            let mut sim = b.start(0.0, [1.0, 0.0], [0.0, 0.0]).unwrap();
            let mut last = (sim.state(), sim.extended_point());
            let err = sim
                .run_until(2.0, |s| last = (s.state(), s.extended_point()))
                .expect_err("the infall cannot pass the collision with f' = x^(-1/2)");
            let label = format!("σ = {sigma}, {composition:?}");
            assert!(matches!(err, Error::OrbitLost { .. }), "{label}: {err:?}");
            // The failed step changed nothing, and fails again the same way.
            assert_eq!((sim.state(), sim.extended_point()), last, "{label}");
            let Error::OrbitLost { state, factor } = err.clone() else { unreachable!() };
            assert_eq!(state, last.0, "{label}");
            assert!(!(0.5..=2.0).contains(&factor), "{label}: {factor}");
            assert!(state.t < COLLISION + 0.01 && state.t > 1.0, "{label}: {state:?}");
            assert_eq!(sim.step().unwrap_err(), err, "{label}");
            assert_eq!((sim.state(), sim.extended_point()), last, "{label}");
        }
    }
}

/// The logarithmic Hamiltonian (`dt/ds = r`) passes the same collision with
/// the energy kept at its nodes: the check does not trip on it.
#[test]
fn the_logarithmic_form_passes_the_collision() {
    for composition in [None, Some(Composition::KAHAN_LI8)] {
        let mut b = ExplicitTimeTransformed::new(Kepler, TimeFunction::Logarithmic, 0.05);
        if let Some(c) = composition {
            b = b.composition(c);
        }
        let mut sim = b.start(0.0, [1.0, 0.0], [0.0, 0.0]).unwrap();
        sim.run_until(2.0, |_| {}).unwrap();
        assert!((sim.energy() + 1.0).abs() < 1e-12, "{composition:?}: {}", sim.energy());
    }
}

#[test]
fn a_start_at_the_singularity_names_it() {
    let err = ExplicitTimeTransformed::new(Kepler, TimeFunction::Logarithmic, 0.05)
        .start(0.0, [0.0, 0.0], [0.0, 0.0])
        .unwrap_err();
    assert!(matches!(err, Error::InvalidInitialData { .. }), "{err:?}");
    assert!(err.to_string().contains("singularity of V"), "{err}");
}

/// The implicit driver's failure on the same infall is reported at the
/// physical state the driver keeps: its time is `t`, not the fictitious `s`.
#[test]
fn implicit_step_errors_carry_the_physical_state() {
    let mut sim = TimeTransformed::new(Kepler, RadiusPower::new([0, 1], 0.5).unwrap())
        .rule(Midpoint, 0.05)
        .start(0.0, [1.0, 0.0], [0.0, 0.0])
        .unwrap();
    let err = sim.run_until(2.0, |_| {}).unwrap_err();
    let t = sim.state().t;
    assert!(t > 1.0 && t < 1.2, "stopped near the collision at t = 1.11, not at s: {t}");
    assert!(err.to_string().contains(&format!("from t = {t}")), "{err}");
}
