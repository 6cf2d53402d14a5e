//! One tolerance-driven solve (`lagrangian::Auto`, choice and pilot
//! included) of a report problem at its horizon, or one run of a fixed
//! method at a setting, for instruction counts that do not depend on the
//! load of the machine:
//!
//! ```text
//! cargo build --release -p lagrangian-bench --example auto_solve
//! valgrind --tool=callgrind target/release/examples/auto_solve fpu-beta 3e-11
//! valgrind --tool=callgrind target/release/examples/auto_solve fpu-beta composition-kahan-li8 steps=168
//! ```
//!
//! `PROBLEM RTOL`: a problem id of the report (`--list` of the report
//! binary) and the relative tolerance. Prints the method the solve chose,
//! its reason, the steps of the survey and pilot and of the final run, the
//! step and the estimated error; with `CALLGRIND_ERROR=1` also the error
//! against the problem's reference (computed after the run, in the same
//! process: leave it unset when counting instructions).
//!
//! `PROBLEM METHOD steps=N|sigma=S|tol=T`: the report's method `METHOD` at
//! that setting (the report's calibrated settings are in its JSON), for the
//! instructions of the method the auto solve is compared with.
//!
//! `PROBLEM none`: only the set-up both kinds of run share, whose
//! instructions `bench/auto-instructions.sh` subtracts.
//!
//! `PROBLEM calibrate`: the report's calibration of `auto` on the problem
//! (tolerances from `1e-3` down, four per decade; at each target of the full
//! suite the coarsest that, with the next two finer ones, meets it), one
//! line `target rtol error` per target, for the runs above.
//!
//! `HORIZON=F` scales every problem's horizon by `F` (the accuracy grid's
//! spans, `bench/tests/auto.rs`).
//!
//! Every run keeps only its last node, as the report's timed runs do.
#![allow(missing_docs)]

use lagrangian_bench::calibrate::{self, error_of};
use lagrangian_bench::methods::{Method, Setting};
use lagrangian_bench::problem;

fn usage() -> ! {
    eprintln!("usage: auto_solve PROBLEM RTOL | PROBLEM METHOD steps=N|sigma=S|tol=T | PROBLEM none");
    std::process::exit(2);
}

/// `HORIZON=F`: the problems at `F` times the report's horizon (the
/// accuracy grid of `bench/tests/auto.rs` runs some at 0.01 to 0.5).
fn horizon_scale() -> f64 {
    std::env::var("HORIZON").ok().and_then(|v| v.parse().ok()).filter(|f: &f64| *f > 0.0).unwrap_or(1.0)
}

/// `steps=N`, `sigma=S` or `tol=T`.
fn setting(s: &str) -> Option<Setting> {
    let (key, value) = s.split_once('=')?;
    match key {
        "steps" => value.parse().ok().map(Setting::Steps),
        "sigma" => value.parse().ok().map(Setting::Sigma),
        "tol" => value.parse().ok().map(Setting::Tolerance),
        _ => None,
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if let [id, mode] = &args[..]
        && mode == "calibrate"
    {
        let id = id.clone();
        let worker = std::thread::Builder::new().stack_size(256 << 20).spawn(move || calibrate_auto(&id));
        worker.expect("a worker thread").join().expect("the calibration does not panic");
        return;
    }
    let (id, method, setting) = match &args[..] {
        [id, none] if none == "none" => (id.clone(), None, None),
        [id, rtol] => {
            (id.clone(), Some(Method::Auto), Some(Setting::Tolerance(rtol.parse().unwrap_or_else(|_| usage()))))
        }
        [id, method, s] => (
            id.clone(),
            Some(Method::parse(method).unwrap_or_else(|| usage())),
            Some(setting(s).unwrap_or_else(|| usage())),
        ),
        _ => usage(),
    };
    // Double-double Galerkin blocks of the larger problems want a large stack.
    let worker = std::thread::Builder::new().stack_size(256 << 20).spawn(move || {
        let Some(p) = problem::all(horizon_scale()).into_iter().find(|p| p.id() == id) else {
            eprintln!("no problem {id}");
            std::process::exit(2);
        };
        let (Some(method), Some(setting)) = (method, setting) else { return };
        let run = p.run(method, setting, p.horizon(), 0);
        // The reference costs far more than the run: only on request, and
        // never while instructions are counted.
        let error = std::env::var("CALLGRIND_ERROR")
            .is_ok_and(|v| v == "1")
            .then(|| p.reference(p.horizon(), 1e-14).ok().and_then(|r| error_of(&run.q, &r.q)))
            .flatten();
        let error = error.map_or(String::new(), |e| format!(", error {e:.2e}"));
        match (&run.failure, &run.auto) {
            (None, Some(a)) => println!(
                "{id} rtol {setting:?}: {} ({}), pilot {} steps, final run {} steps, step {:.4e}, estimate {:.2e} of {:.2e} asked{error}",
                a.method,
                a.reason,
                a.pilot_steps,
                run.steps - a.pilot_steps,
                a.step,
                a.estimate,
                a.requested
            ),
            (None, None) => println!("{id} {} {setting:?}: {} steps{error}", method.name(), run.steps),
            (failure, _) => {
                eprintln!("{id} {setting:?}: {failure:?}");
                std::process::exit(1);
            }
        }
    });
    worker.expect("a worker thread").join().expect("the solve does not panic");
}

/// The calibrated tolerance of `auto` at each target of the full suite.
fn calibrate_auto(id: &str) {
    const TARGETS: [f64; 3] = [1e-4, 1e-7, 1e-10];
    let Some(p) = problem::all(horizon_scale()).into_iter().find(|p| p.id() == id) else {
        eprintln!("no problem {id}");
        std::process::exit(2);
    };
    let reference = p.reference(p.horizon(), 1e-14).expect("a reference").q;
    let mut points = Vec::new();
    for s in calibrate::settings(p.as_ref(), Method::Auto, 4) {
        let run = p.run(Method::Auto, s, p.horizon(), 0);
        points.push(calibrate::point(s, &run, &reference));
        let n = points.len();
        if n >= 3 && points[n - 3..].iter().all(|q| q.error.is_some_and(|e| e <= TARGETS[2])) {
            break;
        }
    }
    for target in TARGETS {
        match calibrate::select(&points, target) {
            Some(k) => {
                let Setting::Tolerance(rtol) = points[k].setting else { unreachable!("auto runs at a tolerance") };
                println!("{target:e} {rtol:e} {:e}", points[k].error.unwrap_or(f64::NAN));
            }
            None => println!("{target:e} none"),
        }
    }
}
