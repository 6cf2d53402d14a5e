//! Galerkin variational integrators: cost per step against the degree `s`,
//! Newton iterations per step, and 1000 pendulum periods at equal final
//! error against two DOP853 implementations (ode_solvers, differential-equations).
//!
//! Run with `cargo bench --bench galerkin` (cargo's default `bench` profile).
//! The work–precision part first calibrates every method to the same final
//! error (printed), then times the whole run and prints the ratios.
#![allow(missing_docs)]

use std::hint::black_box;
use std::time::Duration;

use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};
use lagrangian::{Galerkin, GalerkinIntegrator};

#[path = "../../tests/common/mod.rs"]
mod common;

use common::galerkin_reference as reference;
use common::{PENDULUM as P, Pendulum};

type V2 = nalgebra034::Vector2<f64>;

/// The target: `|θ(T) − θ_exact(T)|` after 1000 periods from θ0 = 1 rad.
const TARGET: f64 = 1e-8;
const THETA0: f64 = 1.0;

fn omega() -> f64 {
    (P.g / P.l).sqrt()
}

fn t_end() -> f64 {
    1000.0 * reference::pendulum_period(omega(), THETA0)
}

fn exact() -> f64 {
    reference::pendulum_angle(omega(), THETA0, t_end())
}

/// `θ(T)` with degree `S`, `S` Gauss points, `n` steps; and Newton iterations per step.
fn galerkin_run<const S: usize>(n: usize) -> Option<(f64, f64)> {
    let t = t_end();
    let mut sim = GalerkinIntegrator::new(Pendulum { ..P }, Galerkin::<S, S>::gauss(), t / n as f64)
        .start(0.0, [THETA0], [0.0])
        .ok()?;
    sim.run(n, |_| {}).ok()?;
    Some((sim.state().q[0], sim.stats().newton_iterations as f64 / sim.stats().steps as f64))
}

/// θ̈ = −ω² sin θ as a first-order system, for the DOP853 baselines.
struct PendulumOde {
    w2: f64,
}

impl ode_solvers::System<f64, V2> for PendulumOde {
    fn system(&self, _t: f64, y: &V2, dy: &mut V2) {
        dy[0] = y[1];
        dy[1] = -self.w2 * y[0].sin();
    }
}

impl differential_equations::ode::ODE<f64, V2> for PendulumOde {
    fn diff(&self, _t: f64, y: &V2, dydt: &mut V2) {
        dydt[0] = y[1];
        dydt[1] = -self.w2 * y[0].sin();
    }
}

fn ode_solvers_run(tol: f64) -> Option<(f64, u32)> {
    let t = t_end();
    let mut s = ode_solvers::Dop853::from_param(
        PendulumOde { w2: omega() * omega() },
        0.0,
        t,
        t,
        V2::new(THETA0, 0.0),
        tol,
        tol,
        0.9,
        0.0,
        0.333,
        6.0,
        t,
        0.0,
        10_000_000,
        1000,
        // Sparse: the accepted steps only, without the three extra stages of dense output.
        ode_solvers::OutputType::Sparse,
    );
    let stats = match s.integrate() {
        Ok(stats) => stats,
        Err(e) => {
            eprintln!("ode_solvers: {e}");
            return None;
        }
    };
    Some((s.y_out().last()?[0], stats.num_eval))
}

fn diffeq_run(tol: f64) -> Option<(f64, usize)> {
    use differential_equations::prelude::*;
    let t = t_end();
    let ode = PendulumOde { w2: omega() * omega() };
    let mut method = ExplicitRungeKutta::dop853().rtol(tol).atol(tol).max_steps(10_000_000);
    let solution = ODEProblem::new(&ode, 0.0, t, V2::new(THETA0, 0.0)).t_eval(vec![t]).solve(&mut method).ok()?;
    let (_, y) = solution.last().ok()?;
    Some((y[0], solution.evals.function))
}

/// Smallest `n` (growing by 2^{1/8}) whose error is at most the target.
fn calibrate_galerkin<const S: usize>(n0: usize) -> Option<(usize, f64, f64)> {
    let want = exact();
    let mut n = n0 as f64;
    for _ in 0..200 {
        // The error is not monotone in h: accept n only if n and the next two
        // larger step counts all meet the target, and report the worst.
        let counts = [0.0, 0.125, 0.25].map(|e| (n * 2f64.powf(e)).round() as usize);
        let runs: Vec<_> = counts.iter().filter_map(|&k| galerkin_run::<S>(k)).collect();
        if runs.len() == 3 && runs.iter().all(|(q, _)| (q - want).abs() <= TARGET) {
            let err = runs.iter().map(|(q, _)| (q - want).abs()).fold(0.0, f64::max);
            return Some((counts[0], err, runs[0].1));
        }
        n *= 2f64.powf(0.125);
    }
    None
}

