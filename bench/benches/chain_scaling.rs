//! The cost of a step against the size of a chain (issue: systems must scale
//! linearly): an FPU-β chain written with `for` loops through
//! `#[lagrangian]`, N = 100 … 2000, in reverse mode (derivatives from a tape,
//! banded Newton solves), against a hand-written Störmer–Verlet step of the
//! same chain.
//!
//! - `trapezoid`: the explicit Störmer–Verlet path (one reverse sweep of `L`
//!   per step for `∂L/∂q`, the constant mass matrix factored once);
//! - `midpoint`: the implicit midpoint rule, Newton with a tridiagonal
//!   Jacobian from the macro's gradient code evaluated once per iteration on
//!   a dual number carrying the 3 colour classes (no tape);
//! - `trapezoid, plain sums`: the same with `Summation::Plain` (the
//!   hand-written step's arithmetic);
//! - `hand-written Verlet`: the analytic force of the same chain, plain
//!   sums; `hand-written Verlet, compensated sums`: the same with the Kahan
//!   sums of `q` and `p` the generated steps keep, in place (the fair
//!   baseline: the same arithmetic).
//!
//! Prints the fitted cost exponent of each in N after the criterion groups.
//!
//! Then the same chain as a run-time-sized system (`DynLagrangian`, written
//! by hand over slices) through `DynIntegrator`, N = 100 … 100 000, with the
//! explicit trapezoid and the banded midpoint steps, their fitted exponents
//! and the process's peak resident memory (`VmHWM`). Fewer steps per timed
//! run at large N keep the bench's run time sensible.
//!
//! Before both, a group times the explicit step alone at N = 1000 on the
//! bench's chain and on the chain as a new user writes it
//! (`lagrangian_bench::chain`), with the size known at compile time and at
//! run time, compensated and plain, against the hand-written Verlet: a
//! table of µs per step and the ratios to the plain hand-written Verlet,
//! all from one run (instruction counts of the same cases:
//! `bench/chain-instructions.sh`).
//!
//! `cargo bench -p lagrangian-bench --bench chain_scaling`
#![allow(missing_docs)]

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{Criterion, criterion_group, criterion_main};
use lagrangian::prelude::*;
use lagrangian_bench::chain::{
    BETA, CompensatedVerlet, DynFpu, DynUserFpu, Fpu, UserFpu, Verlet, start_array, start_q,
};
use lagrangian_runtime::DynIntegrator;

const H: f64 = 0.05;
const STEPS: usize = 20;

/// Seconds per step, best of `repeats` runs of `STEPS` steps.
fn seconds_per_step(repeats: usize, mut run: impl FnMut()) -> f64 {
    (0..repeats)
        .map(|_| {
            let t = Instant::now();
            run();
            t.elapsed().as_secs_f64() / STEPS as f64
        })
        .fold(f64::INFINITY, f64::min)
}

/// Seconds per step at size `N` of each contender.
#[derive(Clone, Copy)]
struct Costs {
    trapezoid: f64,
    /// The trapezoid step with `Summation::Plain` (the hand-written step's
    /// arithmetic: no compensated sums).
    plain: f64,
    midpoint: f64,
    /// The plain hand-written Verlet.
    hand: f64,
    /// The hand-written Verlet with compensated sums, in place.
    compensated: f64,
}

