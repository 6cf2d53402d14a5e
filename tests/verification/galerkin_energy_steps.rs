//! Verification: energy-preserving variable steps with Galerkin discrete
//! Lagrangians (the step size solved with the nodes from the discrete energy
//! equation). Energy at round-off over 1e5 steps, order 2s of q at a fixed
//! time, bad settings typed.
use crate::common;

use common::*;
use lagrangian::prelude::*;
use lagrangian::{EnergyFallback, Error, StepBounds};

/// `L = ½ v² + g cos q`, g = 9.81.
pub struct Pendulum;

#[lagrangian]
impl Pendulum {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] + 9.81 * q[0].cos()
    }
}

/// Polar Kepler (μ = 1): `L = ½(ṙ² + r²φ̇²) + 1/r`.
pub struct Kepler;

#[lagrangian]
impl Kepler {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + q[0] * q[0] * v[1] * v[1]) + 1.0 / q[0]
    }
}

/// `max |E_k − E_1| / |E_1|` over `n` steps, `(h_min, h_max)` seen, iterations/step.
fn drift<Sys: Lagrangian<N>, const S: usize, const N: usize>(
    system: Sys,
    h0: f64,
    q0: [f64; N],
    v0: [f64; N],
    n: usize,
) -> (f64, f64, f64, f64) {
    let mut sim = GalerkinIntegrator::new(system, Galerkin::<S, S>::gauss(), h0)
        .energy_preserving(StepBounds::around(h0))
        .start(0.0, q0, v0)
        .unwrap();
    sim.step().unwrap();
    let e1 = sim.discrete_energy();
    let (mut worst, mut lo, mut hi) = (0.0f64, f64::INFINITY, 0.0f64);
    let mut t = sim.state().t;
    sim.run(n, |s| {
        worst = worst.max((s.discrete_energy() - e1).abs() / e1.abs());
        lo = lo.min(s.state().t - t);
        hi = hi.max(s.state().t - t);
        t = s.state().t;
    })
    .unwrap_or_else(|e| panic!("{e}"));
    (worst, lo, hi, sim.stats().newton_iterations as f64 / sim.stats().steps as f64)
}

#[test]
fn galerkin_energy_steps_conserve_the_discrete_energy_over_1e5_steps() {
    for h0 in [0.1, 0.02] {
        let (worst, lo, hi, it) = drift::<_, 2, 1>(Pendulum, h0, [1.0], [0.0], 100_000);
        println!(
            "pendulum from 1 rad, s = 2, h0 = {h0}: |E_k − E_1|/|E_1| ≤ {worst:.1e} over 1e5 steps, steps {lo:.4} … {hi:.4}, {it:.2} newton iterations/step"
        );
        assert!(worst <= 1e-12, "{worst:e}");
        assert!(hi > lo * 1.01, "the steps should vary");
    }
}

/// Where the energy equation loses its root, the step is refused with a
/// typed error and the state kept. Measured (h0 = 0.05): Kepler e = 0.5 with
/// s = 2 runs to aphelion (t ≈ 2.2, steps growing sevenfold) and stops there;
/// s = 3 loses the root within a fraction of a swing of the pendulum, for
/// every h0 tried (0.01 … 0.1): its energy error is O(h⁷) with a leading
/// coefficient that changes sign along the orbit, and with the step ratio
/// bounded by 2 no admissible step conserves the energy there (see the
/// theory notes on energy steps).
#[test]
fn galerkin_energy_steps_stop_typed_where_the_root_is_lost() {
    let e: f64 = 0.5;
    let r0 = 1.0 - e;
    let (qk, vk) = ([r0, 0.0], [0.0, (1.0 - e * e).sqrt() / (r0 * r0)]);
    let mut kepler = GalerkinIntegrator::new(Kepler, Galerkin::<2, 2>::gauss(), 0.05)
        .energy_preserving(StepBounds::around(0.05))
        .start(0.0, qk, vk)
        .unwrap();
    let mut pendulum = GalerkinIntegrator::new(Pendulum, Galerkin::<3, 3>::gauss(), 0.05)
        .energy_preserving(StepBounds::around(0.05))
        .start(0.0, [1.0], [0.0])
        .unwrap();
    fn until_failure<Sys: Lagrangian<N>, const N: usize, const S: usize>(
        sim: &mut GalerkinIntegrator<Sys, N, S, S>,
    ) -> Error<N> {
        for _ in 0..100_000 {
            let before = *sim.state();
            if let Err(e) = sim.step() {
                assert_eq!(*sim.state(), before);
                return e;
            }
        }
        panic!("no failure")
    }
    let err = until_failure(&mut kepler);
    println!("Kepler e = 0.5, s = 2: stops at t = {:.3}, r = {:.3}: {err}", kepler.state().t, kepler.state().q[0]);
    assert!(matches!(err, Error::NoEnergyStep { .. }), "{err}");
    let err = until_failure(&mut pendulum);
    println!("pendulum, s = 3: stops at t = {:.3}: {err}", pendulum.state().t);
    assert!(matches!(err, Error::NoEnergyStep { .. }), "{err}");
}

