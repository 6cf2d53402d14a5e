//! Time-transformed (Sundman–Poincaré) steps against fixed steps and DOP853
//! on Kepler e = 0.9 over 1000 orbits, at final position errors 1e-6 and
//! 1e-9, in one run.
//!
//! Run with `cargo bench -p lagrangian-bench --bench time_transformed`
//! (cargo's `bench` profile = release). Every method is swept from coarse to
//! fine (step `σ` in `s` or step count, 8 settings per factor 2; tolerance,
//! 8 per decade), and per target the coarsest setting for which it and the
//! next two finer ones meet the target is chosen (the bench crate's
//! calibration rule: the error is not monotone). That setting is then timed
//! as the median of [`REPEATS`] runs, and one more run records the energy
//! error. Prints a Markdown table.
#![allow(missing_docs)]

use std::time::Instant;

use lagrangian::prelude::*;
use lagrangian::time_transform::SStepper;
use lagrangian_bench::calibrate::{self, Limits, Point};
use lagrangian_bench::exact;
use lagrangian_bench::methods::{Method, Setting};
use lagrangian_bench::problem::{Adapter, Problem};
use lagrangian_bench::problems::{Dd, Kepler, KeplerSys};

const E: f64 = 0.9;
const ORBITS: f64 = 1000.0;
const TARGETS: [f64; 2] = [1e-6, 1e-9];
/// Timed runs per chosen setting (median reported).
const REPEATS: usize = 5;
/// A sweep stops after a run longer than this (seconds).
const BUDGET: f64 = 4.0;

fn t_end() -> f64 {
    ORBITS * 2.0 * core::f64::consts::PI
}

/// `q(T)` from Kepler's equation in double-double, at the `f64` time `T`.
fn reference() -> [f64; 2] {
    exact::kepler_position(Dd::from(E), Dd::from(t_end())).map(|x| x.to_f64())
}

fn energy(q: &[f64; 2], v: &[f64; 2]) -> f64 {
    0.5 * (v[0] * v[0] + v[1] * v[1]) - 1.0 / q[0].hypot(q[1])
}

/// One time-transformed run: final position, steps, seconds, relative
/// energy error at `T` and its maximum over the steps (when `watch`).
#[derive(Clone, Debug, Default)]
struct Outcome {
    q: Vec<f64>,
    steps: u64,
    seconds: f64,
    energy_final: f64,
    energy_max: f64,
    newton_per_step: f64,
    /// Right-hand-side evaluations (DOP853).
    evaluations: u64,
    failure: Option<String>,
}

type Tt<G> = TimeTransformed<KeplerSys, G, 2>;

fn tt_run<G, I>(
    build: &dyn Fn(f64) -> Result<Adaptive<I, KeplerSys, G, 2, 3>, String>,
    sigma: f64,
    watch: bool,
) -> Outcome
where
    G: StepDensity<2>,
    I: SStepper<3, System = Tt<G>>,
{
    let start = Instant::now();
    let mut sim = match build(sigma) {
        Ok(sim) => sim,
        Err(e) => return Outcome { failure: Some(e), ..Outcome::default() },
    };
    let (q0, v0) = exact::kepler_start(E);
    let e0 = energy(&q0, &v0);
    let mut worst = 0.0f64;
    let result = sim.run_until(t_end(), |s| {
        if watch {
            worst = worst.max(((s.energy().unwrap_or(f64::NAN) - e0) / e0).abs());
        }
    });
    let seconds = start.elapsed().as_secs_f64();
    let stats = sim.stats();
    let newton_per_step = stats.newton_iterations as f64 / stats.steps.max(1) as f64;
    match result {
        Ok(()) => Outcome {
            q: sim.state().q.to_vec(),
            steps: stats.steps,
            seconds,
            energy_final: sim.energy().map_or(f64::NAN, |e| ((e - e0) / e0).abs()),
            energy_max: worst,
            newton_per_step,
            ..Outcome::default()
        },
        Err(e) => Outcome { failure: Some(e.to_string()), steps: stats.steps, seconds, ..Outcome::default() },
    }
}

