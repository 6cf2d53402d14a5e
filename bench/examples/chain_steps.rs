//! A fixed number of explicit steps of the FPU-β chain of
//! `benches/chain_scaling.rs` (`lagrangian_bench::chain`), for instruction
//! counts that do not depend on the load of the machine
//! (`bench/chain-instructions.sh` runs every case under
//! `valgrind --tool=callgrind` and prints (instructions of `2n` steps − of
//! `n`) / `n`, the steady step):
//!
//! ```text
//! cargo build --release -p lagrangian-bench --example chain_steps
//! valgrind --tool=callgrind target/release/examples/chain_steps trapezoid 1000 200
//! ```
//!
//! `CASE N STEPS`, `N` 1000 or 1024, `h = 0.05`. Cases: `hand` (the
//! hand-written Verlet, plain sums), `hand-compensated` (with the Kahan sums
//! the generated steps keep); the generated explicit trapezoid
//! (Störmer–Verlet) step with the size known at compile time on the bench's
//! chain (`trapezoid`) and on the chain as a new user writes it
//! (`user-trapezoid`), and with the size known at run time (`dyn-trapezoid`,
//! `dyn-user-trapezoid`); each of the four with `-plain` appended runs under
//! `Summation::Plain`. `stepper-trapezoid` and `stepper-user-trapezoid` take
//! the run-time-sized steps through `Problem`/`Stepper<S, Dyn>`, the user's
//! way in: against `dyn-trapezoid` and `dyn-user-trapezoid`, the driver
//! named directly (a hidden item of the runtime crate, kept for this
//! comparison), they give the cost of the stepper's dispatch.
//! `problem-trapezoid` and `problem-user-trapezoid` do the same at the
//! compile-time size (`Problem`/`Stepper<S, Dim<N>>`, `N` 1000 or 1024). The
//! four take `-plain` too (`Problem::summation(Summation::Plain)`).
#![allow(missing_docs)]

use std::hint::black_box;

use lagrangian::Dim;
use lagrangian::prelude::*;
use lagrangian::problem::Extended;
use lagrangian_bench::chain::{
    BETA, CompensatedVerlet, DynFpu, DynUserFpu, Fpu, UserFpu, Verlet, start_array, start_q,
};
use lagrangian_runtime::DynIntegrator;

const H: f64 = 0.05;

fn summation(plain: bool) -> Summation {
    if plain { Summation::Plain } else { Summation::Compensated }
}

/// `steps` explicit steps of the const-size system `system`.
fn fixed<S: Lagrangian<N>, const N: usize>(system: S, plain: bool, steps: usize) {
    let mut sim = Integrator::new(system, Trapezoid, H)
        .summation(summation(plain))
        .start(0.0, start_array::<N>(), [0.0; N])
        .expect("start");
    sim.run(steps, |_| {}).expect("steps");
    black_box(sim.state().q[0]);
}

/// `steps` explicit steps of the run-time-sized system `system` through
/// the stepper.
fn stepper<S: DynLagrangian + Clone>(system: S, n: usize, plain: bool, steps: usize) {
    let problem = Problem::new(system, 0.0, start_q(n), vec![0.0; n]).summation(summation(plain));
    let mut sim = problem.stepper(&Scheme::TRAPEZOID, H).expect("start");
    sim.run(steps, |_| {}).expect("steps");
    black_box(sim.state().q[0]);
}

/// `steps` explicit steps of the const-size system `system` through the
/// stepper.
fn problem<S: Lagrangian<N> + Clone, const N: usize>(system: S, plain: bool, steps: usize)
where
    Dim<N>: Extended<N>,
{
    let problem = Problem::new(system, 0.0, start_array::<N>(), [0.0; N]).summation(summation(plain));
    let mut sim = problem.stepper(&Scheme::TRAPEZOID, H).expect("start");
    sim.run(steps, |_| {}).expect("steps");
    black_box(sim.state().q[0]);
}

/// `steps` explicit steps of the run-time-sized system `system`.
fn dynamic<S: DynLagrangian>(system: S, n: usize, plain: bool, steps: usize) {
    let mut sim = DynIntegrator::new(system, Trapezoid, H)
        .summation(summation(plain))
        .start(0.0, &start_q(n), &vec![0.0; n])
        .expect("start");
    sim.run(steps, |_| {}).expect("steps");
    black_box(sim.state().q[0]);
}

fn case<const N: usize>(case: &str, steps: usize)
where
    Dim<N>: Extended<N>,
{
    let (name, plain) = match case.strip_suffix("-plain") {
        Some(name) => (name, true),
        None => (case, false),
    };
    match name {
        "hand" if !plain => {
            let mut s = Verlet::new(&start_q(N));
            for _ in 0..steps {
                s.step(H);
            }
            black_box(s.q[0]);
        }
        "hand-compensated" if !plain => {
            let mut s = CompensatedVerlet::new(&start_q(N));
            for _ in 0..steps {
                s.step(H);
            }
            black_box(s.q[0]);
        }
        "trapezoid" => fixed(Fpu::<N>, plain, steps),
        "user-trapezoid" => fixed(UserFpu::<N> { beta: BETA }, plain, steps),
        "dyn-trapezoid" => dynamic(DynFpu(N), N, plain, steps),
        "dyn-user-trapezoid" => dynamic(DynUserFpu { n: N, beta: BETA }, N, plain, steps),
        "stepper-trapezoid" => stepper(DynFpu(N), N, plain, steps),
        "stepper-user-trapezoid" => stepper(DynUserFpu { n: N, beta: BETA }, N, plain, steps),
        "problem-trapezoid" => problem(Fpu::<N>, plain, steps),
        "problem-user-trapezoid" => problem(UserFpu::<N> { beta: BETA }, plain, steps),
        _ => panic!("unknown case {case}"),
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let usage = "usage: chain_steps CASE N STEPS (N: 1000 or 1024)";
    let name = args.get(1).expect(usage).as_str();
    let n: usize = args.get(2).and_then(|s| s.parse().ok()).expect(usage);
    let steps: usize = args.get(3).and_then(|s| s.parse().ok()).expect(usage);
    match n {
        1000 => case::<1000>(name, steps),
        1024 => case::<1024>(name, steps),
        _ => panic!("{usage}"),
    }
}
