//! One tolerance-driven solve (`lagrangian::Auto`, choice and pilot
//! included) of a report problem at its horizon, for instruction counts
//! that do not depend on the load of the machine:
//!
//! ```text
//! cargo build --release -p lagrangian-bench --example auto_solve
//! valgrind --tool=callgrind target/release/examples/auto_solve fpu-beta 3e-11
//! ```
//!
//! `PROBLEM RTOL`: a problem id of the report (`--list` of the report
//! binary) and the relative tolerance. Prints the method the solve chose,
//! its reason, the steps of the survey and pilot and of the final run, the
//! step and the estimated error. The run keeps only its last node, as the
//! report's timed runs do.
#![allow(missing_docs)]

use lagrangian_bench::methods::{Method, Setting};
use lagrangian_bench::problem;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [id, rtol] = &args[..] else {
        eprintln!("usage: auto_solve PROBLEM RTOL");
        std::process::exit(2);
    };
    let rtol: f64 = rtol.parse().expect("RTOL is a number");
    // Double-double Galerkin blocks of the larger problems want a large stack.
    let id = id.clone();
    let worker = std::thread::Builder::new().stack_size(256 << 20).spawn(move || {
        let Some(p) = problem::all(1.0).into_iter().find(|p| p.id() == id) else {
            eprintln!("no problem {id}");
            std::process::exit(2);
        };
        let run = p.run(Method::Auto, Setting::Tolerance(rtol), p.horizon(), 0);
        match (&run.failure, &run.auto) {
            (None, Some(a)) => println!(
                "{id} rtol {rtol:e}: {} ({}), pilot {} steps, final run {} steps, step {:.4e}, estimate {:.2e} of {:.2e} asked",
                a.method,
                a.reason,
                a.pilot_steps,
                run.steps - a.pilot_steps,
                a.step,
                a.estimate,
                a.requested
            ),
            (failure, _) => {
                eprintln!("{id} rtol {rtol:e}: {failure:?}");
                std::process::exit(1);
            }
        }
    });
    worker.expect("a worker thread").join().expect("the solve does not panic");
}