/// One run of the explicit time-transformed splitting.
fn split_run(
    build: &dyn Fn(f64) -> Result<ExplicitAdaptive<KeplerSys, f64, 2>, String>,
    sigma: f64,
    watch: bool,
) -> Outcome {
    let start = Instant::now();
    let mut sim = match build(sigma) {
        Ok(sim) => sim,
        Err(e) => return Outcome { failure: Some(e), ..Outcome::default() },
    };
    let (q0, v0) = exact::kepler_start(E);
    let e0 = energy(&q0, &v0);
    let mut worst = 0.0f64;
    let result = sim.run_until(t_end(), |s| {
        if watch {
            worst = worst.max(((s.energy() - e0) / e0).abs());
        }
    });
    let seconds = start.elapsed().as_secs_f64();
    let stats = sim.stats();
    match result {
        Ok(()) => Outcome {
            q: sim.state().q.to_vec(),
            steps: stats.steps,
            seconds,
            energy_final: ((sim.energy() - e0) / e0).abs(),
            energy_max: worst,
            evaluations: stats.gradient_evaluations,
            ..Outcome::default()
        },
        Err(e) => Outcome { failure: Some(e.to_string()), steps: stats.steps, seconds, ..Outcome::default() },
    }
}

/// An explicit time-transformed method: `σ` on `σ0 · 2^{-k/8}`.
fn split(
    label: &str,
    sigma0: f64,
    build: &dyn Fn(f64) -> Result<ExplicitAdaptive<KeplerSys, f64, 2>, String>,
    rows: &mut Vec<Row>,
) {
    let sigmas = (0..200).map(|k| sigma0 * 2f64.powf(-(k as f64) / 8.0));
    let describe = |sigma: f64, o: &Outcome| format!("σ = {sigma:.4}, {} gradients", o.evaluations);
    calibrate_outcomes(label, sigmas, &|sigma, watch| split_run(build, sigma, watch), &describe, rows);
}

fn median(mut xs: Vec<f64>) -> f64 {
    xs.sort_by(f64::total_cmp);
    xs[xs.len() / 2]
}

/// One row of the table.
struct Row {
    method: String,
    target: f64,
    setting: String,
    steps: u64,
    error: f64,
    seconds: f64,
    energy_final: f64,
    energy_max: f64,
}

/// Sweeps `settings` (coarse to fine) with `run(setting, watch)`, then per
/// target picks the coarsest setting for which it and the next two meet it.
fn calibrate_outcomes(
    label: &str,
    settings: impl Iterator<Item = f64>,
    run: &dyn Fn(f64, bool) -> Outcome,
    describe: &dyn Fn(f64, &Outcome) -> String,
    rows: &mut Vec<Row>,
) {
    let want = reference();
    let mut sweep: Vec<(f64, Outcome, Option<f64>)> = Vec::new();
    for setting in settings {
        let out = run(setting, false);
        let err = if out.failure.is_none() { calibrate::error_of(&out.q, &want) } else { None };
        eprintln!("{label}: {setting:.4e}, {} steps, error {err:?}, {:.3} s {:?}", out.steps, out.seconds, out.failure);
        let slow = out.seconds > BUDGET;
        sweep.push((setting, out, err));
        let n = sweep.len();
        if (n >= 3 && sweep[n - 3..].iter().all(|p| p.2.is_some_and(|e| e <= TARGETS[1]))) || slow {
            break;
        }
    }
    for target in TARGETS {
        let Some(k) = (0..sweep.len().saturating_sub(2))
            .find(|&k| sweep[k..k + 3].iter().all(|p| p.2.is_some_and(|e| e <= target)))
        else {
            let best = sweep.iter().filter_map(|p| p.2).fold(f64::INFINITY, f64::min);
            rows.push(Row {
                method: label.into(),
                target,
                setting: format!("not reached (smallest error in the sweep {best:.1e})"),
                steps: 0,
                error: f64::NAN,
                seconds: f64::NAN,
                energy_final: f64::NAN,
                energy_max: f64::NAN,
            });
            continue;
        };
        let setting = sweep[k].0;
        let error = sweep[k..k + 3].iter().filter_map(|p| p.2).fold(0.0, f64::max);
        let seconds = median((0..REPEATS).map(|_| run(setting, false).seconds).collect());
        let watched = run(setting, true);
        rows.push(Row {
            method: label.into(),
            target,
            setting: describe(setting, &watched),
            steps: watched.steps,
            error,
            seconds,
            energy_final: watched.energy_final,
            energy_max: watched.energy_max,
        });
    }
}

