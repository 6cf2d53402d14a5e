//! Verification of energy-preserving variable steps (MATH.md §3, §9), on
//! systems implemented by hand against the runtime's trait.
//!
//! The energy that is conserved is the discrete energy `E_1` of the first
//! step, which is taken with the given `h0` (paper 000 §V starts from τ0);
//! `E_1` is within `O(h0²)` of `E_L(q0, v0)`.
#![allow(missing_docs)]

use lagrangian_runtime::{
    DiscreteLagrangian, Error, Integrator, Lagrangian, Midpoint, Scalar, StepBounds, StepPolicy, Trapezoid,
};

struct Pendulum;
impl Lagrangian<1> for Pendulum {
    const AUTONOMOUS: bool = true;
    const CYCLIC: [bool; 1] = [false];
    fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 1], v: [D; 1]) -> D {
        v[0] * v[0] * 0.5 + q[0].cos() * 9.81
    }
}

struct DoublePendulum;
impl Lagrangian<2> for DoublePendulum {
    const AUTONOMOUS: bool = true;
    const CYCLIC: [bool; 2] = [false, false];
    fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 2], v: [D; 2]) -> D {
        // m1 = m2 = l1 = l2 = 1, g = 9.81
        v[0] * v[0] + v[1] * v[1] * 0.5 + v[0] * v[1] * (q[0] - q[1]).cos() + q[0].cos() * 19.62 + q[1].cos() * 9.81
    }
}

struct Kepler;
impl Lagrangian<2> for Kepler {
    const AUTONOMOUS: bool = true;
    const CYCLIC: [bool; 2] = [false, true];
    fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 2], v: [D; 2]) -> D {
        (v[0] * v[0] + q[0] * q[0] * v[1] * v[1]) * 0.5 + q[0].recip()
    }
}

/// Kepler at perihelion with eccentricity `e` (μ = a = 1): `(q0, v0)`.
fn perihelion(e: f64) -> ([f64; 2], [f64; 2]) {
    let r0 = 1.0 - e;
    ([r0, 0.0], [0.0, (1.0 - e * e).sqrt() / (r0 * r0)])
}

/// Largest `|E_k − E_1| / |E_1|` over `n` energy-preserving steps, and `(h_min, h_max)` seen.
fn energy_drift<S: Lagrangian<N>, M: DiscreteLagrangian, const N: usize>(
    system: S,
    method: M,
    h0: f64,
    q0: [f64; N],
    v0: [f64; N],
    n: usize,
) -> (f64, f64, f64) {
    let mut sim =
        Integrator::new(system, method, h0).energy_preserving(StepBounds::around(h0)).start(0.0, q0, v0).unwrap();
    sim.step().unwrap();
    let e1 = sim.discrete_energy();
    let (mut worst, mut lo, mut hi) = (0.0f64, f64::INFINITY, 0.0f64);
    sim.run(n, |s| {
        worst = worst.max((s.discrete_energy() - e1).abs() / e1.abs());
        lo = lo.min(s.step_size());
        hi = hi.max(s.step_size());
    })
    .unwrap_or_else(|e| panic!("{e}"));
    (worst, lo, hi)
}

#[test]
fn pendulum_energy_is_conserved_to_round_off_over_1e5_steps() {
    for v0 in [0.0, 1.0] {
        let (err, lo, hi) = energy_drift(Pendulum, Midpoint, 0.05, [2.0], [v0], 100_000);
        assert!(err <= 1e-12, "v0 = {v0}: {err:e}");
        assert!(hi / lo > 1.2, "the steps should vary along the orbit: [{lo}, {hi}]");
    }
}

#[test]
#[ignore = "known failure: from (1, -0.5) with v0 = (0, 0.5) the coupled Newton on (dq, h) diverges at step 36 (t = 0.313); a safeguarded 1-D solve in h is the planned fix"]
fn double_pendulum_energy_is_conserved_to_round_off_over_1e5_steps() {
    let (err, _, _) = energy_drift(DoublePendulum, Midpoint, 0.01, [1.0, -0.5], [0.0, 0.5], 100_000);
    assert!(err <= 1e-12, "{err:e}");
}

