//! The momentum change of a Newton step is the impulse at the increment it
//! stored: `p_{k+1} − p_k = ∂A/∂q_k + ∂A/∂q_{k+1}` at `(q_k, Δq_k)`
//! (`= Σ_j w h L_q(q_j)` for a one-point rule) to round-off, evaluated here
//! independently (`step_derivatives`, one hyper-dual sweep of the action)
//! after every step. (The momentum is formed as `p_k` plus that change, so
//! it equals `∂A/∂q_{k+1}` only up to the DEL residual Newton leaves.)
//!
//! Where the macro wrote gradient code, the one-point steps take the impulse
//! from Newton's last linearisation: its value at the last iterate plus its
//! derivative times the last correction, instead of an evaluation at the
//! solution. That correction moves the momentum by far more than its ulps,
//! so the check fails if the derivative is wrong or left out (measured with
//! it zeroed: 107 … 124 ulps on every Newton step case here, against at
//! most 4.5 with it). Looser tolerances (`1e-12`, `1e-10`) leave larger last
//! corrections, where the linearisation's own error would show if its
//! a-priori bound let it through.

use crate::common::{CHARGED, DOUBLE_PENDULUM, KeplerPolar, PENDULUM};
use lagrangian::derivatives::step_derivatives;
use lagrangian::{DiscreteLagrangian, Integrator, Lagrangian, Midpoint, NewtonOptions, Trapezoid};

/// The largest `|(p_{k+1} − p_k) − (∂A/∂q_k + ∂A/∂q_{k+1})|` over `steps`
/// steps, in units of `ε · max(|p|, |∂A/∂q_k|, |∂A/∂q_{k+1}|)` (the terms the
/// sums cancel).
fn worst_ulps<S: Lagrangian<N>, M: DiscreteLagrangian + Copy, const N: usize>(
    system: S,
    method: M,
    h: f64,
    rtol: f64,
    (q0, v0): ([f64; N], [f64; N]),
    steps: usize,
) -> f64 {
    let newton = NewtonOptions { rtol, ..NewtonOptions::default() };
    let mut it = Integrator::new(system, method, h).newton(newton).start(0.0, q0, v0).unwrap();
    let mut worst: f64 = 0.0;
    for _ in 0..steps {
        let p0 = it.state().p;
        it.step().unwrap();
        let d = step_derivatives(it.system(), &method, it.last_step().unwrap());
        let p = it.state().p;
        let scale = p.iter().chain(&d.d_q0).chain(&d.d_q1).fold(0.0_f64, |m, x| m.max(x.abs()));
        for i in 0..N {
            let change = (p[i] - p0[i]) - (d.d_q0[i] + d.d_q1[i]);
            worst = worst.max(change.abs() / (f64::EPSILON * scale));
        }
    }
    worst
}

fn check<S: Lagrangian<N>, const N: usize>(
    name: &str,
    system: impl Fn() -> S,
    h: f64,
    start: ([f64; N], [f64; N]),
    steps: usize,
) {
    for rtol in [NewtonOptions::default().rtol, 1e-12, 1e-10] {
        let midpoint = worst_ulps(system(), Midpoint, h, rtol, start, steps);
        let trapezoid = worst_ulps(system(), Trapezoid, h, rtol, start, steps);
        println!("{name}, rtol {rtol:e}: midpoint {midpoint:.1} ulps, trapezoid {trapezoid:.1} ulps");
        assert!(midpoint <= 8.0, "{name} midpoint, rtol {rtol:e}: {midpoint} ulps");
        assert!(trapezoid <= 8.0, "{name} trapezoid, rtol {rtol:e}: {trapezoid} ulps");
    }
}

#[test]
fn the_momentum_change_of_a_newton_step_is_the_impulse_at_its_increment() {
    use crate::common::{ChargedParticle, DoublePendulum, Pendulum};
    check("pendulum", || Pendulum { ..PENDULUM }, 0.05, ([2.5], [0.0]), 2000);
    check("double pendulum", || DoublePendulum { ..DOUBLE_PENDULUM }, 0.01, ([1.2, -0.4], [0.0, 1.0]), 2000);
    check("Kepler (polar)", || KeplerPolar { mu: 1.0 }, 0.01, ([1.0, 0.0], [0.0, 1.3]), 2000);
    check("charged particle", || ChargedParticle { ..CHARGED }, 0.02, ([0.8, 0.1], [0.3, -0.5]), 2000);
}