/// A time-transformed method: `σ` on `σ0 · 2^{-k/8}`.
fn time_transformed<G, I>(
    label: &str,
    sigma0: f64,
    build: &dyn Fn(f64) -> Result<Adaptive<I, KeplerSys, G, 2, 3>, String>,
    rows: &mut Vec<Row>,
) where
    G: StepDensity<2>,
    I: SStepper<3, System = Tt<G>>,
{
    let sigmas = (0..200).map(|k| sigma0 * 2f64.powf(-(k as f64) / 8.0));
    let describe = |sigma: f64, o: &Outcome| format!("σ = {sigma:.4}, {:.2} Newton it./step", o.newton_per_step);
    calibrate_outcomes(label, sigmas, &|sigma, watch| tt_run(build, sigma, watch), &describe, rows);
}

type V4 = nalgebra034::Vector4<f64>;

/// Kepler as a first-order system for DOP853.
struct KeplerOde;

impl ode_solvers::System<f64, V4> for KeplerOde {
    fn system(&self, _t: f64, y: &V4, dy: &mut V4) {
        let r2 = y[0] * y[0] + y[1] * y[1];
        let r3 = r2 * r2.sqrt();
        *dy = V4::new(y[2], y[3], -y[0] / r3, -y[1] / r3);
    }
}

/// ode_solvers' DOP853 with `rtol = atol = tol`, sparse output (the
/// accepted steps, no extra stages); the energy from the accepted steps.
fn dop853(tol: f64, watch: bool) -> Outcome {
    let (q0, v0) = exact::kepler_start(E);
    let t = t_end();
    let start = Instant::now();
    let mut s = ode_solvers::Dop853::from_param(
        KeplerOde,
        0.0,
        t,
        t,
        V4::new(q0[0], q0[1], v0[0], v0[1]),
        tol,
        tol,
        0.9,
        0.0,
        0.333,
        6.0,
        t,
        0.0,
        50_000_000,
        1000,
        ode_solvers::OutputType::Sparse,
    );
    let result = s.integrate();
    let seconds = start.elapsed().as_secs_f64();
    let stats = match result {
        Ok(stats) => stats,
        Err(e) => return Outcome { failure: Some(e.to_string()), seconds, ..Outcome::default() },
    };
    let e0 = energy(&q0, &v0);
    let rel = |y: &V4| ((energy(&[y[0], y[1]], &[y[2], y[3]]) - e0) / e0).abs();
    match (s.x_out().last(), s.y_out().last()) {
        (Some(&tl), Some(y)) if (tl - t).abs() <= 1e-9 * t => Outcome {
            q: vec![y[0], y[1]],
            steps: stats.accepted_steps as u64,
            seconds,
            energy_final: rel(y),
            energy_max: if watch { s.y_out().iter().map(rel).fold(0.0, f64::max) } else { 0.0 },
            evaluations: stats.num_eval as u64,
            ..Outcome::default()
        },
        _ => Outcome { failure: Some("stopped before T".into()), seconds, ..Outcome::default() },
    }
}