/// The [`Costs`] of the const-size chain of `N` masses.
fn costs<const N: usize>(c: &mut Criterion) -> Costs {
    let q0 = start_array::<N>();
    let mut g = c.benchmark_group(format!("FPU-β chain, N = {N}, {STEPS} steps"));
    g.sample_size(10);
    // The integrators keep stepping across iterations: only steps are timed.
    let mut explicit = Integrator::new(Fpu::<N>, Trapezoid, H).start(0.0, q0, [0.0; N]).unwrap();
    let mut explicit_plain =
        Integrator::new(Fpu::<N>, Trapezoid, H).summation(Summation::Plain).start(0.0, q0, [0.0; N]).unwrap();
    let mut implicit = Integrator::new(Fpu::<N>, Midpoint, H).start(0.0, q0, [0.0; N]).unwrap();
    let mut verlet = Verlet::new(&q0);
    let mut kahan = CompensatedVerlet::new(&q0);
    let mut trapezoid = move || {
        explicit.run(STEPS, |_| {}).unwrap();
        black_box(explicit.state().q[0]);
    };
    let mut plain = move || {
        explicit_plain.run(STEPS, |_| {}).unwrap();
        black_box(explicit_plain.state().q[0]);
    };
    let mut compensated = move || {
        for _ in 0..STEPS {
            kahan.step(H);
        }
        black_box(kahan.q[0]);
    };
    let mut midpoint = move || {
        implicit.run(STEPS, |_| {}).unwrap();
        black_box(implicit.state().q[0]);
    };
    let mut hand = move || {
        for _ in 0..STEPS {
            verlet.step(H);
        }
        black_box(verlet.q[0]);
    };
    g.bench_function("trapezoid (explicit, reverse mode)", |b| b.iter(&mut trapezoid));
    g.bench_function("trapezoid (explicit, reverse mode), plain sums", |b| b.iter(&mut plain));
    g.bench_function("midpoint (banded Newton, reverse mode)", |b| b.iter(&mut midpoint));
    g.bench_function("hand-written Verlet", |b| b.iter(&mut hand));
    g.bench_function("hand-written Verlet, compensated sums", |b| b.iter(&mut compensated));
    g.finish();
    Costs {
        trapezoid: seconds_per_step(20, &mut trapezoid),
        plain: seconds_per_step(20, &mut plain),
        midpoint: seconds_per_step(10, &mut midpoint),
        hand: seconds_per_step(50, &mut hand),
        compensated: seconds_per_step(50, &mut compensated),
    }
}

