//! Steps of a Galerkin rule on the bench's FPU-β chain with its size known
//! at run time (`lagrangian_bench::chain::DynFpu`, `h = 0.05`), through
//! `Problem` with vectors and `Scheme::Galerkin`: the cost of a step against `N`.
//!
//! ```text
//! cargo build --release -p lagrangian-bench --example dyn_galerkin_steps
//! target/release/examples/dyn_galerkin_steps 2 100000 5
//! valgrind --tool=callgrind target/release/examples/dyn_galerkin_steps 2 1000 4
//! ```
//!
//! `S N STEPS`: degree `S`, `N` coordinates, `STEPS` steps after one
//! first step (whose start costs more: allocation, straight-line guess).
//! With `ENERGY=1` in the environment the steps are energy-preserving
//! (`Policy::energy_preserving(0.05)`: the step size solves the energy
//! equation, each probe a Newton solve of the node equations).
//! Prints the wall time per step; for instruction counts that do not
//! depend on the load of the machine, run it under callgrind with `STEPS`
//! and `2·STEPS` and divide the difference by `STEPS`.
#![allow(missing_docs)]

use std::hint::black_box;
use std::time::Instant;

use lagrangian::prelude::*;
use lagrangian_bench::chain::{DynFpu, start_q};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let parse = |i: usize, default: usize| args.get(i).and_then(|a| a.parse().ok()).unwrap_or(default);
    let (s, n, steps) = (parse(1, 2), parse(2, 1000), parse(3, 5));
    let problem = Problem::new(DynFpu(n), 0.0, start_q(n), vec![0.0; n]);
    let energy = std::env::var("ENERGY").is_ok_and(|v| v == "1");
    let policy = if energy { Policy::energy_preserving(0.05) } else { Policy::fixed(0.05) };
    let mut sim = problem.stepper(&Scheme::galerkin(s), policy).expect("start");
    sim.step().expect("first step");
    let start = Instant::now();
    sim.run(steps, |_| {}).expect("steps");
    let per_step = start.elapsed().as_secs_f64() / steps as f64;
    let iterations = sim.stats().newton_iterations as f64 / sim.stats().steps as f64;
    let kind = if energy { "energy-preserving" } else { "fixed" };
    println!(
        "Galerkin s = {s} ({kind} steps), N = {n}: {per_step:.3e} s per step, {iterations:.2} Newton iterations per step"
    );
    black_box(sim.state().q[0]);
}
