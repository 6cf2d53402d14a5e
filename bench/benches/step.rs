//! ns/step of the generated integrators against hand-written ones.
//!
//! Run with `cargo bench --bench step`; it uses cargo's default `bench`
//! profile (= `release`: opt-level 3, 16 codegen units, no fat LTO), which is
//! what a user of the crate compiles with unless they change it.
#![allow(missing_docs)]

use lagrangian_bench::handwritten;

use criterion::{Criterion, criterion_group, criterion_main};
use handwritten::*;
use lagrangian::{Composition, Integrator, Midpoint, StepBounds, Summation, Trapezoid};
use lagrangian_bench::compositions::{Composition as HandComposition, Stepper};
use lagrangian_bench::problems::{HenonHeilesSys, KeplerSys};
use std::hint::black_box;

// The systems of the tests, so the bench measures what the tests verify.
#[path = "../../tests/common/mod.rs"]
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
    // `Summation::Plain`: the state's sums rounded once, as the hand-written steps do.
    let mut sim =
        Integrator::new(Pendulum { ..P }, Midpoint, H).summation(Summation::Plain).start(0.0, [1.0], [0.0]).unwrap();
    g.bench_function("generated midpoint, plain sums", |b| b.iter(|| black_box(sim.step().unwrap().q)));
    let mut sim =
        Integrator::new(Pendulum { ..P }, Trapezoid, H).summation(Summation::Plain).start(0.0, [1.0], [0.0]).unwrap();
    g.bench_function("generated trapezoid, plain sums", |b| b.iter(|| black_box(sim.step().unwrap().q)));
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
    let mut sim =
        Integrator::new(DoublePendulum { ..DP }, Midpoint, H).summation(Summation::Plain).start(0.0, q0, v0).unwrap();
    g.bench_function("generated midpoint, plain sums", |b| b.iter(|| black_box(sim.step().unwrap().q)));
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

/// Energy-preserving variable steps against fixed steps of the same initial
/// size; prints the Newton iterations per step (over 1e5 steps) beside the
/// timings. The double pendulum starts from rest at (0.5, 0.3), where the
/// energy equation keeps its root (from (1, −0.5) it loses it at step 36).
fn variable_steps(c: &mut Criterion) {
    let mut g = c.benchmark_group("variable steps");
    macro_rules! pair {
        ($name:literal, $system:expr, $q0:expr, $v0:expr) => {{
            let fixed = || Integrator::new($system, Midpoint, H).start(0.0, $q0, $v0).unwrap();
            let variable = || {
                Integrator::new($system, Midpoint, H)
                    .energy_preserving(StepBounds::around(H))
                    .start(0.0, $q0, $v0)
                    .unwrap()
            };
            let (mut f, mut v) = (fixed(), variable());
            f.run(100_000, |_| {}).unwrap();
            v.run(100_000, |_| {}).unwrap();
            let per_step = |s: &lagrangian::Stats| s.newton_iterations as f64 / s.steps as f64;
            println!(
                "{}: newton iterations per step, fixed {:.2}, variable {:.2} (over 1e5 steps)",
                $name,
                per_step(f.stats()),
                per_step(v.stats())
            );
            let mut sim = fixed();
            g.bench_function(concat!($name, " fixed midpoint"), |b| b.iter(|| black_box(sim.step().unwrap().q)));
            let mut sim = variable();
            g.bench_function(concat!($name, " variable midpoint"), |b| b.iter(|| black_box(sim.step().unwrap().q)));
        }};
    }
    pair!("pendulum", Pendulum { ..P }, [1.0], [0.0]);
    pair!("double pendulum", DoublePendulum { ..DP }, [0.5, 0.3], [0.0, 0.0]);
    g.finish();
}