/// Fixed steps and DOP853 through the report's own sweep and runner.
fn report_method(problem: &dyn Problem, method: Method, rows: &mut Vec<Row>) {
    let want = reference();
    let limits = Limits { smallest_target: TARGETS[1], run_budget: BUDGET, per_octave: 8 };
    let points: Vec<Point> = calibrate::sweep(problem, method, &want, t_end(), limits, |p| {
        eprintln!("{}: {:?}, {} steps, error {:?}, {:.3} s", method.name(), p.setting, p.steps, p.error, p.seconds);
    });
    for target in TARGETS {
        let Some(k) = calibrate::select(&points, target) else {
            rows.push(Row {
                method: method.name(),
                target,
                setting: "not reached in the sweep".into(),
                steps: 0,
                error: f64::NAN,
                seconds: f64::NAN,
                energy_final: f64::NAN,
                energy_max: f64::NAN,
            });
            continue;
        };
        let setting = points[k].setting;
        let seconds = median((0..REPEATS).map(|_| problem.run(method, setting, t_end(), 0).seconds).collect());
        // 2000 energy samples (dense output for DOP853): the last is at `T`.
        let sampled = problem.run(method, setting, t_end(), 2000);
        let energy_final = sampled.energy.last().map_or(f64::NAN, |e| e.1.abs());
        let energy_max = sampled.energy.iter().fold(0.0f64, |m, e| m.max(e.1.abs()));
        rows.push(Row {
            method: method.name(),
            target,
            setting: match setting {
                Setting::Steps(n) => format!("{n} fixed steps, h = {:.4}", t_end() / n as f64),
                Setting::Tolerance(tol) => format!("rtol = atol = {tol:.2e}"),
                Setting::Sigma(sigma) => format!("σ = {sigma:.4}"),
            },
            steps: points[k].steps,
            error: calibrate::worst_of_three(&points, k).unwrap_or(f64::NAN),
            seconds,
            energy_final,
            energy_max,
        });
    }
}

