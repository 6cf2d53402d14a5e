//! Gauss Galerkin steps solved by the fixed-point iteration on the stage
//! velocities give the steps Newton gives, to round-off; a stiff step falls
//! back to Newton; a step the fixed point alone cannot solve fails with the
//! state kept.
use crate::common;

use common::forced::SENSOR_VARIABLE;
use common::*;
use lagrangian::galerkin::StageIteration;
use lagrangian::prelude::*;
use lagrangian::{Error, GalerkinIntegrator};

/// The largest difference of `(q, p)` between two runs of `n` steps of size
/// `h` with the rule `Galerkin<S, S>` solved by `a` and by `b`, relative to
/// the size of the state, step by step; and the two integrators.
#[allow(clippy::type_complexity)]
fn compare<Sys: Lagrangian<2> + Copy, const S: usize>(
    system: Sys,
    (q0, v0): ([f64; 2], [f64; 2]),
    h: f64,
    n: usize,
    (a, b): (StageIteration, StageIteration),
) -> (f64, GalerkinIntegrator<Sys, 2, S, S>, GalerkinIntegrator<Sys, 2, S, S>) {
    let start = |it| {
        GalerkinIntegrator::new(system, Galerkin::<S, S>::gauss().with_iteration(it), h).start(0.0, q0, v0).unwrap()
    };
    let (mut x, mut y) = (start(a), start(b));
    let mut worst: f64 = 0.0;
    for _ in 0..n {
        x.step().unwrap();
        y.step().unwrap();
        let (s, t) = (x.state(), y.state());
        let size = s.q.iter().chain(&s.p).fold(1.0f64, |m, z| m.max(z.abs()));
        for i in 0..2 {
            worst = worst.max((s.q[i] - t.q[i]).abs() / size).max((s.p[i] - t.p[i]).abs() / size);
        }
    }
    (worst, x, y)
}

#[test]
fn fixed_point_and_newton_give_the_same_double_pendulum_steps() {
    let start = ([1.2, -0.4], [0.3, 1.1]);
    let iterations = (StageIteration::FixedPoint, StageIteration::Newton);
    let (worst4, fixed, newton) = compare::<_, 4>(&DOUBLE_PENDULUM, start, 0.05, 200, iterations);
    let (worst6, ..) = compare::<_, 6>(&DOUBLE_PENDULUM, start, 0.04, 100, iterations);
    // Measured: 6e-13 and 3e-14 relative: round-off, grown along a chaotic
    // orbit over 200 and 100 steps (each single step agrees to 1e-15, below).
    assert!(worst4 < 1e-11 && worst6 < 1e-12, "{worst4:e} {worst6:e}");
    // Single steps from states along the orbit, from the same first guess.
    let mut orbit = newton.clone();
    let mut single: f64 = 0.0;
    for _ in 0..40 {
        orbit.run(5, |_| {}).unwrap();
        let (s, v) = (*orbit.state(), orbit.velocity().unwrap());
        let step = |it| {
            let rule = Galerkin::<4, 4>::gauss().with_iteration(it);
            let mut sim = GalerkinIntegrator::new(&DOUBLE_PENDULUM, rule, 0.05).start(s.t, s.q, v).unwrap();
            sim.step().unwrap();
            *sim.state()
        };
        let (a, b) = (step(StageIteration::FixedPoint), step(StageIteration::Newton));
        let size = a.q.iter().chain(&a.p).fold(1.0f64, |m, z| m.max(z.abs()));
        for i in 0..2 {
            single = single.max((a.q[i] - b.q[i]).abs() / size).max((a.p[i] - b.p[i]).abs() / size);
        }
    }
    assert!(single < 1e-14, "{single:e}");
    // The fixed-point run used no Jacobian; the Newton run no fixed point.
    let (e, f) = (fixed.point_evaluations(), newton.point_evaluations());
    assert!(e.hessians == 0 && e.velocity_hessians == 4 * 200, "{e:?}");
    assert!(f.hessians > 0 && f.velocity_hessians == 0, "{f:?}");
}

