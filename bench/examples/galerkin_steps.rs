//! Runs of the report's double pendulum and sensor with a Gauss Galerkin
//! rule, for instruction counts that do not depend on the load of the
//! machine:
//!
//! ```text
//! cargo build --release -p lagrangian-bench --example galerkin_steps
//! valgrind --tool=callgrind target/release/examples/galerkin_steps double-pendulum 4 auto 400 10
//! callgrind_annotate --inclusive=yes callgrind.out.PID
//! ```
//!
//! `PROBLEM S ITERATION STEPS RUNS`: `RUNS` runs over the report's horizon
//! (`double-pendulum`: t ≤ 10, `sensor`: t ≤ 2, `kepler-polar`: 1000
//! orbits, `perturbed-pendulum`: t ≤ 314) from the report's initial
//! data, each with `STEPS` fixed steps of Galerkin degree `S` (2 to 8) with
//! `S` Gauss points, the stages solved by `auto` (`StageIteration::Automatic`,
//! the report's `galerkin-fp-S`), `fixed-point` or `newton` (the report's
//! `galerkin-S`). A run starts the integrator anew, as the report's runs
//! do, so the start of a run is counted once per run. It prints the
//! iterations and the evaluations of `L` per step (`point_evaluations`) and
//! the final positions.
#![allow(missing_docs)]

use std::hint::black_box;

use lagrangian::GalerkinIntegrator;
use lagrangian::galerkin::PointEvaluations;
use lagrangian::galerkin::StageIteration;
use lagrangian::prelude::*;
use lagrangian_bench::problems::{DoublePendulum, KeplerPolar, Model, PerturbedPendulum, Sensor};

/// `runs` runs of `steps` steps; the last run's iterations, evaluations and positions.
fn runs<M: Model<N>, const N: usize, const S: usize>(
    model: &M,
    iteration: StageIteration,
    steps: usize,
    runs: usize,
) -> (f64, PointEvaluations, [f64; N]) {
    let (q0, v0) = model.initial();
    let h = model.horizon() / steps as f64;
    let mut last = (0.0, PointEvaluations::default(), q0);
    for _ in 0..runs {
        let method = Galerkin::<S, S>::gauss().with_iteration(iteration);
        let mut sim = GalerkinIntegrator::new(model.system(), method, h).start(0.0, q0, v0).expect("start");
        sim.run(steps, |_| {}).expect("steps");
        let s = sim.stats();
        last = (s.newton_iterations as f64 / s.steps as f64, sim.point_evaluations(), black_box(sim.state().q));
    }
    last
}

fn report<const N: usize>(steps: usize, (iterations, e, q): (f64, PointEvaluations, [f64; N])) {
    let per = |x: u64| x as f64 / steps as f64;
    println!(
        "iterations/step {iterations:.3}  gradients/step {:.2}  hessians/step {:.2}  velocity hessians/step {:.2}  q {q:?}",
        per(e.gradients),
        per(e.hessians),
        per(e.velocity_hessians)
    );
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: galerkin_steps double-pendulum|sensor|kepler-polar|perturbed-pendulum S auto|fixed-point|newton STEPS RUNS";
    let [problem, s, iteration, steps, n] = &args[..] else { panic!("{usage}") };
    let iteration = match iteration.as_str() {
        "auto" => StageIteration::Automatic,
        "fixed-point" => StageIteration::FixedPoint,
        "newton" => StageIteration::Newton,
        _ => panic!("{usage}"),
    };
    let (steps, n): (usize, usize) = (steps.parse().expect(usage), n.parse().expect(usage));
    macro_rules! degree {
        ($model:expr, $n:literal, $($s:literal)*) => {
            match s.as_str() {
                $(stringify!($s) => report(steps, runs::<_, $n, $s>(&$model, iteration, steps, n)),)*
                _ => panic!("{usage}"),
            }
        };
    }
    match problem.as_str() {
        "double-pendulum" => degree!(DoublePendulum { scale: 1.0 }, 2, 2 3 4 5 6 7 8),
        "sensor" => degree!(Sensor { scale: 1.0 }, 2, 2 3 4 5 6 7 8),
        "kepler-polar" => degree!(KeplerPolar { scale: 1.0 }, 2, 2 3 4 5 6 7 8),
        "perturbed-pendulum" => degree!(PerturbedPendulum { scale: 1.0 }, 1, 2 3 4 5 6 7 8),
        _ => panic!("{usage}"),
    }
}