#[test]
fn kepler_energy_and_angular_momentum_are_conserved_over_1e5_steps() {
    let (q0, v0) = perihelion(0.5);
    let (err, lo, hi) = energy_drift(Kepler, Midpoint, 0.01, q0, v0, 100_000);
    assert!(err <= 1e-12, "{err:e}");
    // Steps grow away from perihelion.
    assert!(hi / lo > 2.0, "[{lo}, {hi}]");
    let (err, _, _) = energy_drift(Kepler, Trapezoid, 0.01, q0, v0, 100_000);
    assert!(err <= 1e-12, "trapezoid: {err:e}");
}

#[test]
fn variable_step_converges_at_order_two_at_a_fixed_time() {
    // Pendulum from θ = 1.2 at rest, to T = 3; reference by a midpoint run
    // with fixed h = 1e-4 (error ~1e-9, far below the errors measured).
    let t_end = 3.0;
    let mut reference = Integrator::new(Pendulum, Midpoint, 1e-4).start(0.0, [1.2], [0.0]).unwrap();
    reference.run_until(t_end, |_| {}).unwrap();
    let q_ref = reference.state().q[0];
    let steps = [0.04, 0.02, 0.01, 0.005];
    let errors: Vec<f64> = steps
        .iter()
        .map(|&h0| {
            let mut sim = Integrator::new(Pendulum, Midpoint, h0)
                .energy_preserving(StepBounds::around(h0))
                .start(0.0, [1.2], [0.0])
                .unwrap();
            sim.run_until(t_end, |_| {}).unwrap();
            assert_eq!(sim.state().t, t_end);
            (sim.state().q[0] - q_ref).abs()
        })
        .collect();
    let x: Vec<f64> = steps.iter().map(|h| h.ln()).collect();
    let y: Vec<f64> = errors.iter().map(|e| e.ln()).collect();
    let (mx, my) = (x.iter().sum::<f64>() / 4.0, y.iter().sum::<f64>() / 4.0);
    let slope = x.iter().zip(&y).map(|(a, b)| (a - mx) * (b - my)).sum::<f64>()
        / x.iter().map(|a| (a - mx) * (a - mx)).sum::<f64>();
    assert!((slope - 2.0).abs() <= 0.1, "order {slope}, errors {errors:?}");
}

#[test]
fn bad_step_settings_are_typed_errors() {
    let start = |h0: f64, bounds: StepBounds| {
        Integrator::new(Pendulum, Midpoint, h0).energy_preserving(bounds).start(0.0, [1.0], [0.0]).map(|_| ())
    };
    assert!(matches!(start(-0.1, StepBounds::around(0.1)), Err(Error::InvalidStepSize { .. })));
    assert!(matches!(start(f64::NAN, StepBounds::around(0.1)), Err(Error::InvalidStepSize { .. })));
    let inverted = StepBounds { h_min: 0.2, h_max: 0.1, max_ratio: 2.0 };
    assert!(matches!(start(0.1, inverted), Err(Error::InvalidStepBounds { .. })));
    let ratio = StepBounds { h_min: 0.01, h_max: 1.0, max_ratio: 0.5 };
    assert!(matches!(start(0.1, ratio), Err(Error::InvalidStepBounds { .. })));
    let outside = StepBounds { h_min: 0.2, h_max: 1.0, max_ratio: 2.0 };
    assert!(matches!(start(0.1, outside), Err(Error::InvalidStepSize { .. })));
}

#[test]
fn a_step_outside_the_bounds_is_refused_and_the_state_kept() {
    // A narrow bracket around h0 that the energy equation leaves at once.
    let bounds = StepBounds { h_min: 0.0499, h_max: 0.0501, max_ratio: 1.001 };
    let mut sim = Integrator::new(Pendulum, Midpoint, 0.05).energy_preserving(bounds).start(0.0, [2.0], [0.0]).unwrap();
    assert_eq!(sim.policy(), StepPolicy::EnergyPreserving(bounds));
    let mut failure = None;
    for _ in 0..200 {
        let before = *sim.state();
        if let Err(e) = sim.step() {
            assert_eq!(*sim.state(), before);
            failure = Some(e);
            break;
        }
    }
    match failure {
        Some(Error::StepRejected { reason, .. }) => assert!(reason.contains("h_min") || reason.contains("ratio")),
        other => panic!("expected a rejected step, got {other:?}"),
    }
}