#[test]
fn fixed_point_and_newton_give_the_same_forced_steps() {
    // The sensor with a position-dependent inductance, a resistor and a
    // battery: forces and dissipation enter the stage momenta.
    let start = ([0.01, 0.0], [0.0, 0.0]);
    let iterations = (StageIteration::FixedPoint, StageIteration::Newton);
    let (worst, fixed, _) = compare::<_, 3>(&SENSOR_VARIABLE, start, 0.02, 100, iterations);
    // Measured: 3e-16.
    assert!(worst < 1e-13, "{worst:e}");
    assert_eq!(fixed.point_evaluations().hessians, 0);
    // The automatic choice takes the fixed point on these non-stiff steps.
    let (worst, auto, _) =
        compare::<_, 5>(&SENSOR_VARIABLE, start, 0.01, 40, (StageIteration::Automatic, StageIteration::Newton));
    assert!(worst < 1e-13, "{worst:e}");
    // Most of them (the first steps, from a straight-line guess, go to Newton).
    let e = auto.point_evaluations();
    assert!(e.velocity_hessians >= 5 * 40 * 3 / 4, "{e:?}");
}

#[test]
fn coarse_forced_steps_contract_with_the_second_order_terms() {
    // The report's sensor from rest at its coarsest calibrated step for
    // s = 5, h = 2/34: the armature's spring has ωh = 1.18, so the terms of
    // second order in h that the coupled matrix takes decide the
    // contraction. With them every step is solved by the fixed point, the
    // first (from a straight-line guess) included.
    let iterations = (StageIteration::Automatic, StageIteration::Newton);
    let (worst, auto, _) = compare::<_, 5>(&SENSOR_VARIABLE, ([0.0, 0.0], [0.0, 0.0]), 2.0 / 34.0, 34, iterations);
    assert!(worst < 1e-13, "{worst:e}");
    let e = auto.point_evaluations();
    assert_eq!(e.hessians, 0, "{e:?}");
    // Measured: 5.00 rounds per step (8.94 with the first-order matrix,
    // whose first step went to Newton).
    let rounds = auto.stats().newton_iterations as f64 / 34.0;
    assert!(rounds <= 6.0, "{rounds}");
}

/// `L = ½ v² − ½ k q²` with `k = 10⁴`: `ω h = 5` at `h = 0.05`, where the
/// fixed point diverges.
#[derive(Clone, Copy)]
struct Stiff;

impl Lagrangian<2> for Stiff {
    const AUTONOMOUS: bool = true;
    const CYCLIC: [bool; 2] = [false; 2];
    fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 2], v: [D; 2]) -> D {
        (v[0] * v[0] + v[1] * v[1] - (q[0] * q[0] * 1e4 + q[1] * q[1])) * 0.5
    }
}

#[test]
fn a_stiff_step_falls_back_to_newton() {
    let start = ([1.0, 1.0], [0.0, 1.0]);
    let (worst, auto, _) = compare::<_, 3>(Stiff, start, 0.05, 20, (StageIteration::Automatic, StageIteration::Newton));
    assert!(worst < 1e-12, "{worst:e}");
    // Newton solved the steps (Jacobians assembled), after the fixed point
    // was tried on the first and then paused (offered again after pauses of
    // 1, 3 and 7 steps); each step is finished by the fixed point from
    // Newton's root (Hessians in v at its first round, and a round or two).
    let e = auto.point_evaluations();
    assert!(e.hessians > 0 && e.velocity_hessians > 0, "{e:?}");
    assert!(e.velocity_hessians <= 3 * (20 + 4), "{e:?}");
    assert!(auto.stats().newton_iterations <= 20 * 6, "{:?}", auto.stats());
    // The fixed point alone fails with a typed error and keeps the state.
    let mut sim =
        GalerkinIntegrator::new(Stiff, Galerkin::<3, 3>::gauss().with_iteration(StageIteration::FixedPoint), 0.05)
            .start(0.0, start.0, start.1)
            .unwrap();
    let before = sim.clone();
    let err = sim.step().unwrap_err();
    assert!(matches!(err, Error::StepRejected { .. }), "{err}");
    assert_eq!(sim.state(), before.state());
    assert_eq!(sim.point_evaluations(), before.point_evaluations());
    // At a step the fixed point contracts on, it succeeds.
    sim.set_step_size(0.001).unwrap();
    sim.step().unwrap();
}

