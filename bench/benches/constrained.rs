//! The price of holonomic constraints: ns/step of a system written in
//! Cartesian coordinates with constraints (`Constrained`, RATTLE) against
//! the same system in minimal coordinates with the same rule.
//!
//! Run with `cargo bench -p lagrangian-bench --bench constrained`; the
//! ratio constrained / minimal of each group is the cost of the constraints
//! (a larger `N`, the multipliers, the projection of the momenta).
#![allow(missing_docs)]

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use lagrangian::prelude::*;

const H: f64 = 0.01;

/// A unit pendulum under unit gravity in its angle.
struct AnglePendulum;

#[lagrangian]
impl AnglePendulum {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] + q[0].cos()
    }
}

/// The same pendulum as a point on the unit circle.
struct CartesianPendulum;

#[lagrangian]
impl CartesianPendulum {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) - q[1]
    }
    fn constraints(&self, q: [f64; 2]) -> [f64; 1] {
        [q[0] * q[0] + q[1] * q[1] - 1.0]
    }
}

/// A double pendulum (unit masses, lengths and gravity) in its two angles.
struct AngleDoublePendulum;

#[lagrangian]
impl AngleDoublePendulum {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        v[0] * v[0] + 0.5 * v[1] * v[1] + v[0] * v[1] * (q[0] - q[1]).cos() + 2.0 * q[0].cos() + q[1].cos()
    }
}

/// The same double pendulum in Cartesian coordinates `(x₁, y₁, x₂, y₂)`.
struct CartesianDoublePendulum;

#[lagrangian]
impl CartesianDoublePendulum {
    fn lagrangian(&self, q: [f64; 4], v: [f64; 4]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2] + v[3] * v[3]) - q[1] - q[3]
    }
    fn constraints(&self, q: [f64; 4]) -> [f64; 2] {
        let (dx, dy) = (q[2] - q[0], q[3] - q[1]);
        [q[0] * q[0] + q[1] * q[1] - 1.0, dx * dx + dy * dy - 1.0]
    }
}

fn pendulum(c: &mut Criterion) {
    let mut g = c.benchmark_group("pendulum");
    g.warm_up_time(Duration::from_secs(1)).measurement_time(Duration::from_secs(3));
    let theta = 1.0f64;
    let mut sim = Integrator::new(AnglePendulum, Midpoint, H).start(0.0, [theta], [0.0]).unwrap();
    g.bench_function("angle, midpoint", |b| b.iter(|| black_box(sim.step().unwrap().q)));
    let method = Constrained::<_, 1>::new(Midpoint);
    let q0 = [theta.sin(), -theta.cos()];
    let mut sim = Integrator::new(CartesianPendulum, method, H).start(0.0, q0, [0.0; 2]).unwrap();
    g.bench_function("Cartesian, constrained midpoint", |b| b.iter(|| black_box(sim.step().unwrap().q)));
    g.finish();
}

fn double_pendulum(c: &mut Criterion) {
    let mut g = c.benchmark_group("double pendulum");
    g.warm_up_time(Duration::from_secs(1)).measurement_time(Duration::from_secs(3));
    let (a, b) = (0.8f64, -0.4f64);
    let mut sim = Integrator::new(AngleDoublePendulum, Midpoint, H).start(0.0, [a, b], [0.0; 2]).unwrap();
    g.bench_function("angles, midpoint", |bench| bench.iter(|| black_box(sim.step().unwrap().q)));
    let method = Constrained::<_, 2>::new(Midpoint);
    let q0 = [a.sin(), -a.cos(), a.sin() + b.sin(), -a.cos() - b.cos()];
    let mut sim = Integrator::new(CartesianDoublePendulum, method, H).start(0.0, q0, [0.0; 4]).unwrap();
    g.bench_function("Cartesian, constrained midpoint", |bench| bench.iter(|| black_box(sim.step().unwrap().q)));
    g.finish();
}

criterion_group!(benches, pendulum, double_pendulum);
criterion_main!(benches);