fn main() {
    // `cargo bench` passes `--bench`; a name filter selects methods by substring.
    let filter: Vec<String> = std::env::args().skip(1).filter(|a| !a.starts_with("--")).collect();
    let wanted = |name: &str| filter.is_empty() || filter.iter().any(|f| name.contains(f.as_str()));
    let (q0, v0) = exact::kepler_start(E);
    let r32 = RadiusPower::new([0, 1], 1.5).expect("finite exponent");
    // The automatic monitor; its floor caps the step at σ/√floor ≈ 30σ, far
    // above the steps near apocentre (κ ≈ 0.1 there), so it does not act.
    let auto = Curvature::new(1e-3).expect("positive floor");
    let mut rows = Vec::new();

    macro_rules! tt {
        ($label:expr, $sigma0:expr, $monitor:expr, rule $m:expr) => {
            if wanted($label) {
                time_transformed(
                    $label,
                    $sigma0,
                    &|s| {
                        TimeTransformed::new(KeplerSys, $monitor)
                            .rule($m, s)
                            .start(0.0, q0, v0)
                            .map_err(|e| e.to_string())
                    },
                    &mut rows,
                );
            }
        };
        ($label:expr, $sigma0:expr, $monitor:expr, galerkin $s:literal) => {
            if wanted($label) {
                time_transformed(
                    $label,
                    $sigma0,
                    &|s| {
                        TimeTransformed::new(KeplerSys, $monitor)
                            .galerkin(Galerkin::<$s, $s>::gauss(), s)
                            .start(0.0, q0, v0)
                            .map_err(|e| e.to_string())
                    },
                    &mut rows,
                );
            }
        };
    }
    tt!("tt midpoint, r^3/2", 0.004, r32, rule Midpoint);
    tt!("tt galerkin-2, r^3/2", 0.2, r32, galerkin 2);
    tt!("tt galerkin-4, r^3/2", 0.8, r32, galerkin 4);
    tt!("tt galerkin-6, r^3/2", 1.2, r32, galerkin 6);
    tt!("tt galerkin-2, auto", 0.2, auto, galerkin 2);
    tt!("tt galerkin-4, auto", 0.8, auto, galerkin 4);
    tt!("tt galerkin-6, auto", 1.2, auto, galerkin 6);

    // The explicit splitting (no Newton): f' = x^{-α} of Γ = f(T + p_t) − f(−V).
    macro_rules! split {
        ($label:expr, $sigma0:expr, $f:expr, $comp:expr, $form:expr) => {
            if wanted($label) {
                split(
                    $label,
                    $sigma0,
                    &|s| {
                        ExplicitTimeTransformed::new(KeplerSys, $f, s)
                            .composition($comp)
                            .form($form)
                            .start(0.0, q0, v0)
                            .map_err(|e| e.to_string())
                    },
                    &mut rows,
                );
            }
        };
    }
    let (r32s, logh) = (TimeFunction::Power(1.5), TimeFunction::Logarithmic);
    let (kdk, dkd) = (LeapfrogForm::KickDriftKick, LeapfrogForm::DriftKickDrift);
    split!("split r^3/2 yoshida-4 kdk", 0.2, r32s, Composition::YOSHIDA4, kdk);
    split!("split r^3/2 yoshida-6 kdk", 0.4, r32s, Composition::YOSHIDA6, kdk);
    split!("split r^3/2 yoshida-6 dkd", 0.4, r32s, Composition::YOSHIDA6, dkd);
    split!("split r^3/2 kahan-li-8 kdk", 0.8, r32s, Composition::KAHAN_LI8, kdk);
    split!("split r^3/2 kahan-li-8 dkd", 0.8, r32s, Composition::KAHAN_LI8, dkd);
    split!("split logH kahan-li-8 kdk", 0.8, logh, Composition::KAHAN_LI8, kdk);
    split!("split logH kahan-li-8 dkd", 0.8, logh, Composition::KAHAN_LI8, dkd);
    split!("split r^2 kahan-li-8 dkd", 0.8, TimeFunction::Power(2.0), Composition::KAHAN_LI8, dkd);

    let problem = Adapter::<_, 2, 4>(Kepler::<900> { scale: ORBITS / 10.0 });
    assert!((problem.horizon() - t_end()).abs() <= 1e-9 * t_end(), "the report problem has another horizon");
    if wanted("ode_solvers-dop853") {
        let tols = (0..200).map(|k| 1e-3 * 10f64.powf(-(k as f64) / 8.0)).take_while(|&t| t >= 1e-16);
        let describe = |tol: f64, o: &Outcome| format!("rtol = atol = {tol:.2e}, {} evaluations", o.evaluations);
        calibrate_outcomes("ode_solvers-dop853", tols, &dop853, &describe, &mut rows);
    }
    for method in [Method::Galerkin(6), Method::Galerkin(8)] {
        if wanted(&method.name()) {
            report_method(&problem, method, &mut rows);
        }
    }

    println!(
        "\nKepler e = {E}, {ORBITS} orbits (T = {:.4}), final position error max_i |q_i(T) − q_i^exact(T)|",
        t_end()
    );
    println!("time: median of {REPEATS} runs; energy: |E − E0|/|E0| at T and its maximum over the run\n");
    println!("| target | method | setting | steps | error (worst of 3) | time | energy at T | max energy |");
    println!("| --- | --- | --- | --- | --- | --- | --- | --- |");
    for target in TARGETS {
        for r in rows.iter().filter(|r| r.target == target) {
            println!(
                "| {:.0e} | {} | {} | {} | {:.2e} | {:.1} ms | {:.1e} | {:.1e} |",
                r.target,
                r.method,
                r.setting,
                r.steps,
                r.error,
                r.seconds * 1e3,
                r.energy_final,
                r.energy_max
            );
        }
    }
}
