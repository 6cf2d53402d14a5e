//! The explicit time-transformed splitting on the bench's FPU-β chain with
//! its size known at run time (`lagrangian_bench::chain::DynFpu`), through
//! `Problem` with vectors and `Scheme::Splitting`: the cost of a step in
//! `s` against `N`, and against the run-time explicit composition of the
//! same order on the same chain (Störmer–Verlet for the leapfrog, Kahan–Li
//! 8 of Störmer–Verlet for the splitting composed by Kahan–Li 8).
//!
//! ```text
//! cargo build --release -p lagrangian-bench --example dyn_splitting_steps
//! target/release/examples/dyn_splitting_steps split 10000 20
//! valgrind --tool=callgrind target/release/examples/dyn_splitting_steps split8 1000 20
//! ```
//!
//! `METHOD N STEPS`: `split` (the logarithmic leapfrog, drift–kick–drift),
//! `split8` (composed by Kahan–Li 8), `verlet` or `kahan-li8` (the explicit
//! compositions of trapezoid steps), `N` coordinates, `STEPS` steps after
//! two first steps (which factor the mass matrix and start the buffers).
//! Prints the wall time per step; for instruction counts that do not depend
//! on the load of the machine, run it under callgrind with `STEPS` and
//! `2·STEPS` and divide the difference by `STEPS`.
#![allow(missing_docs)]

use std::hint::black_box;
use std::time::Instant;

use lagrangian::prelude::*;
use lagrangian_bench::chain::{DynFpu, start_q};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let parse = |i: usize, default: usize| args.get(i).and_then(|a| a.parse().ok()).unwrap_or(default);
    let method = args.get(1).map_or("split", String::as_str);
    let (n, steps) = (parse(2, 1000), parse(3, 5));
    let q0 = start_q(n);
    // The steps in `t` near 0.05: the splitting's `dt/ds = 1/(c − V)` is
    // about the inverse of the chain's energy scale at the start (the default
    // shift `c = E + m`, `m` the largest of `|V|` and `|q·∇V| ≤ 4|V|`).
    let potential = -DynFpu(n).lagrangian(0.0, &q0, &vec![0.0; n]);
    let sigma = 0.05 * 4.0 * potential;
    let (scheme, h) = match method {
        "split" => (Scheme::splitting(TimeFunction::Logarithmic, None), sigma),
        "split8" => (Scheme::splitting(TimeFunction::Logarithmic, Some(Composition::KAHAN_LI8)), 4.0 * sigma),
        "verlet" => (Scheme::TRAPEZOID, 0.05),
        "kahan-li8" => (Scheme::composition(Composition::KAHAN_LI8, OnePoint::Trapezoid), 0.2),
        other => panic!("unknown method {other}: split, split8, verlet or kahan-li8"),
    };
    let problem = Problem::new(DynFpu(n), 0.0, q0, vec![0.0; n]);
    let mut sim = problem.stepper(&scheme, h).expect("start");
    sim.run(2, |_| {}).expect("first steps");
    let t = sim.state().t;
    let start = Instant::now();
    sim.run(steps, |_| {}).expect("steps");
    let per_step = start.elapsed().as_secs_f64() / steps as f64;
    let dt = (sim.state().t - t) / steps as f64;
    println!("{}, N = {n}: {per_step:.3e} s per step, dt {dt:.3e} per step", scheme.name());
    black_box(sim.state().q[0]);
}