fn slope(n: &[f64], t: &[f64]) -> f64 {
    let x: Vec<f64> = n.iter().map(|v| v.ln()).collect();
    let y: Vec<f64> = t.iter().map(|v| v.ln()).collect();
    let (mx, my) = (x.iter().sum::<f64>() / x.len() as f64, y.iter().sum::<f64>() / y.len() as f64);
    let sxy: f64 = x.iter().zip(&y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let sxx: f64 = x.iter().map(|a| (a - mx) * (a - mx)).sum();
    sxy / sxx
}

fn scaling(c: &mut Criterion) {
    let sizes = [100.0, 200.0, 500.0, 1000.0, 2000.0];
    let rows = [costs::<100>(c), costs::<200>(c), costs::<500>(c), costs::<1000>(c), costs::<2000>(c)];
    println!("\nFPU-β chain, µs per step (best of repeated runs of {STEPS} steps):");
    table(&sizes, &rows);
    let column = |k: usize| -> Vec<f64> { rows.iter().map(|r| [r.trapezoid, r.midpoint, r.hand][k]).collect() };
    println!(
        "fitted cost exponent in N: trapezoid {:.2}, midpoint {:.2}, hand-written {:.2}",
        slope(&sizes, &column(0)),
        slope(&sizes, &column(1)),
        slope(&sizes, &column(2))
    );
}

/// The µs per step of each contender and the ratios of the explicit
/// trapezoid to the plain and the compensated hand-written Verlet.
fn table(sizes: &[f64], rows: &[Costs]) {
    println!(
        "{:>7} {:>10} {:>10} {:>10} {:>12} {:>14} {:>14} {:>11}",
        "N", "trapezoid", "plain", "midpoint", "hand Verlet", "compensated", "trap/compens.", "plain/hand"
    );
    for (n, r) in sizes.iter().zip(rows) {
        println!(
            "{n:>7} {:>10.2} {:>10.2} {:>10.2} {:>12.3} {:>14.3} {:>14.2} {:>11.2}",
            r.trapezoid * 1e6,
            r.plain * 1e6,
            r.midpoint * 1e6,
            r.hand * 1e6,
            r.compensated * 1e6,
            r.trapezoid / r.compensated,
            r.plain / r.hand
        );
    }
}

/// The [`Costs`] of the run-time-sized chain of `n` masses, `steps` steps
/// per timed run.
fn dyn_costs(c: &mut Criterion, n: usize, steps: usize, repeats: usize) -> Costs {
    let q0 = start_q(n);
    let v0 = vec![0.0; n];
    let mut explicit = DynIntegrator::new(DynFpu(n), Trapezoid, H).start(0.0, &q0, &v0).unwrap();
    let mut explicit_plain =
        DynIntegrator::new(DynFpu(n), Trapezoid, H).summation(Summation::Plain).start(0.0, &q0, &v0).unwrap();
    let mut implicit = DynIntegrator::new(DynFpu(n), Midpoint, H).start(0.0, &q0, &v0).unwrap();
    let mut verlet = Verlet::new(&q0);
    let mut hand = move || {
        for _ in 0..steps {
            verlet.step(H);
        }
        black_box(verlet.q[0]);
    };
    let mut kahan = CompensatedVerlet::new(&q0);
    let mut compensated = move || {
        for _ in 0..steps {
            kahan.step(H);
        }
        black_box(kahan.q[0]);
    };
    let mut trapezoid = move || {
        explicit.run(steps, |_| {}).unwrap();
        black_box(explicit.state().q[0]);
    };
    let mut plain = move || {
        explicit_plain.run(steps, |_| {}).unwrap();
        black_box(explicit_plain.state().q[0]);
    };
    let mut midpoint = move || {
        implicit.run(steps, |_| {}).unwrap();
        black_box(implicit.state().q[0]);
    };
    let mut g = c.benchmark_group(format!("run-time-sized FPU-β chain, N = {n}, {steps} steps"));
    g.sample_size(10).warm_up_time(Duration::from_millis(500)).measurement_time(Duration::from_secs(3));
    g.bench_function("trapezoid (explicit)", |b| b.iter(&mut trapezoid));
    g.bench_function("trapezoid (explicit), plain sums", |b| b.iter(&mut plain));
    g.bench_function("midpoint (banded Newton)", |b| b.iter(&mut midpoint));
    g.bench_function("hand-written Verlet", |b| b.iter(&mut hand));
    g.bench_function("hand-written Verlet, compensated sums", |b| b.iter(&mut compensated));
    g.finish();
    let per_step = |repeats: usize, run: &mut dyn FnMut()| {
        (0..repeats)
            .map(|_| {
                let t = Instant::now();
                run();
                t.elapsed().as_secs_f64() / steps as f64
            })
            .fold(f64::INFINITY, f64::min)
    };
    Costs {
        trapezoid: per_step(repeats, &mut trapezoid),
        plain: per_step(repeats, &mut plain),
        midpoint: per_step(repeats, &mut midpoint),
        hand: per_step(5 * repeats, &mut hand),
        compensated: per_step(5 * repeats, &mut compensated),
    }
}

/// `VmHWM` of this process from `/proc/self/status`, if readable.
fn peak_memory() -> Option<String> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    status.lines().find(|l| l.starts_with("VmHWM:")).map(|l| l["VmHWM:".len()..].trim().to_string())
}

fn dyn_scaling(c: &mut Criterion) {
    // (N, steps per timed run, repeats)
    let sizes = [(100, 20, 20), (1_000, 20, 10), (10_000, 10, 5), (100_000, 2, 3)];
    let rows: Vec<Costs> = sizes.iter().map(|&(n, steps, repeats)| dyn_costs(c, n, steps, repeats)).collect();
    println!("\nrun-time-sized FPU-β chain (DynIntegrator), µs per step (best of repeated runs):");
    let n: Vec<f64> = sizes.iter().map(|s| s.0 as f64).collect();
    table(&n, &rows);
    let (t, m): (Vec<f64>, Vec<f64>) = rows.iter().map(|r| (r.trapezoid, r.midpoint)).unzip();
    println!(
        "fitted cost exponent in N (100 … 100 000): trapezoid {:.2}, midpoint {:.2}",
        slope(&n, &t),
        slope(&n, &m)
    );
    println!("peak resident memory of the bench process (VmHWM): {}", peak_memory().unwrap_or("unavailable".into()));
}

