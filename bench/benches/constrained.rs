//! The price of holonomic constraints: ns/step of a system written in
//! Cartesian coordinates with constraints (`Constrained`, RATTLE) against
//! the same system in minimal coordinates with the same rule.
//!
//! Run with `cargo bench -p lagrangian-bench --bench constrained`; the
//! ratio constrained / minimal of each group is the cost of the constraints
//! (a larger `N`, the multipliers, the projection of the momenta).
//!
//! The last group steps a hanging chain of 100 … 10 000 planar links in
//! Cartesian coordinates (`DynConstrained`: banded saddle-point solves) and
//! prints the cost per step against the number of links with its fitted
//! exponent (1 for a cost linear in `N`).
#![allow(missing_docs)]

use std::hint::black_box;
use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use lagrangian::prelude::*;
use lagrangian_bench::cartesian::{AnglePendulum, CartesianPendulum};
use lagrangian_bench::clock::Clock;

/// The hanging chain of the constraint tests (`Links`, `folded`).
#[path = "../../tests/common/links.rs"]
mod links;
use links::{Links, folded};

const H: f64 = 0.01;

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

fn slope(n: &[f64], t: &[f64]) -> f64 {
    let x: Vec<f64> = n.iter().map(|v| v.ln()).collect();
    let y: Vec<f64> = t.iter().map(|v| v.ln()).collect();
    let (mx, my) = (x.iter().sum::<f64>() / x.len() as f64, y.iter().sum::<f64>() / y.len() as f64);
    let sxy: f64 = x.iter().zip(&y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let sxx: f64 = x.iter().map(|a| (a - mx) * (a - mx)).sum();
    sxy / sxx
}

fn chain(c: &mut Criterion) {
    const STEPS: usize = 10;
    // (links, repeats of STEPS steps)
    let sizes = [(100, 40), (300, 20), (1_000, 10), (3_000, 5), (10_000, 3)];
    let mut per_step = Vec::new();
    for &(links, repeats) in &sizes {
        let q0 = folded(links, 0.01);
        let v0 = vec![0.0; 2 * links];
        let mut sim = DynConstrained::start(Links(links), Midpoint, 1e-3, 0.0, &q0, &v0).unwrap();
        let mut run = move || {
            sim.run(STEPS, |_| {}).unwrap();
            black_box(sim.state().q[0]);
        };
        let mut g = c.benchmark_group(format!("hanging chain, {links} links, {STEPS} steps"));
        g.sample_size(10).warm_up_time(Duration::from_millis(500)).measurement_time(Duration::from_secs(3));
        g.bench_function("DynConstrained midpoint (banded saddle point)", |b| b.iter(&mut run));
        g.finish();
        // CPU time of this thread, best of the repeats: comparable across
        // sizes on a busy machine (see `lagrangian_bench::clock`).
        let best = (0..repeats)
            .map(|_| {
                let clock = Clock::start();
                run();
                clock.seconds() / STEPS as f64
            })
            .fold(f64::INFINITY, f64::min);
        per_step.push(best);
    }
    println!(
        "\nhanging chain in Cartesian coordinates (DynConstrained, midpoint, h = 1e-3), µs per step (best of repeated runs):"
    );
    for (&(links, _), t) in sizes.iter().zip(&per_step) {
        println!("  {links:>6} links (N = {:>6}, M = {links:>6}): {:>10.1} µs", 2 * links, t * 1e6);
    }
    let n: Vec<f64> = sizes.iter().map(|s| s.0 as f64).collect();
    println!("fitted cost exponent in the number of links (100 … 10 000): {:.2}", slope(&n, &per_step));
}

criterion_group!(benches, pendulum, double_pendulum, chain);
criterion_main!(benches);
