//! Energy-preserving midpoint steps on the bench's FPU-β chain with its
//! size known at run time (`lagrangian_bench::chain::DynFpu`, `h = 0.05`),
//! through `Problem` with vectors and `Policy::energy_preserving`: the cost of a step
//! against `N`, and against a fixed midpoint step of the same chain.
//!
//! ```text
//! cargo build --release -p lagrangian-bench --example dyn_energy_steps
//! target/release/examples/dyn_energy_steps energy 100000 5
//! valgrind --tool=callgrind target/release/examples/dyn_energy_steps energy 1000 20
//! ```
//!
//! `POLICY N STEPS`: `energy` or `fixed`, `N` coordinates, `STEPS` steps
//! after two first steps (the first has the given size, and starts the
//! buffers). Prints the wall time per step; for instruction counts that do
//! not depend on the load of the machine, run it under callgrind with
//! `STEPS` and `2·STEPS` and divide the difference by `STEPS`.
#![allow(missing_docs)]

use std::hint::black_box;
use std::time::Instant;

use lagrangian::prelude::*;
use lagrangian_bench::chain::{DynFpu, start_q};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let parse = |i: usize, default: usize| args.get(i).and_then(|a| a.parse().ok()).unwrap_or(default);
    let energy = args.get(1).is_none_or(|a| a == "energy");
    let (n, steps) = (parse(2, 1000), parse(3, 5));
    let problem = Problem::new(DynFpu(n), 0.0, start_q(n), vec![0.0; n]);
    let policy = if energy { Policy::energy_preserving(0.05) } else { Policy::fixed(0.05) };
    let mut sim = problem.stepper(&Scheme::MIDPOINT, policy).expect("start");
    sim.run(2, |_| {}).expect("first steps");
    let before = sim.stats();
    let start = Instant::now();
    sim.run(steps, |_| {}).expect("steps");
    let per_step = start.elapsed().as_secs_f64() / steps as f64;
    let stats = sim.stats();
    let iterations = (stats.newton_iterations - before.newton_iterations) as f64 / steps as f64;
    let name = if energy { "energy-preserving" } else { "fixed" };
    println!("midpoint, {name}, N = {n}: {per_step:.3e} s per step, {iterations:.2} Newton iterations per step");
    black_box(sim.state().q[0]);
}
