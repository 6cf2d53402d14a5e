//! Implicit time-transformed midpoint steps (curvature monitor, `σ = 0.05`)
//! on the bench's FPU-β chain with its size known at run time
//! (`lagrangian_bench::chain::DynFpu`), through `Problem` with vectors:
//! the cost of a step in `s` against `N`, and against a plain fixed
//! midpoint step of the same chain (`h = 0.05`).
//!
//! ```text
//! cargo build --release -p lagrangian-bench --example dyn_time_transform_steps
//! target/release/examples/dyn_time_transform_steps transformed 30 5
//! valgrind --tool=callgrind target/release/examples/dyn_time_transform_steps transformed 30 2
//! ```
//!
//! `SCHEME N STEPS`: `transformed` or `midpoint`, `N` coordinates, `STEPS`
//! steps after one first step (which starts the buffers). Prints the wall
//! time per step; for instruction counts that do not depend on the load of
//! the machine, run it under callgrind with `STEPS` and `2·STEPS` and
//! divide the difference by `STEPS`.
#![allow(missing_docs)]

use std::hint::black_box;
use std::time::Instant;

use lagrangian::prelude::*;
use lagrangian_bench::chain::{DynFpu, start_q};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let parse = |i: usize, default: usize| args.get(i).and_then(|a| a.parse().ok()).unwrap_or(default);
    let transformed = args.get(1).is_none_or(|a| a == "transformed");
    let (n, steps) = (parse(2, 30), parse(3, 5));
    let problem = Problem::new(DynFpu(n), 0.0, start_q(n), vec![0.0; n]);
    let scheme = if transformed {
        Scheme::MIDPOINT.time_transformed(Curvature::new(1.0).expect("a positive floor"))
    } else {
        Scheme::MIDPOINT
    };
    let mut sim = problem.stepper(&scheme, 0.05).expect("start");
    sim.run(1, |_| {}).expect("first step");
    let before = sim.stats();
    let start = Instant::now();
    sim.run(steps, |_| {}).expect("steps");
    let per_step = start.elapsed().as_secs_f64() / steps as f64;
    let stats = sim.stats();
    let iterations = (stats.newton_iterations - before.newton_iterations) as f64 / steps as f64;
    println!("{}, N = {n}: {per_step:.3e} s per step, {iterations:.2} Newton iterations per step", scheme.name());
    black_box(sim.state().q[0]);
}