/// Largest tolerance (shrinking by 10^{1/8}) whose error is at most the target.
fn calibrate_tol(run: impl Fn(f64) -> Option<f64>) -> Option<(f64, f64)> {
    let want = exact();
    let mut tol = 1e-6;
    for _ in 0..80 {
        // As for the Galerkin steps: this and the next two tolerances must meet the target.
        let tols = [1.0, 10f64.powf(-0.125), 10f64.powf(-0.25)].map(|f| tol * f);
        let errs: Vec<f64> = tols.iter().filter_map(|&t| run(t)).map(|q| (q - want).abs()).collect();
        if errs.len() == 3 && errs.iter().all(|&e| e <= TARGET) {
            return Some((tol, errs.iter().fold(0.0, |m: f64, e| m.max(*e))));
        }
        tol /= 10f64.powf(0.125);
    }
    None
}

fn step_cost(c: &mut Criterion) {
    let mut g = c.benchmark_group("galerkin step (pendulum, h = 0.1)");
    macro_rules! degree {
        ($($s:literal)*) => {$(
            let mut sim = GalerkinIntegrator::new(Pendulum { ..P }, Galerkin::<$s, $s>::gauss(), 0.1)
                .start(0.0, [THETA0], [0.0])
                .unwrap();
            sim.run(1000, |_| {}).unwrap();
            println!(
                "s = {}: {:.2} Newton iterations per step",
                $s,
                sim.stats().newton_iterations as f64 / sim.stats().steps as f64
            );
            g.bench_function(BenchmarkId::from_parameter($s), |b| b.iter(|| black_box(sim.step().unwrap().q)));
        )*};
    }
    degree!(1 2 3 4 5 6 7 8);
    g.finish();
    // N = 2, where a step of the size of the last one starts from the last
    // step's factored Newton block (from sN = 8).
    let mut g = c.benchmark_group("galerkin step (kepler e = 0.5, h = 0.1)");
    macro_rules! kepler_degree {
        ($($s:literal)*) => {$(
            let mut sim = GalerkinIntegrator::new(lagrangian_bench::problems::KeplerSys, Galerkin::<$s, $s>::gauss(), 0.1)
                .start(0.0, [0.5, 0.0], [0.0, 3f64.sqrt()])
                .unwrap();
            sim.run(1000, |_| {}).unwrap();
            println!(
                "kepler s = {}: {:.2} Newton iterations per step",
                $s,
                sim.stats().newton_iterations as f64 / sim.stats().steps as f64
            );
            g.bench_function(BenchmarkId::from_parameter($s), |b| b.iter(|| black_box(sim.step().unwrap().q)));
        )*};
    }
    kepler_degree!(2 4 6);
    g.finish();
}

fn thousand_periods(c: &mut Criterion) {
    let mut g = c.benchmark_group("1000 pendulum periods, |θ error| ≤ 1e-8");
    g.sample_size(10).measurement_time(Duration::from_secs(5));
    macro_rules! degree {
        ($($s:literal => $n0:expr),*) => {$(
            match calibrate_galerkin::<$s>($n0) {
                Some((n, err, iters)) => {
                    println!("galerkin s = {}: {n} steps (h = {:.4}), error {err:.2e}, {iters:.2} Newton iterations per step", $s, t_end() / n as f64);
                    g.bench_function(format!("galerkin s={}", $s), |b| b.iter(|| black_box(galerkin_run::<$s>(n))));
                }
                None => println!("galerkin s = {}: no step size reaches the target", $s),
            }
        )*};
    }
    degree!(2 => 20_000, 3 => 5_000, 4 => 3_000, 5 => 2_000, 6 => 1_500, 8 => 1_000);
    if let Some((tol, err)) = calibrate_tol(|tol| ode_solvers_run(tol).map(|r| r.0)) {
        let evals = ode_solvers_run(tol).unwrap().1;
        println!("ode_solvers DOP853: tol {tol:.2e}, error {err:.2e}, {evals} evaluations");
        g.bench_function("ode_solvers DOP853", |b| b.iter(|| black_box(ode_solvers_run(tol))));
    }
    if let Some((tol, err)) = calibrate_tol(|tol| diffeq_run(tol).map(|r| r.0)) {
        let evals = diffeq_run(tol).unwrap().1;
        println!("differential-equations DOP853: tol {tol:.2e}, error {err:.2e}, {evals} evaluations");
        g.bench_function("differential-equations DOP853", |b| b.iter(|| black_box(diffeq_run(tol))));
    }
    g.finish();
}

criterion_group!(benches, step_cost, thousand_periods);
criterion_main!(benches);
