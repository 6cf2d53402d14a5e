//! Verification: the one-point rules (midpoint, trapezoid, α-β) run in
//! double-double ([`DoubleDouble`]) through the same `Integrator`, with
//! fixed and energy-preserving steps.
//!
//! In double-double they run as the Galerkin rule of degree 1 with their own
//! quadrature points, which is the same discrete Lagrangian; these tests show
//! that it is (agreement with the `f64` path to `f64` round-off), that the
//! orders are those of the rules down to errors `f64` cannot hold (below
//! 1e-25), and that energy-preserving steps conserve the discrete energy to
//! double-double round-off.
//!
//! Orders at errors below 1e-25 with a second-order method need step sizes
//! near 1e-8, so the horizon is short (`T = 1e-5`, 128 … 1024 steps from
//! rest, where the global error grows like `h² T²`): the smallest error
//! stays about 1e3 above the round-off floor of these runs (about 1e-29).
use crate::common;
use crate::common::galerkin_reference;

use common::{PENDULUM, Pendulum, fitted_order};
use galerkin_reference::pendulum_angle;
use lagrangian::num_dual::DualNum;
use lagrangian::{
    AlphaBeta, DiscreteLagrangian, DoubleDouble, Error, Integrator, Lagrangian, Method, Midpoint, NewtonOptions,
    StepBounds, Trapezoid,
};

type Dd = DoubleDouble;

fn dd(x: f64) -> Dd {
    Dd::from(x)
}

fn newton() -> NewtonOptions {
    NewtonOptions { rtol: 1e-30, ..NewtonOptions::default() }
}

/// `ω` of the pendulum as its generated Lagrangian sees it in double-double.
fn pendulum_omega() -> Dd {
    let p = Pendulum { ..PENDULUM };
    let (zero, one) = (dd(0.0), dd(1.0));
    let potential = p.lagrangian(zero, [zero], [zero]);
    let kinetic = p.lagrangian(zero, [zero], [one]) - potential;
    (potential / (kinetic * 2.0)).sqrt()
}

/// Errors of `q(T)` relative to θ0 = 1 rad after `n` fixed steps of `T/n`, for each `n`.
fn fixed_errors<M: Method<Dd> + Copy>(method: M, t_end: f64, steps: &[usize]) -> (Vec<f64>, Vec<f64>) {
    let t_end = dd(t_end);
    let exact = pendulum_angle(pendulum_omega(), dd(1.0), t_end);
    let mut h = Vec::new();
    let mut err = Vec::new();
    for &n in steps {
        let step = t_end / n as f64;
        let mut sim = Integrator::new(Pendulum { ..PENDULUM }, method, step)
            .newton(newton())
            .start(dd(0.0), [dd(1.0)], [dd(0.0)])
            .unwrap();
        sim.run_until(t_end, |_| {}).unwrap();
        assert_eq!(sim.state().t, t_end);
        h.push(step.to_f64());
        err.push((sim.state().q[0] - exact).abs().to_f64());
    }
    (h, err)
}

fn check_order(name: &str, (h, err): (Vec<f64>, Vec<f64>), want: f64, below: f64) {
    let order = fitted_order(&h, &err);
    println!("{name}: fitted order {order:.3}, errors {:.2e} … {:.2e}", err[0], err[err.len() - 1]);
    assert!((order - want).abs() <= 0.15, "{name}: fitted order {order:.3}, want {want}; errors {err:?}");
    assert!(err[err.len() - 1] < below, "{name}: smallest error {:e} not below {below:e}", err[err.len() - 1]);
    assert!(err[err.len() - 1] > 1e-29, "{name}: smallest error {:e} at the round-off floor", err[err.len() - 1]);
}

const STEPS: [usize; 5] = [128, 215, 362, 609, 1024];

/// The horizon of the order fits.
const T_END: f64 = 1e-5;

#[test]
fn double_double_midpoint_has_order_2_below_1e_25() {
    check_order("midpoint, double-double", fixed_errors(Midpoint, T_END, &STEPS), 2.0, 1e-25);
}

#[test]
fn double_double_trapezoid_has_order_2_below_1e_25() {
    check_order("trapezoid, double-double", fixed_errors(Trapezoid, T_END, &STEPS), 2.0, 1e-25);
}

#[test]
fn double_double_alpha_beta_has_order_1() {
    // First order: errors C h T, far above round-off at these steps.
    let method = AlphaBeta::new(0.3).unwrap();
    check_order("α-β (α = 0.3), double-double", fixed_errors(method, T_END, &STEPS), 1.0, 1e-12);
}

/// The same discrete Lagrangian in both types: 100 pendulum steps of 0.01
/// agree with the `f64` path to `f64` round-off, for each rule.
#[test]
fn double_double_and_f64_paths_are_the_same_map() {
    fn both<M: DiscreteLagrangian>(method: M) -> (f64, f64) {
        let mut f = Integrator::new(Pendulum { ..PENDULUM }, method, 0.01).start(0.0, [1.0], [0.0]).unwrap();
        let mut d = Integrator::new(Pendulum { ..PENDULUM }, method, dd(0.01))
            .newton(newton())
            .start(dd(0.0), [dd(1.0)], [dd(0.0)])
            .unwrap();
        f.run(100, |_| {}).unwrap();
        d.run(100, |_| {}).unwrap();
        ((f.state().q[0] - d.state().q[0].to_f64()).abs(), (f.state().p[0] - d.state().p[0].to_f64()).abs())
    }
    for (name, (dq, dp)) in
        [("midpoint", both(Midpoint)), ("trapezoid", both(Trapezoid)), ("α-β 0.3", both(AlphaBeta::new(0.3).unwrap()))]
    {
        println!("{name}: |q_f64 − q_dd| = {dq:.1e}, |p_f64 − p_dd| = {dp:.1e}");
        assert!(dq < 1e-13 && dp < 1e-12, "{name}: f64 and double-double differ by {dq:e} in q, {dp:e} in p");
    }
}