/// The explicit path: `Trapezoid` on separable constant-mass systems
/// (Störmer–Verlet, no Newton) and Kahan–Li's order-8 composition of it,
/// against hand-written Störmer–Verlet and the bench's hand-written
/// composition of the same scheme, each also with the compensated sums the
/// generated steps keep (`Stepper::step_compensated`).
fn explicit(c: &mut Criterion) {
    let mut g = c.benchmark_group("explicit");
    let (kq, kv) = ([0.5, 0.0], [0.0, 3f64.sqrt()]);
    let kepler = |q: &[f64; 2]| {
        let r2 = q[0] * q[0] + q[1] * q[1];
        let k = -1.0 / (r2 * r2.sqrt());
        [k * q[0], k * q[1]]
    };
    let mut sim = Integrator::new(KeplerSys, Trapezoid, H).start(0.0, kq, kv).unwrap();
    g.bench_function("kepler generated trapezoid", |b| b.iter(|| black_box(sim.step().unwrap().q)));
    let mut sim = Integrator::new(KeplerSys, Trapezoid, H).summation(Summation::Plain).start(0.0, kq, kv).unwrap();
    g.bench_function("kepler generated trapezoid, plain sums", |b| b.iter(|| black_box(sim.step().unwrap().q)));
    let mut hand = Stepper::new(HandComposition::Verlet, [1.0; 2], &kepler, H, kq, kv);
    g.bench_function("kepler hand-written verlet", |b| {
        b.iter(|| {
            hand.step(&kepler);
            black_box(hand.q)
        })
    });
    let mut hand = Stepper::new(HandComposition::Verlet, [1.0; 2], &kepler, H, kq, kv);
    g.bench_function("kepler hand-written compensated verlet", |b| {
        b.iter(|| {
            hand.step_compensated(&kepler);
            black_box(hand.q)
        })
    });
    let (hq, hv) = ([0.0, 0.1], [0.4, 0.0]);
    let henon_heiles = |q: &[f64; 2]| [-q[0] - 2.0 * q[0] * q[1], -q[1] - q[0] * q[0] + q[1] * q[1]];
    let mut sim = Integrator::new(HenonHeilesSys, Trapezoid, H).start(0.0, hq, hv).unwrap();
    g.bench_function("henon-heiles generated trapezoid", |b| b.iter(|| black_box(sim.step().unwrap().q)));
    let mut sim = Integrator::new(HenonHeilesSys, Trapezoid, H).summation(Summation::Plain).start(0.0, hq, hv).unwrap();
    g.bench_function("henon-heiles generated trapezoid, plain sums", |b| b.iter(|| black_box(sim.step().unwrap().q)));
    let mut hand = Stepper::new(HandComposition::Verlet, [1.0; 2], &henon_heiles, H, hq, hv);
    g.bench_function("henon-heiles hand-written verlet", |b| {
        b.iter(|| {
            hand.step(&henon_heiles);
            black_box(hand.q)
        })
    });
    let mut hand = Stepper::new(HandComposition::Verlet, [1.0; 2], &henon_heiles, H, hq, hv);
    g.bench_function("henon-heiles hand-written compensated verlet", |b| {
        b.iter(|| {
            hand.step_compensated(&henon_heiles);
            black_box(hand.q)
        })
    });
    let params = pendulum_params();
    let pendulum = |q: &[f64; 1]| [-params.d * q[0].sin()];
    let mut sim = Integrator::new(Pendulum { ..P }, Composition::KAHAN_LI8, H).start(0.0, [1.0], [0.0]).unwrap();
    g.bench_function("pendulum generated kahan-li8", |b| b.iter(|| black_box(sim.step().unwrap().q)));
    let plain = |method| Integrator::new(Pendulum { ..P }, method, H).summation(Summation::Plain);
    let mut sim = plain(Composition::KAHAN_LI8).start(0.0, [1.0], [0.0]).unwrap();
    g.bench_function("pendulum generated kahan-li8, plain sums", |b| b.iter(|| black_box(sim.step().unwrap().q)));
    let mut sim = plain(Composition::YOSHIDA6).start(0.0, [1.0], [0.0]).unwrap();
    g.bench_function("pendulum generated yoshida6, plain sums", |b| b.iter(|| black_box(sim.step().unwrap().q)));
    let mut hand = Stepper::new(HandComposition::Yoshida6, [1.0 / params.a], &pendulum, H, [1.0], [0.0]);
    g.bench_function("pendulum hand-written yoshida6", |b| {
        b.iter(|| {
            hand.step(&pendulum);
            black_box(hand.q)
        })
    });
    let mut hand = Stepper::new(HandComposition::KahanLi8, [1.0 / params.a], &pendulum, H, [1.0], [0.0]);
    g.bench_function("pendulum hand-written kahan-li8", |b| {
        b.iter(|| {
            hand.step(&pendulum);
            black_box(hand.q)
        })
    });
    let mut hand = Stepper::new(HandComposition::KahanLi8, [1.0 / params.a], &pendulum, H, [1.0], [0.0]);
    g.bench_function("pendulum hand-written compensated kahan-li8", |b| {
        b.iter(|| {
            hand.step_compensated(&pendulum);
            black_box(hand.q)
        })
    });
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .warm_up_time(std::time::Duration::from_millis(500))
        .measurement_time(std::time::Duration::from_secs(3));
    targets = pendulum, double_pendulum, variable_steps, explicit
}
criterion_main!(benches);
