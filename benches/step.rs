//! ns/step of the generated integrators against hand-written ones.
//!
//! Run with `cargo bench --bench step`; it uses cargo's default `bench`
//! profile (= `release`: opt-level 3, 16 codegen units, no fat LTO), which is
//! what a user of the crate compiles with unless they change it.
#![allow(missing_docs)]

mod handwritten;

use criterion::{Criterion, criterion_group, criterion_main};
use handwritten::*;
use lagrangian::prelude::*;
use lagrangian::{Integrator, Midpoint, Trapezoid};
use std::hint::black_box;

pub struct Pendulum {
    pub m: f64,
    pub l: f64,
    pub g: f64,
}

#[lagrangian]
impl Pendulum {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * self.m * self.l * self.l * v[0] * v[0] + self.m * self.g * self.l * q[0].cos()
    }
}

pub struct DoublePendulum {
    pub m1: f64,
    pub m2: f64,
    pub l1: f64,
    pub l2: f64,
    pub g: f64,
}

#[lagrangian]
impl DoublePendulum {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let kinetic = 0.5 * (self.m1 + self.m2) * self.l1 * self.l1 * v[0] * v[0]
            + 0.5 * self.m2 * self.l2 * self.l2 * v[1] * v[1]
            + self.m2 * self.l1 * self.l2 * v[0] * v[1] * (q[0] - q[1]).cos();
        let potential = -(self.m1 + self.m2) * self.g * self.l1 * q[0].cos() - self.m2 * self.g * self.l2 * q[1].cos();
        kinetic - potential
    }
}

const H: f64 = 0.01;
const P: Pendulum = Pendulum { m: 1.3, l: 0.8, g: 9.81 };
const DP: DoublePendulum = DoublePendulum { m1: 1.0, m2: 1.5, l1: 1.0, l2: 0.7, g: 9.81 };

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
