//! The cost of the workflow tools: recording a solution at every step
//! (double pendulum, N = 2, midpoint, h = 0.01) against the bare `run`
//! loop, and an ensemble of 1000 pendulum runs in parallel against serial.
//!
//! `cargo bench -p lagrangian-bench --bench workflow`
#![allow(missing_docs)]

use criterion::{Criterion, criterion_group, criterion_main};
use lagrangian::ensemble;
use lagrangian::prelude::*;
use lagrangian::{Plan, State};
use std::hint::black_box;

#[derive(Clone)]
struct DoublePendulum;

#[lagrangian]
impl DoublePendulum {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let kinetic = 1.25 * v[0] * v[0] + 0.3675 * v[1] * v[1] + 1.05 * v[0] * v[1] * (q[0] - q[1]).cos();
        kinetic + 2.5 * 9.81 * q[0].cos() + 1.05 * 9.81 * q[1].cos()
    }
}

#[derive(Clone)]
struct Pendulum {
    omega2: f64,
}

#[lagrangian]
impl Pendulum {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] + self.omega2 * q[0].cos()
    }
}

const STEPS: usize = 1000;

fn start() -> Integrator<DoublePendulum, Midpoint, 2> {
    Integrator::new(DoublePendulum, Midpoint, 0.01).start(0.0, [1.0, -0.5], [0.0, 0.3]).unwrap()
}

fn recording(c: &mut Criterion) {
    let mut g = c.benchmark_group("record 1000 steps, double pendulum, midpoint");
    g.sample_size(30);
    g.bench_function("run (no recording)", |b| {
        b.iter(|| {
            let mut sim = start();
            sim.run(STEPS, |_| {}).unwrap();
            black_box(sim.state().q)
        })
    });
    g.bench_function("run, observer pushing t, q, p", |b| {
        b.iter(|| {
            let mut sim = start();
            let mut rows = Vec::new();
            sim.run(STEPS, |s| rows.push(*s.state())).unwrap();
            black_box(rows.len())
        })
    });
    g.bench_function("solve, every step, t q p", |b| {
        b.iter(|| {
            let mut sim = start();
            black_box(sim.solve(Plan::until(STEPS as f64 * 0.01).without_velocities()).unwrap().len())
        })
    });
    g.bench_function("solve, every step, t q p v energy", |b| {
        b.iter(|| {
            let mut sim = start();
            black_box(sim.solve(Plan::until(STEPS as f64 * 0.01)).unwrap().len())
        })
    });
    g.finish();
}

fn member(_: usize, &(theta0, omega2): &(f64, f64)) -> Result<State<1>, Error> {
    let mut sim = Integrator::new(Pendulum { omega2 }, Midpoint, 0.01).start(0.0, [theta0], [0.0])?;
    sim.run(STEPS, |_| {})?;
    Ok(*sim.state())
}

fn ensembles(c: &mut Criterion) {
    let inputs: Vec<(f64, f64)> = (0..1000).map(|i| (0.1 + 2.9 * i as f64 / 1000.0, 9.81)).collect();
    let mut g = c.benchmark_group("ensemble of 1000 pendulum runs, 1000 midpoint steps each");
    g.sample_size(10);
    g.bench_function("serial", |b| b.iter(|| black_box(ensemble::run_serial(&inputs, member).len())));
    g.bench_function(format!("parallel ({} threads)", rayon_threads()), |b| {
        b.iter(|| black_box(ensemble::run(&inputs, member).len()))
    });
    g.finish();
}

fn rayon_threads() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

criterion_group!(benches, recording, ensembles);
criterion_main!(benches);
