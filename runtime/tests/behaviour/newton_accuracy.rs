//! The fixed-step DEL solve against a full Newton solve of the same DEL,
//! written here from the public derivatives and iterated far below the
//! tolerance: the increments must agree to round-off, on easy steps and on a
//! hard one (Cartesian Kepler e = 0.99 from perihelion, first-order
//! predictor). The stepper stops at `rtol = 1e-14`, but full Newton
//! converges quadratically, so its last iterate is far more accurate than
//! that: at most 7.3e-16 relative to `|dq|`. This guards against
//! shortcuts that stop at the tolerance instead: a simplified Newton that
//! freezes the second iteration's Jacobian from the first stops at 7.6e-14
//! here (double pendulum, trapezoid) and 1.2e-14 (Kepler), because the
//! stopping rule's contraction estimate then mixes Newton's rate with the
//! frozen iteration's. The simplified iterations the runtime takes (after a
//! small, contracting correction: `newton::Jacobian::Kept`) are therefore
//! held to 1/100 of the tolerance: 7.3e-16 here, as without them (4.5e-15
//! when held to 1/4 only).
#![allow(missing_docs)]

use lagrangian_runtime::derivatives::{Segment, step_derivatives};
use lagrangian_runtime::{AlphaBeta, DiscreteLagrangian, Integrator, Lagrangian, Midpoint, Scalar, Trapezoid};
use nalgebra::{SMatrix, SVector};

struct DoublePendulum;
impl Lagrangian<2> for DoublePendulum {
    const AUTONOMOUS: bool = true;
    const CYCLIC: [bool; 2] = [false, false];
    fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 2], v: [D; 2]) -> D {
        v[0] * v[0] + v[1] * v[1] * 0.5 + v[0] * v[1] * (q[0] - q[1]).cos() + q[0].cos() * 19.62 + q[1].cos() * 9.81
    }
}

struct CartesianKepler;
impl Lagrangian<2> for CartesianKepler {
    const AUTONOMOUS: bool = true;
    const CYCLIC: [bool; 2] = [false, false];
    fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 2], v: [D; 2]) -> D {
        (v[0] * v[0] + v[1] * v[1]) * 0.5 + (q[0] * q[0] + q[1] * q[1]).sqrt().recip()
    }
}

/// Full Newton on `p + ∂A/∂q_k(dq) = 0` from `dq`, a fresh Jacobian every
/// iteration, until the correction is below `1e-17 |dq|`.
fn full_newton<S: Lagrangian<2>, M: DiscreteLagrangian>(
    system: &S,
    method: &M,
    (t0, h, q0, p): (f64, f64, [f64; 2], [f64; 2]),
    mut dq: [f64; 2],
) -> [f64; 2] {
    for _ in 0..50 {
        let d = step_derivatives(system, method, &Segment { t0, h, q0, dq });
        let r = SVector::<f64, 2>::from_fn(|i, _| p[i] + d.d_q0[i]);
        let j: SMatrix<f64, 2, 2> = d.d2_q0_q1;
        let delta = j.lu().solve(&(-r)).expect("regular Jacobian");
        dq = [dq[0] + delta[0], dq[1] + delta[1]];
        if delta.amax() <= 1e-17 * dq[0].abs().max(dq[1].abs()) {
            return dq;
        }
    }
    dq
}

/// `steps` steps of `method`, each compared with the full Newton solution
/// from the same state; returns the largest difference relative to `|dq|`.
fn worst_difference<S: Lagrangian<2>, M: DiscreteLagrangian>(
    system: S,
    method: M,
    h: f64,
    q0: [f64; 2],
    v0: [f64; 2],
    steps: usize,
) -> f64 {
    let mut sim = Integrator::new(system, method, h).start(0.0, q0, v0).unwrap();
    let mut worst = 0.0f64;
    for _ in 0..steps {
        let before = *sim.state();
        sim.step().unwrap();
        let dq = sim.last_step().unwrap().dq;
        let reference = full_newton(sim.system(), &method, (before.t, h, before.q, before.p), dq);
        let scale = dq[0].abs().max(dq[1].abs());
        let diff = (dq[0] - reference[0]).abs().max((dq[1] - reference[1]).abs()) / scale;
        worst = worst.max(diff);
    }
    worst
}

#[test]
fn fixed_steps_agree_with_full_newton_to_round_off() {
    let cases = [
        ("double pendulum, midpoint", worst_difference(DoublePendulum, Midpoint, 0.01, [1.0, -0.5], [0.0, 0.5], 2000)),
        (
            "double pendulum, trapezoid",
            worst_difference(DoublePendulum, Trapezoid, 0.01, [1.0, -0.5], [0.0, 0.5], 2000),
        ),
        (
            "double pendulum, α-β (α = 0.3)",
            worst_difference(DoublePendulum, AlphaBeta::new(0.3).unwrap(), 0.01, [1.0, -0.5], [0.0, 0.5], 2000),
        ),
    ];
    for (name, worst) in cases {
        eprintln!("{name}: max |dq − dq_full| / |dq| = {worst:.1e}");
        // A few ulps of |dq| (the integrator adds its Kahan compensation to
        // p_k, this reference does not), well below the tolerance 1e-14.
        assert!(worst <= 3e-15, "{name}: {worst:e}");
    }
}

#[test]
fn a_hard_first_step_agrees_with_full_newton_to_round_off() {
    // Perihelion of e = 0.99: v = 14.1, the predictor v0·h is first-order
    // and the Jacobian changes fast along the iteration (up to 7 iterations).
    let e: f64 = 0.99;
    let (q0, v0) = ([1.0 - e, 0.0], [0.0, ((1.0 + e) / (1.0 - e)).sqrt()]);
    let worst = worst_difference(CartesianKepler, Midpoint, 1e-3, q0, v0, 20);
    eprintln!("Kepler e = 0.99, midpoint: max |dq − dq_full| / |dq| = {worst:.1e}");
    assert!(worst <= 3e-15, "{worst:e}");
}