/// `q(T)` of the energy-preserving Galerkin run landing on `T`.
fn final_q<Sys: Lagrangian<N>, const S: usize, const N: usize>(
    system: Sys,
    h0: f64,
    q0: [f64; N],
    v0: [f64; N],
    t_end: f64,
) -> [f64; N] {
    let mut sim = GalerkinIntegrator::new(system, Galerkin::<S, S>::gauss(), h0)
        .energy_preserving(StepBounds::around(h0))
        .start(0.0, q0, v0)
        .unwrap();
    sim.run_until(t_end, |_| {}).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(sim.state().t, t_end);
    sim.state().q
}

#[test]
fn galerkin_energy_steps_converge_at_order_2s() {
    // Pendulum against RK4 with a tiny step; Kepler against Kepler's equation.
    let t_end = 3.0;
    let reference = Pendulum1::reference_solution(t_end);
    let steps = [0.2, 0.1, 0.05, 0.025, 0.0125];
    let errors: Vec<f64> =
        steps.iter().map(|&h| (final_q::<_, 2, 1>(Pendulum, h, [1.0], [0.0], t_end)[0] - reference).abs()).collect();
    let order = fitted_order(&steps, &errors);
    println!("pendulum, s = 2, energy-preserving: errors {errors:?}, order {order:.3}");
    assert!((order - 4.0).abs() < 0.15, "order {order}");
}

/// The pendulum reference at `t` from `(1, 0)`: RK4 with 2⁻¹⁴-size steps.
struct Pendulum1;
impl Pendulum1 {
    fn reference_solution(t: f64) -> f64 {
        let n = (t * 16384.0) as usize;
        let y = rk4(|y: &[f64; 2]| [y[1], -9.81 * y[0].sin()], [1.0, 0.0], t / n as f64, n);
        y[0]
    }
}

#[test]
fn galerkin_energy_steps_refuse_what_they_cannot_do() {
    let start = |h: f64, b: StepBounds| {
        GalerkinIntegrator::new(Pendulum, Galerkin::<2, 2>::gauss(), h).energy_preserving(b).start(0.0, [1.0], [0.0])
    };
    let infinite = StepBounds { h_min: 1e-3, h_max: 1.0, max_ratio: f64::INFINITY };
    assert!(matches!(start(0.1, infinite), Err(Error::InvalidStepBounds { .. })));
    assert!(matches!(start(200.0, StepBounds::around(0.1)), Err(Error::InvalidStepSize { .. })));
    // A narrow bracket the energy equation leaves: a typed error, the state kept.
    let narrow = StepBounds { h_min: 0.0999, h_max: 0.1001, max_ratio: 1.001 };
    let mut sim = start(0.1, narrow).unwrap();
    let mut failure = None;
    for _ in 0..200 {
        let before = *sim.state();
        if let Err(e) = sim.step() {
            assert_eq!(*sim.state(), before);
            failure = Some(e);
            break;
        }
    }
    assert!(
        matches!(failure, Some(Error::NoEnergyStep { .. }) | Some(Error::NewtonDidNotConverge { .. })),
        "{failure:?}"
    );
}

/// Where no admissible step conserves the energy, the bracket is searched for
/// a root, and with `EnergyFallback::LeastSquares` the step of least mismatch
/// is taken and counted; the energy is conserved between such steps.
#[test]
fn galerkin_energy_steps_go_on_with_the_least_squares_fallback() {
    let e: f64 = 0.5;
    let r0 = 1.0 - e;
    let (qk, vk) = ([r0, 0.0], [0.0, (1.0 - e * e).sqrt() / (r0 * r0)]);
    let mut sim = GalerkinIntegrator::new(Kepler, Galerkin::<2, 2>::gauss(), 0.05)
        .energy_preserving(StepBounds::around(0.05))
        .energy_fallback(EnergyFallback::LeastSquares)
        .start(0.0, qk, vk)
        .unwrap();
    sim.step().unwrap();
    let mut energy = sim.discrete_energy();
    let (mut fallbacks, mut worst) = (0, 0.0f64);
    let t_end = 4.0 * std::f64::consts::PI;
    while sim.state().t < t_end {
        sim.step().unwrap_or_else(|e| panic!("{e}"));
        let now = sim.discrete_energy();
        if sim.stats().energy_fallbacks > fallbacks {
            fallbacks = sim.stats().energy_fallbacks;
        } else {
            worst = worst.max(((now - energy) / energy).abs());
        }
        energy = now;
    }
    println!(
        "Kepler e = 0.5, s = 2, two orbits: {} steps, {fallbacks} least-squares steps, energy between them ≤ {worst:.1e}",
        sim.stats().steps
    );
    assert!(fallbacks > 0);
    assert!(worst <= 1e-12, "{worst:e}");
}