/// Energy-preserving midpoint steps in double-double: the discrete energy is
/// conserved to double-double round-off over 2000 steps, and the position at
/// a fixed time converges with order 2 in the first step size, down to
/// errors below 1e-25.
#[test]
fn double_double_energy_preserving_midpoint() {
    let h0 = dd(0.01);
    let mut sim = Integrator::new(Pendulum { ..PENDULUM }, Midpoint, h0)
        .energy_preserving(StepBounds::around(0.01))
        .newton(newton())
        .start(dd(0.0), [dd(1.0)], [dd(0.0)])
        .unwrap();
    sim.step().unwrap();
    let e1 = sim.discrete_energy();
    let mut worst = 0.0f64;
    sim.run(2000, |s| worst = worst.max(((s.discrete_energy() - e1) / e1).abs().to_f64())).unwrap();
    println!("energy-preserving midpoint, double-double: |E_k − E_1|/|E_1| ≤ {worst:.1e} over 2000 steps");
    assert!(worst < 1e-28, "energy drift {worst:e}");

    let t_end = dd(T_END);
    let exact = pendulum_angle(pendulum_omega(), dd(1.0), t_end);
    let (mut h, mut err) = (Vec::new(), Vec::new());
    for n in STEPS {
        let h0 = t_end / n as f64;
        let mut sim = Integrator::new(Pendulum { ..PENDULUM }, Midpoint, h0)
            .energy_preserving(StepBounds::around(h0.to_f64()))
            .newton(newton())
            .start(dd(0.0), [dd(1.0)], [dd(0.0)])
            .unwrap();
        sim.run_until(t_end, |_| {}).unwrap();
        h.push(h0.to_f64());
        err.push((sim.state().q[0] - exact).abs().to_f64());
    }
    check_order("energy-preserving midpoint, double-double", (h, err), 2.0, 1e-25);
}

/// A rule that does not say which Galerkin rule it is has no double-double
/// path: refused at `start` with a typed error, not a wrong result.
#[test]
fn a_rule_without_galerkin_points_is_refused_in_double_double() {
    #[derive(Clone, Copy, Debug)]
    struct Custom;
    impl DiscreteLagrangian for Custom {
        fn order(&self) -> u32 {
            2
        }
        fn action<S, D, const N: usize>(&self, system: &S, t0: D, h: D, q0: [D; N], dq: [D; N]) -> D
        where
            S: Lagrangian<N> + ?Sized,
            D: lagrangian::Scalar,
        {
            Midpoint.action(system, t0, h, q0, dq)
        }
    }
    let err = Integrator::new(Pendulum { ..PENDULUM }, Custom, dd(0.01)).start(dd(0.0), [dd(1.0)], [dd(0.0)]);
    assert!(matches!(err, Err(Error::InvalidMethod { .. })), "{err:?}");
    // In f64 it runs.
    let mut sim = Integrator::new(Pendulum { ..PENDULUM }, Custom, 0.01).start(0.0, [1.0], [0.0]).unwrap();
    sim.run(10, |_| {}).unwrap();
}

/// Bad input in double-double: non-finite data, a non-positive step, a
/// failed Newton solve; the integrator is unchanged after a failed step.
#[test]
fn double_double_bad_input_is_typed() {
    let start = |h: Dd, q: Dd| {
        Integrator::new(Pendulum { ..PENDULUM }, Midpoint, h)
            .start(dd(0.0), [q], [dd(0.0)])
            .map(|_| ())
            .map_err(Box::new)
    };
    assert!(matches!(start(dd(0.0), dd(1.0)).map_err(|e| *e), Err(Error::InvalidStepSize { .. })));
    assert!(matches!(start(dd(-0.1), dd(1.0)).map_err(|e| *e), Err(Error::InvalidStepSize { .. })));
    assert!(matches!(start(dd(0.01), dd(f64::NAN)).map_err(|e| *e), Err(Error::InvalidInitialData { .. })));
    let mut sim = Integrator::new(Pendulum { ..PENDULUM }, Midpoint, dd(0.01))
        .newton(NewtonOptions { max_iterations: 1, ..newton() })
        .start(dd(0.0), [dd(1.0)], [dd(0.0)])
        .unwrap();
    let before = *sim.state();
    let failed = sim.step();
    assert!(failed.is_err(), "one Newton iteration cannot reach 1e-30");
    assert_eq!(*sim.state(), before);
    assert_eq!(sim.stats().failed_steps, 1);
    assert!(matches!(sim.set_step_size(dd(f64::NAN)), Err(Error::InvalidStepSize { .. })));
}
