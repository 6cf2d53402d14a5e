//! Bad input: every failure is a typed error, nothing panics, and a failed
//! step leaves the integrator as it was.
use crate::common;

use common::*;
use lagrangian::prelude::*;
use lagrangian::{Error, Integrator, Midpoint, NewtonOptions};

#[test]
fn invalid_step_sizes_are_rejected() {
    for h in [0.0, -0.1, f64::NAN, f64::INFINITY] {
        let err = Integrator::new(Pendulum { ..PENDULUM }, Midpoint, h).start(0.0, [0.1], [0.0]).unwrap_err();
        assert!(matches!(err, Error::InvalidStepSize { .. }), "{err}");
    }
    let mut sim = Integrator::new(Pendulum { ..PENDULUM }, Midpoint, 0.1).start(0.0, [0.1], [0.0]).unwrap();
    assert!(matches!(sim.set_step_size(-1.0), Err(Error::InvalidStepSize { .. })));
    assert_eq!(sim.step_size(), 0.1);
}

#[test]
fn non_finite_initial_data_is_rejected() {
    let err = Integrator::new(Pendulum { ..PENDULUM }, Midpoint, 0.1).start(0.0, [f64::NAN], [0.0]).unwrap_err();
    assert!(matches!(err, Error::InvalidInitialData { .. }), "{err}");
    let err = Integrator::new(Pendulum { ..PENDULUM }, Midpoint, 0.1).start(f64::INFINITY, [0.0], [0.0]).unwrap_err();
    assert!(matches!(err, Error::InvalidInitialData { .. }), "{err}");
}

/// `L = q v − ½ q²` is linear in `v`: the Legendre transform is singular.
#[derive(Debug)]
struct Degenerate;

#[lagrangian]
impl Degenerate {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        q[0] * v[0] - 0.5 * q[0] * q[0]
    }
}

#[test]
fn a_degenerate_lagrangian_is_rejected_at_the_start() {
    let err = Integrator::new(Degenerate, Midpoint, 0.1).start(0.0, [1.0], [0.0]).unwrap_err();
    assert!(matches!(err, Error::InvalidInitialData { .. }), "{err}");
    assert!(err.to_string().contains("legendre"), "{err}");
}

#[test]
fn newton_failure_keeps_the_state_and_a_smaller_step_recovers() {
    let options = NewtonOptions { max_iterations: 3, ..NewtonOptions::default() };
    let mut sim =
        Integrator::new(Pendulum { ..PENDULUM }, Midpoint, 0.01).newton(options).start(0.0, [3.0], [4.0]).unwrap();
    sim.run(10, |_| {}).unwrap();
    let before = *sim.state();
    let stats_before = sim.stats().steps;
    sim.set_step_size(3.0).unwrap();
    let err = sim.step().unwrap_err();
    match &err {
        Error::NewtonDidNotConverge { state, iterations, residual_norm, .. } => {
            assert_eq!(*state, before);
            assert_eq!(*iterations, 3);
            assert!(*residual_norm > 0.0);
        }
        Error::SingularJacobian { state, .. } | Error::NonFinite { state, .. } => assert_eq!(*state, before),
        other => panic!("unexpected error {other}"),
    }
    assert_eq!(*sim.state(), before, "a failed step must not move the integrator");
    assert_eq!(sim.stats().steps, stats_before);
    assert_eq!(sim.stats().failed_steps, 1);
    // Retry with a step it can take: same result as an integrator that never failed.
    sim.set_step_size(0.01).unwrap();
    sim.step().unwrap();
    let mut clean =
        Integrator::new(Pendulum { ..PENDULUM }, Midpoint, 0.01).newton(options).start(0.0, [3.0], [4.0]).unwrap();
    clean.run(11, |_| {}).unwrap();
    assert_eq!(sim.state().q, clean.state().q);
    assert_eq!(sim.state().p, clean.state().p);
}

/// `L = ½ v² − √q` is undefined for `q < 0`.
#[derive(Debug)]
struct SquareRootWell;

#[lagrangian]
impl SquareRootWell {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] - q[0].sqrt()
    }
}

#[test]
fn non_finite_values_are_reported_with_the_state() {
    let mut sim = Integrator::new(SquareRootWell, Midpoint, 0.5).start(0.0, [0.01], [-1.0]).unwrap();
    let before = *sim.state();
    let err = sim.step().unwrap_err();
    match &err {
        Error::NonFinite { state, quantity, .. } => {
            assert_eq!(*state, before);
            assert!(["residual", "jacobian", "correction", "position", "momentum"].contains(quantity));
        }
        Error::NewtonDidNotConverge { state, .. } | Error::SingularJacobian { state, .. } => assert_eq!(*state, before),
        other => panic!("unexpected error {other}"),
    }
    assert_eq!(*sim.state(), before);
}

#[test]
fn a_target_time_in_the_past_is_rejected() {
    let mut sim = Integrator::new(Pendulum { ..PENDULUM }, Midpoint, 0.1).start(1.0, [0.1], [0.0]).unwrap();
    assert!(matches!(sim.run_until(0.5, |_| {}), Err(Error::InvalidTarget { .. })));
    assert!(matches!(sim.run_until(f64::NAN, |_| {}), Err(Error::InvalidTarget { .. })));
    assert_eq!(sim.state().step, 0);
}

#[test]
fn run_until_lands_exactly_on_the_target() {
    let mut sim = Integrator::new(Pendulum { ..PENDULUM }, Midpoint, 0.3).start(0.0, [0.1], [0.0]).unwrap();
    sim.run_until(1.0, |_| {}).unwrap();
    assert_eq!(sim.state().t, 1.0);
    assert_eq!(sim.state().step, 4);
    assert_eq!(sim.step_size(), 0.3);
    sim.step().unwrap();
    assert!((sim.state().t - 1.3).abs() < 1e-15);
}

/// `L = ½ v² + c ln(1 − q)` with `c = 0`: free motion, and `L` is NaN past
/// `q = 1`, where the gradient code's derivatives `−c/(1 − q)` stay finite.
#[derive(Clone, Copy)]
struct ZeroLogWall {
    c: f64,
}

#[lagrangian]
impl ZeroLogWall {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] + self.c * (1.0 - q[0]).ln()
    }
}

/// The implicit one-point steps on the macro's gradient code check `L` near
/// the solution, from the value their Newton linearisation computes: they
/// stop with the non-finite Lagrangian where the midpoint (or the rule's
/// points) passes the wall, within half a step of it, and leave the state.
#[test]
fn gradient_code_steps_stop_where_the_lagrangian_is_not_defined() {
    fn stops<M: DiscreteLagrangian>(method: M, name: &str) {
        let h = 0.01;
        let system = ZeroLogWall { c: 0.0 };
        let mut sim = Integrator::new(system, method, h).start(0.0, [0.5], [1.0]).unwrap();
        let err = loop {
            let before = *sim.state();
            match sim.step() {
                Ok(_) => {}
                Err(e) => {
                    assert_eq!(*sim.state(), before, "{name}: a failed step changed the state");
                    break e;
                }
            }
            assert!(sim.state().step < 1000, "{name}: never stopped (q = {})", sim.state().q[0]);
        };
        assert!(matches!(err, Error::NonFinite { quantity: "lagrangian", .. }), "{name}: {err}");
        let q = sim.state().q[0];
        assert!((0.99..1.006).contains(&q), "{name}: stopped at q = {q}");
    }
    const { assert!(<ZeroLogWall as Lagrangian<1>>::HAS_GRADIENT_QV) };
    stops(Midpoint, "midpoint");
    stops(AlphaBeta::new(0.3).unwrap(), "α-β");
}