/// The explicit step at N = 1000 on both chains (the bench's and a new
/// user's: `lagrangian_bench::chain`), with the size known at compile time
/// and at run time, each with compensated and plain sums, against the
/// hand-written Verlet: criterion's timings, then a table of µs per step
/// (best of repeated runs of 20 steps, all in this run) and each over the
/// plain hand-written Verlet.
fn explicit_step(c: &mut Criterion) {
    const N: usize = 1000;
    /// `STEPS` steps of one contender.
    type Run = Box<dyn FnMut()>;
    fn summation(plain: bool) -> Summation {
        if plain { Summation::Plain } else { Summation::Compensated }
    }
    fn fixed<S: Lagrangian<N> + 'static>(system: S, plain: bool) -> Run {
        let mut sim = Integrator::new(system, Trapezoid, H)
            .summation(summation(plain))
            .start(0.0, start_array::<N>(), [0.0; N])
            .unwrap();
        Box::new(move || {
            sim.run(STEPS, |_| {}).unwrap();
            black_box(sim.state().q[0]);
        })
    }
    fn dynamic<S: DynLagrangian + 'static>(system: S, plain: bool) -> Run {
        let n = system.dimension();
        let mut sim = DynIntegrator::new(system, Trapezoid, H)
            .summation(summation(plain))
            .start(0.0, &start_q(n), &vec![0.0; n])
            .unwrap();
        Box::new(move || {
            sim.run(STEPS, |_| {}).unwrap();
            black_box(sim.state().q[0]);
        })
    }
    let q0 = start_q(N);
    let mut verlet = Verlet::new(&q0);
    let mut kahan = CompensatedVerlet::new(&q0);
    let mut contenders: Vec<(&str, Run)> = vec![
        (
            "hand-written Verlet",
            Box::new(move || {
                for _ in 0..STEPS {
                    verlet.step(H);
                }
                black_box(verlet.q[0]);
            }),
        ),
        (
            "hand-written Verlet, compensated sums",
            Box::new(move || {
                for _ in 0..STEPS {
                    kahan.step(H);
                }
                black_box(kahan.q[0]);
            }),
        ),
        ("trapezoid, bench's chain", fixed(Fpu::<N>, false)),
        ("trapezoid, bench's chain, plain sums", fixed(Fpu::<N>, true)),
        ("trapezoid, user's chain", fixed(UserFpu::<N> { beta: BETA }, false)),
        ("trapezoid, user's chain, plain sums", fixed(UserFpu::<N> { beta: BETA }, true)),
        ("run-time size, bench's chain", dynamic(DynFpu(N), false)),
        ("run-time size, bench's chain, plain sums", dynamic(DynFpu(N), true)),
        ("run-time size, user's chain", dynamic(DynUserFpu { n: N, beta: BETA }, false)),
        ("run-time size, user's chain, plain sums", dynamic(DynUserFpu { n: N, beta: BETA }, true)),
    ];
    let mut g = c.benchmark_group(format!("explicit FPU-β step, N = {N}, {STEPS} steps"));
    g.sample_size(20);
    for (name, run) in &mut contenders {
        g.bench_function(*name, |b| b.iter(&mut *run));
    }
    g.finish();
    let best: Vec<f64> = contenders.iter_mut().map(|(_, run)| seconds_per_step(50, run)).collect();
    println!(
        "\nexplicit FPU-β step, N = {N}, µs per step (best of 50 runs of {STEPS} steps) and over the hand-written Verlet:"
    );
    for ((name, _), t) in contenders.iter().zip(&best) {
        println!("{name:>42} {:>8.3} {:>6.2}", t * 1e6, t / best[0]);
    }
}

criterion_group!(benches, explicit_step, scaling, dyn_scaling);
criterion_main!(benches);