#[test]
fn fixed_point_steps_are_symplectic() {
    let start = ([1.2, -0.4], [0.3, 1.1]);
    let (_, mut fixed, mut newton) =
        compare::<_, 4>(&DOUBLE_PENDULUM, start, 0.02, 30, (StageIteration::FixedPoint, StageIteration::Newton));
    let (a, b) = (fixed.last_tangent_map().unwrap(), newton.last_tangent_map().unwrap());
    // Measured: defects 1e-14 for both; the maps agree to 1e-13.
    assert!(a.symplecticity_defect() < 1e-12, "{}", a.symplecticity_defect());
    assert!(b.symplecticity_defect() < 1e-12, "{}", b.symplecticity_defect());
    assert!((a.matrix() - b.matrix()).amax() < 1e-11, "{}", (a.matrix() - b.matrix()).amax());
    // And along a run: the discrete energy stays bounded (no drift) on both.
    let e0 = fixed.discrete_energy();
    fixed.run(2000, |_| {}).unwrap();
    newton.run(2000, |_| {}).unwrap();
    assert!((fixed.discrete_energy() - newton.discrete_energy()).abs() < 1e-9 * e0.abs().max(1.0));
}

/// A unit charge in the plane in a uniform magnetic field `b`:
/// `L = ½|v|² + ½ b (q₀ v₁ − q₁ v₀)`. `∂L/∂q` depends on `v` only and
/// `∂L/∂v` is linear in `(q, v)`, so the stage equations are linear in the
/// stage velocities and their whole Jacobian is the first-order coupling.
#[derive(Clone, Copy)]
struct Magnetic {
    b: f64,
}

impl Lagrangian<2> for Magnetic {
    const AUTONOMOUS: bool = true;
    const CYCLIC: [bool; 2] = [false; 2];
    fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 2], v: [D; 2]) -> D {
        (v[0] * v[0] + v[1] * v[1] + (q[0] * v[1] - q[1] * v[0]) * self.b) * 0.5
    }
}

#[test]
fn the_gyroscopic_coupling_is_in_the_iteration_matrix() {
    // b h = 1.5: the coupling h ∂²L/∂q∂v is as large as the mass matrix, so
    // an iteration with ∂²L/∂v² alone gains only a factor of about
    // b h ρ(A) (ρ(A) the spectral radius of the Gauss matrix) per round.
    // With the coupling in its matrix the first correction solves the
    // linear stage equations, and the second is at round-off. A step that
    // starts block-diagonal switches to the coupled matrix after its second
    // round (four rounds); the next 1, 3, 7, 15, 15, … steps start coupled
    // (two rounds): by that schedule 9 of the 100 steps start block-diagonal
    // and the run takes 218 rounds.
    let (system, h, n) = (Magnetic { b: 30.0 }, 0.05, 100);
    let start = ([1.0, 0.0], [0.0, 2.0]);
    let iterations = (StageIteration::FixedPoint, StageIteration::Newton);
    let (worst, fixed, _) = compare::<_, 4>(system, start, h, n, iterations);
    // Measured: 2e-15 (the orbit is a circle; no chaos to grow round-off).
    assert!(worst < 1e-13, "{worst:e}");
    let stats = fixed.stats();
    assert!(stats.newton_iterations <= 5 * n as u64 / 2, "{} iterations in {n} steps", stats.newton_iterations);
    assert_eq!(fixed.point_evaluations().hessians, 0);
}
