//! The hand-written baselines of the benchmark compute the same trajectories
//! as the generated integrators (otherwise the timing ratios are meaningless).
#[path = "../../tests/common/mod.rs"]
mod common;

use common::*;
use lagrangian::{Integrator, Midpoint, Trapezoid};
use lagrangian_bench::handwritten::*;

#[test]
fn pendulum_midpoint_agrees_with_the_hand_written_one() {
    let s = PENDULUM;
    let params = PendulumParams { a: s.m * s.l * s.l, d: s.m * s.g * s.l };
    let mut hand = PendulumMidpoint::new(params, 0.01, 1.0, 0.3);
    let mut sim = Integrator::new(Pendulum { ..PENDULUM }, Midpoint, 0.01).start(0.0, [1.0], [0.3]).unwrap();
    for _ in 0..1000 {
        hand.step().unwrap();
        sim.step().unwrap();
    }
    assert!((hand.q - sim.state().q[0]).abs() < 1e-12, "{} vs {}", hand.q, sim.state().q[0]);
    assert!((hand.p - sim.state().p[0]).abs() < 1e-11);
}

#[test]
fn pendulum_trapezoid_is_the_hand_written_verlet() {
    let s = PENDULUM;
    let params = PendulumParams { a: s.m * s.l * s.l, d: s.m * s.g * s.l };
    let mut verlet = PendulumVerlet { s: params, h: 0.01, q: 1.0, p: params.a * 0.3 };
    let mut sim = Integrator::new(Pendulum { ..PENDULUM }, Trapezoid, 0.01).start(0.0, [1.0], [0.3]).unwrap();
    for _ in 0..1000 {
        verlet.step();
        sim.step().unwrap();
    }
    assert!((verlet.q - sim.state().q[0]).abs() < 1e-12);
    assert!((verlet.p - sim.state().p[0]).abs() < 1e-11);
}

#[test]
fn double_pendulum_agrees_with_the_hand_written_ones() {
    let s = DOUBLE_PENDULUM;
    let params = DoubleParams {
        a: (s.m1 + s.m2) * s.l1 * s.l1,
        b: s.m2 * s.l2 * s.l2,
        c: s.m2 * s.l1 * s.l2,
        d: (s.m1 + s.m2) * s.g * s.l1,
        e: s.m2 * s.g * s.l2,
    };
    let (q0, v0) = ([1.0, -0.5], [0.0, 0.5]);
    let mut hand = DoubleStepper::new(params, DoubleMethod::Midpoint, 0.01, q0, v0);
    let mut sim = Integrator::new(DoublePendulum { ..DOUBLE_PENDULUM }, Midpoint, 0.01).start(0.0, q0, v0).unwrap();
    let mut verlet = DoubleStepper::new(params, DoubleMethod::Verlet, 0.01, q0, v0);
    let mut trap = Integrator::new(DoublePendulum { ..DOUBLE_PENDULUM }, Trapezoid, 0.01).start(0.0, q0, v0).unwrap();
    for _ in 0..500 {
        hand.step().unwrap();
        sim.step().unwrap();
        verlet.step().unwrap();
        trap.step().unwrap();
    }
    assert!(rel_err(&hand.q, &sim.state().q) < 1e-11, "{:?} vs {:?}", hand.q, sim.state().q);
    assert!(rel_err(&hand.p, &sim.state().p) < 1e-11);
    assert!(rel_err(&verlet.q, &trap.state().q) < 1e-11, "{:?} vs {:?}", verlet.q, trap.state().q);
    assert!(rel_err(&verlet.p, &trap.state().p) < 1e-11);
}
