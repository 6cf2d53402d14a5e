//! ns/step of the generated integrators against hand-written ones.
//!
//! Run with `cargo bench --bench step`; it uses cargo's default `bench`
//! profile (= `release`: opt-level 3, 16 codegen units, no fat LTO), which is
//! what a user of the crate compiles with unless they change it.
#![allow(missing_docs)]

mod handwritten;

use criterion::{Criterion, criterion_group, criterion_main};
use handwritten::*;
use lagrangian::{Integrator, Midpoint, Trapezoid};
use std::hint::black_box;

// The systems of the tests, so the bench measures what the tests verify.
#[path = "../tests/common/mod.rs"]
mod common;

use common::{DOUBLE_PENDULUM as DP, DoublePendulum, PENDULUM as P, Pendulum};

const H: f64 = 0.01;

fn pendulum_params() -> PendulumParams {
    PendulumParams { a: P.m * P.l * P.l, d: P.m * P.g * P.l }
}

fn double_params() -> DoubleParams {
    DoubleParams {
        a: (DP.m1 + DP.m2) * DP.l1 * DP.l1,
        b: DP.m2 * DP.l2 * DP.l2,
        c: DP.m2 * DP.l1 * DP.l2,
        d: (DP.m1 + DP.m2) * DP.g * DP.l1,
        e: DP.m2 * DP.g * DP.l2,
    }
}

fn pendulum(c: &mut Criterion) {
    let mut g = c.benchmark_group("pendulum");
    let mut sim = Integrator::new(Pendulum { ..P }, Midpoint, H).start(0.0, [1.0], [0.0]).unwrap();
    g.bench_function("generated midpoint", |b| b.iter(|| black_box(sim.step().unwrap().q)));
    let mut sim = Integrator::new(Pendulum { ..P }, Trapezoid, H).start(0.0, [1.0], [0.0]).unwrap();
    g.bench_function("generated trapezoid", |b| b.iter(|| black_box(sim.step().unwrap().q)));
    let mut hand = PendulumMidpoint::new(pendulum_params(), H, 1.0, 0.0);
    g.bench_function("hand-written midpoint", |b| {
        b.iter(|| {
            hand.step().unwrap();
            black_box(hand.q)
        })
    });
    let mut verlet = PendulumVerlet { s: pendulum_params(), h: H, q: 1.0, p: 0.0 };
    g.bench_function("hand-written verlet", |b| {
        b.iter(|| {
            verlet.step();
            black_box(verlet.q)
        })
    });
    g.finish();
}

fn double_pendulum(c: &mut Criterion) {
    let mut g = c.benchmark_group("double pendulum");
    let (q0, v0) = ([1.0, -0.5], [0.0, 0.5]);
    let mut sim = Integrator::new(DoublePendulum { ..DP }, Midpoint, H).start(0.0, q0, v0).unwrap();
    g.bench_function("generated midpoint", |b| b.iter(|| black_box(sim.step().unwrap().q)));
    let mut sim = Integrator::new(DoublePendulum { ..DP }, Trapezoid, H).start(0.0, q0, v0).unwrap();
    g.bench_function("generated trapezoid", |b| b.iter(|| black_box(sim.step().unwrap().q)));
    let mut hand = DoubleStepper::new(double_params(), DoubleMethod::Midpoint, H, q0, v0);
    g.bench_function("hand-written midpoint", |b| {
        b.iter(|| {
            hand.step().unwrap();
            black_box(hand.q)
        })
    });
    let mut verlet = DoubleStepper::new(double_params(), DoubleMethod::Verlet, H, q0, v0);
    g.bench_function("hand-written verlet", |b| {
        b.iter(|| {
            verlet.step().unwrap();
            black_box(verlet.q)
        })
    });
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .warm_up_time(std::time::Duration::from_millis(500))
        .measurement_time(std::time::Duration::from_secs(3));
    targets = pendulum, double_pendulum
}
criterion_main!(benches);
