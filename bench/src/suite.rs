//! Runs the suites: references, calibration sweeps, timing of the selected
//! settings, long energy runs and the stress section, into a [`Report`].

use std::cell::Cell;
use std::sync::mpsc;
use std::time::{Duration, Instant};

use crate::calibrate::{self, Limits};
use crate::methods::{Family, Method, Setting};
use crate::problem::{self, Problem};
use crate::report::*;

/// Which suite.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Suite {
    /// For the test suite: horizons ×0.02, two loose targets, tiny budgets.
    Tiny,
    /// The default: one problem of each family ([`DEFAULT_PROBLEMS`]),
    /// horizons ×0.2, two targets, every method and peer, the stress section
    /// at 10⁵ steps; 70 s of CPU time (one thread) on the 2-core test machine
    /// at a load average of 3, of which the Cartesian double pendulum takes 6 s.
    Default,
    /// `--full`: every problem at its own horizon, three targets, energy runs
    /// over 100 horizons, 10⁷-step runs.
    Full,
    /// `--exhaustive`: ten targets, larger budgets, energy runs over 1000 horizons.
    Exhaustive,
}

/// The problems of the default suite: one of each family (the Kepler orbit
/// at e = 0.5; e = 0.9 and 0.99 stay in its hard-orbit runs).
pub const DEFAULT_PROBLEMS: [&str; 10] = [
    "pendulum",
    "kepler-0.5",
    "henon-heiles",
    "outer-solar-system",
    "double-pendulum",
    "double-pendulum-cartesian",
    "kepler-polar",
    "fpu-beta",
    "perturbed-pendulum",
    "sensor",
];

impl Suite {
    /// Name in the JSON.
    pub fn name(self) -> &'static str {
        match self {
            Suite::Tiny => "tiny",
            Suite::Default => "default",
            Suite::Full => "full",
            Suite::Exhaustive => "exhaustive",
        }
    }
    /// The problems it runs unless `--problem` says otherwise (`None`: all).
    pub fn problems(self) -> Option<&'static [&'static str]> {
        match self {
            Suite::Default => Some(&DEFAULT_PROBLEMS),
            Suite::Tiny | Suite::Full | Suite::Exhaustive => None,
        }
    }
    /// Multiplies every problem's horizon.
    pub fn scale(self) -> f64 {
        match self {
            Suite::Tiny => 0.02,
            Suite::Default => 0.2,
            Suite::Full | Suite::Exhaustive => 1.0,
        }
    }
    /// Target errors.
    pub fn targets(self) -> Vec<f64> {
        match self {
            Suite::Tiny => vec![1e-3, 1e-6],
            Suite::Default => vec![1e-4, 1e-8],
            Suite::Full => vec![1e-4, 1e-7, 1e-10],
            Suite::Exhaustive => (3..=12).map(|k| 10f64.powi(-k)).collect(),
        }
    }
    fn limits(self, smallest_target: f64) -> Limits {
        let (run_budget, per_octave) = match self {
            Suite::Tiny => (0.02, 2),
            Suite::Default => (0.25, 4),
            // Halved twice from (2.0, 8), which did not finish in 25 minutes.
            Suite::Full => (1.0, 4),
            Suite::Exhaustive => (20.0, 8),
        };
        Limits { smallest_target, run_budget, per_octave }
    }
    fn repeats(self) -> u32 {
        match self {
            Suite::Tiny | Suite::Default => 1,
            Suite::Full => 3,
            Suite::Exhaustive => 5,
        }
    }
    /// Long energy runs: this many horizons.
    fn long_factor(self) -> f64 {
        match self {
            Suite::Tiny => 2.0,
            Suite::Default => 10.0,
            Suite::Full => 100.0,
            Suite::Exhaustive => 1000.0,
        }
    }
    /// `(steps per run, runs)` of the step-cost measurements.
    fn step_cost_sizes(self) -> (usize, u32) {
        match self {
            Suite::Tiny => (2_000, 1),
            Suite::Default => (50_000, 3),
            Suite::Full => (200_000, 5),
            Suite::Exhaustive => (1_000_000, 7),
        }
    }
    /// Steps of the long runs of the stress section.
    fn many_steps(self) -> usize {
        match self {
            Suite::Tiny => 1_000,
            Suite::Default => 100_000,
            Suite::Full | Suite::Exhaustive => 10_000_000,
        }
    }
    /// Steps per orbit of the hard-orbit runs (tolerances for the adaptive ones).
    fn hard_settings(self) -> (Vec<usize>, Vec<f64>) {
        match self {
            Suite::Tiny => (vec![200], vec![1e-6]),
            Suite::Default => (vec![200, 2000], vec![1e-6, 1e-9]),
            Suite::Full | Suite::Exhaustive => (vec![200, 2000, 20000], vec![1e-6, 1e-9, 1e-12]),
        }
    }
    fn bad_input_timeout(self) -> Duration {
        Duration::from_secs(match self {
            Suite::Tiny => 2,
            Suite::Default => 5,
            Suite::Full | Suite::Exhaustive => 20,
        })
    }
}

/// What to run.
#[derive(Clone, Debug)]
pub struct Config {
    /// The suite.
    pub suite: Suite,
    /// Problem ids (`None`: the suite's, [`Suite::problems`]).
    pub problems: Option<Vec<String>>,
    /// Methods (`None`: all).
    pub methods: Option<Vec<Method>>,
    /// Relative agreement a reference must reach in its check.
    pub reference_tolerance: f64,
    /// Progress lines on stderr ([`Progress`]).
    pub progress: bool,
    /// Multiplies every problem's horizon (on top of the suite's scale).
    pub horizon_scale: f64,
    /// Target errors in place of the suite's.
    pub targets: Option<Vec<f64>>,
    /// Only the work–precision calibration: no long energy runs, stress
    /// section or step costs (for long horizons, `--scale`).
    pub calibration_only: bool,
    /// The command that runs this configuration, stated in the report.
    pub command: String,
}

/// The ids of every problem of the work–precision suite.
pub fn problem_ids() -> Vec<&'static str> {
    problem::all(1.0).iter().map(|p| p.id()).collect()
}

/// The 1-minute load average (Linux), so a report says how busy the machine was.
fn load_average() -> Option<f64> {
    std::fs::read_to_string("/proc/loadavg").ok()?.split_whitespace().next()?.parse().ok()
}

/// Progress on stderr, a line as each unit of work starts: seconds since the
/// start, the unit's number of all, the problem and method; plain lines, so
/// that a terminal, a log file and CI show the same.
pub struct Progress {
    on: bool,
    start: Instant,
    done: Cell<usize>,
    total: usize,
}

impl Progress {
    /// `total` units, silent unless `on`.
    pub fn new(on: bool, total: usize) -> Progress {
        Progress { on, start: Instant::now(), done: Cell::new(0), total }
    }
    /// Unit `what` starts.
    pub fn unit(&self, what: impl std::fmt::Display) {
        self.done.set(self.done.get() + 1);
        if self.on {
            let width = self.total.to_string().len();
            eprintln!(
                "[{:6.1} s] {:>width$}/{} {what}",
                self.start.elapsed().as_secs_f64(),
                self.done.get(),
                self.total
            );
        }
    }
    /// The end of the work.
    pub fn finish(&self) {
        if self.on {
            eprintln!("[{:6.1} s] done", self.start.elapsed().as_secs_f64());
        }
    }
}

/// Runs the suite. Fails on a reference that does not pass its check.
pub fn run(config: &Config) -> Result<Report, String> {
    let suite = config.suite;
    let load_start = load_average();
    let targets = config.targets.clone().unwrap_or_else(|| suite.targets());
    let scale = suite.scale() * config.horizon_scale;
    let smallest = targets.iter().copied().fold(f64::INFINITY, f64::min);
    let methods = config.methods.clone().unwrap_or_else(Method::all);
    let chosen = |id: &str| match (&config.problems, suite.problems()) {
        (Some(ids), _) => ids.iter().any(|i| i == id),
        (None, Some(ids)) => ids.contains(&id),
        (None, None) => true,
    };
    let problems: Vec<Box<dyn Problem>> = problem::all(scale).into_iter().filter(|p| chosen(p.id())).collect();
    let applicable = |p: &dyn Problem| methods.iter().copied().filter(|&m| p.applies(m)).collect::<Vec<Method>>();
    // Per problem: the reference, each method, the twins and energy runs; then the stress section.
    let stress_units = if config.calibration_only { 0 } else { problems.len() + HARD_ORBITS + 3 };
    // A unit more for the drift runs of a problem with constraints.
    let units = problems.iter().map(|p| applicable(&**p).len() + 2 + usize::from(p.constrained())).sum::<usize>()
        + stress_units;
    let progress = Progress::new(config.progress, units);
    let mut reports = Vec::new();
    for (i, p) in problems.iter().enumerate() {
        let applicable = applicable(&**p);
        let t_end = p.horizon();
        let at = format!("problem {}/{} {}", i + 1, problems.len(), p.id());
        progress.unit(format_args!("{at}: reference"));
        let reference = p.reference(t_end, config.reference_tolerance)?;
        let limits = suite.limits(smallest);
        let mut sweeps = Vec::new();
        let mut calibrated = Vec::new();
        for (j, &m) in applicable.iter().enumerate() {
            progress.unit(format_args!("{at}: method {}/{} {}", j + 1, applicable.len(), m.name()));
            let points = calibrate::sweep(&**p, m, &reference.q, t_end, limits, |_| {});
            for &target in &targets {
                calibrated.push(time_selected(&**p, m, &points, target, &reference.q, t_end, suite.repeats()));
            }
            sweeps.push(Sweep { method: m.name(), family: m.family(), order: m.order(), points });
        }
        progress.unit(format_args!(
            "{at}: generated against hand-written{}",
            if config.calibration_only { "" } else { ", long energy runs" }
        ));
        let twins = twins(&**p, &applicable, &calibrated, &targets, t_end, suite.repeats().max(5));
        let recommendations = targets.iter().map(|&t| recommend(&calibrated, t)).collect();
        let constraints = if p.constrained() {
            progress.unit(format_args!("{at}: constraint and energy drift at the calibrated settings"));
            drift(&**p, &calibrated, t_end)
        } else {
            Vec::new()
        };
        let energy = if config.calibration_only {
            Vec::new()
        } else {
            long_energy(&**p, &applicable, &calibrated, targets[0], t_end * suite.long_factor())
        };
        reports.push(ProblemReport {
            id: p.id().to_string(),
            title: p.title().to_string(),
            dim: p.dim(),
            horizon: t_end,
            reference,
            sweeps,
            calibrated,
            recommendations,
            energy,
            twins,
            constraints,
        });
    }
    let references: Vec<&[f64]> = reports.iter().map(|r| r.reference.q.as_slice()).collect();
    let (stress, step_costs) = if config.calibration_only {
        (Stress::default(), Vec::new())
    } else {
        let mut stress = stress(config, &methods, &problems, &references, &progress);
        progress.unit(format_args!("stress: {} steps at the calibrated step", suite.many_steps()));
        stress.long_runs = long_runs(config, &methods, &problems, &reports);
        progress.unit("step costs");
        let (steps, runs) = suite.step_cost_sizes();
        (stress, crate::step_cost::measure(steps, runs))
    };
    progress.finish();
    Ok(Report {
        schema_version: SCHEMA_VERSION,
        suite: suite.name().to_string(),
        command: config.command.clone(),
        crate_version: env!("CARGO_PKG_VERSION").to_string(),
        machine: Machine {
            cores: std::thread::available_parallelism().map_or(1, |n| n.get()),
            os: std::env::consts::OS.to_string(),
            arch: std::env::consts::ARCH.to_string(),
            load_start,
            load_end: load_average(),
        },
        targets,
        horizon_scale: config.horizon_scale,
        calibration_only: config.calibration_only,
        problems: reports,
        stress,
        step_costs,
    })
}

/// Each project composition against its hand-written twin, per target: both
/// at their calibrated settings, timed again in alternation (`repeats` runs
/// each, the minimum), so that a burst of load hits both alike.
fn twins(
    p: &dyn Problem,
    applicable: &[Method],
    calibrated: &[Calibrated],
    targets: &[f64],
    t_end: f64,
    repeats: u32,
) -> Vec<Twin> {
    let steps = |c: &Calibrated| match c.setting {
        Some(Setting::Steps(n)) => Some(n as u64),
        _ => None,
    };
    let mut out = Vec::new();
    for &g in applicable {
        let Some(h) = g.hand_written_twin().filter(|h| applicable.contains(h)) else { continue };
        for &target in targets {
            let find = |m: Method| calibrated.iter().find(|c| c.method == m.name() && c.target == target);
            let (Some(cg), Some(ch)) = (find(g), find(h)) else { continue };
            let (mut tg, mut th) = (cg.seconds, ch.seconds);
            if let (Some(sg), Some(sh)) = (cg.setting, ch.setting) {
                let (mut bg, mut bh) = (f64::INFINITY, f64::INFINITY);
                for _ in 0..repeats {
                    let rg = p.run(g, sg, t_end, 0);
                    let rh = p.run(h, sh, t_end, 0);
                    if rg.failure.is_some() || rh.failure.is_some() {
                        break;
                    }
                    bg = bg.min(rg.seconds);
                    bh = bh.min(rh.seconds);
                }
                if bg.is_finite() && bh.is_finite() {
                    (tg, th) = (Some(bg), Some(bh));
                }
            }
            let ratio = tg.zip(th).map(|(a, b)| a / b);
            let per_step =
                tg.zip(steps(cg)).zip(th.zip(steps(ch))).map(|((a, na), (b, nb))| (a / na as f64) / (b / nb as f64));
            out.push(Twin {
                generated: g.name(),
                hand_written: h.name(),
                target,
                generated_seconds: tg,
                hand_written_seconds: th,
                generated_steps: steps(cg),
                hand_written_steps: steps(ch),
                ratio,
                per_step_ratio: per_step,
            });
        }
    }
    out
}

fn time_selected(
    p: &dyn Problem,
    m: Method,
    points: &[calibrate::Point],
    target: f64,
    reference: &[f64],
    t_end: f64,
    repeats: u32,
) -> Calibrated {
    let mut c = Calibrated {
        method: m.name(),
        family: m.family(),
        target,
        setting: None,
        error: None,
        worst_of_three: None,
        seconds: None,
        repeats: 0,
        newton_per_step: None,
        evaluations: None,
    };
    let Some(k) = calibrate::select(points, target) else {
        return c;
    };
    let setting = points[k].setting;
    c.setting = Some(setting);
    c.worst_of_three = calibrate::worst_of_three(points, k);
    let mut best = f64::INFINITY;
    for _ in 0..repeats {
        let run = p.run(m, setting, t_end, 0);
        best = best.min(run.seconds);
        let pt = calibrate::point(setting, &run, reference);
        c.error = pt.error;
        c.newton_per_step = pt.newton_per_step;
        c.evaluations = pt.evaluations;
    }
    c.seconds = Some(best);
    c.repeats = repeats;
    c
}

fn recommend(calibrated: &[Calibrated], target: f64) -> Recommendation {
    let best = |family: Option<Family>| {
        calibrated
            .iter()
            .filter(|c| c.target == target && family.is_none_or(|f| c.family == f))
            .filter_map(|c| Some(Best { method: c.method.clone(), seconds: c.seconds?, setting: c.setting? }))
            .min_by(|a, b| a.seconds.total_cmp(&b.seconds))
    };
    Recommendation {
        target,
        best: best(None),
        best_project: best(Some(Family::Project)),
        best_peer: best(Some(Family::Peer)),
        best_hand_written: best(Some(Family::HandWritten)),
    }
}

/// Samples of the drift runs: the invariants at this many evenly spaced times.
const DRIFT_SAMPLES: usize = 1000;

/// Each calibrated run again, sampling the energy and the constraint errors
/// ([`crate::run::Run::constraints`]) at [`DRIFT_SAMPLES`] times.
fn drift(p: &dyn Problem, calibrated: &[Calibrated], t_end: f64) -> Vec<ConstraintDrift> {
    calibrated
        .iter()
        .filter_map(|c| {
            let setting = c.setting?;
            let run = p.run(Method::parse(&c.method)?, setting, t_end, DRIFT_SAMPLES);
            let component = |i: usize| run.constraints.iter().map(|s| (s.0, s.1[i])).collect::<Vec<_>>();
            Some(ConstraintDrift {
                method: c.method.clone(),
                target: c.target,
                setting,
                samples: DRIFT_SAMPLES,
                energy_max_abs: max_abs(&run.energy),
                position_max: max_abs(&component(0)),
                velocity_max: max_abs(&component(1)),
                failure: run.failure,
            })
        })
        .collect()
}

/// The methods of the long energy runs (those that apply and were calibrated).
const LONG_RUN: [Method; 11] = [
    Method::Midpoint,
    Method::TimeTransformed(6),
    Method::Galerkin(4),
    Method::EnergyMidpoint,
    Method::GeneratedKahanLi8,
    Method::Verlet,
    Method::KahanLi8,
    Method::OdeSolversDop853,
    Method::DiffEqDop853,
    Method::Dop853Angles,
    Method::Dop853Baumgarte,
];

fn long_energy(
    p: &dyn Problem,
    applicable: &[Method],
    calibrated: &[Calibrated],
    target: f64,
    t_long: f64,
) -> Vec<EnergySeries> {
    if !p.conservative() {
        return Vec::new();
    }
    let t_end = p.horizon();
    LONG_RUN
        .iter()
        .filter(|m| applicable.contains(m))
        .filter_map(|&m| {
            let c = calibrated.iter().find(|c| c.method == m.name() && c.target == target)?;
            // Keep h (or the tolerance) of the calibrated run: scale the step count with the horizon.
            let setting = match c.setting? {
                Setting::Steps(n) => Setting::Steps((n as f64 * t_long / t_end).round() as usize),
                s => s,
            };
            let run = p.run(m, setting, t_long, 400);
            Some(EnergySeries {
                method: m.name(),
                setting,
                t_end: t_long,
                failure: run.failure,
                max_abs: max_abs(&run.energy),
                samples: run.energy,
                momentum_max_abs: max_abs(&run.momentum),
                momentum_samples: run.momentum,
            })
        })
        .collect()
}

/// The methods of the ten-million-step runs: cheap steps, one of each kind.
const MANY_STEPS: [Method; 6] = [
    Method::Trapezoid,
    Method::Midpoint,
    Method::GeneratedKahanLi8,
    Method::Verlet,
    Method::KahanLi8,
    Method::OdeSolversDop853,
];

/// The problems of the ten-million-step runs.
const MANY_STEPS_PROBLEMS: [&str; 2] = ["pendulum", "kepler-0.5"];

/// Runs of [`Suite::many_steps`] steps with the settings calibrated at the
/// loosest target, on the cheap problems: whether anything accumulates
/// (round-off in the state, drift of energy or angular momentum) over 10⁷
/// steps. DOP853 keeps its tolerance and runs over the trapezoid rule's span.
fn long_runs(
    config: &Config,
    methods: &[Method],
    problems: &[Box<dyn Problem>],
    reports: &[ProblemReport],
) -> Vec<LongRun> {
    let steps = config.suite.many_steps();
    let mut out = Vec::new();
    for (p, r) in problems.iter().zip(reports).filter(|(p, _)| MANY_STEPS_PROBLEMS.contains(&p.id())) {
        let Some(&target) = r.calibrated.iter().map(|c| &c.target).next() else { continue };
        let calibrated = |m: Method| {
            r.calibrated.iter().find(|c| c.method == m.name() && c.target == target).and_then(|c| c.setting)
        };
        // The span of the trapezoid rule's run, for the adaptive peers.
        let span = match calibrated(Method::Trapezoid) {
            Some(Setting::Steps(n)) => steps as f64 * r.horizon / n as f64,
            _ => continue,
        };
        for &m in MANY_STEPS.iter().filter(|m| methods.contains(m) && p.applies(**m)) {
            let Some(setting) = calibrated(m) else { continue };
            let (setting, t_end) = match setting {
                Setting::Steps(n) => (Setting::Steps(steps), steps as f64 * r.horizon / n as f64),
                tol => (tol, span),
            };
            let start = crate::clock::Clock::start();
            let run = p.run(m, setting, t_end, 1000);
            out.push(LongRun {
                problem: p.id().to_string(),
                method: m.name(),
                setting,
                steps: run.steps,
                t_end,
                seconds: start.seconds(),
                energy_max_abs: max_abs(&run.energy),
                momentum_max_abs: max_abs(&run.momentum),
                outcome: run.failure.unwrap_or_else(|| "ok".to_string()),
            });
        }
    }
    out
}

/// `max |x|` over samples `(t, x)`; `None` without samples.
fn max_abs(samples: &[(f64, f64)]) -> Option<f64> {
    samples.iter().map(|s| s.1.abs()).fold(None, |m: Option<f64>, e| Some(m.map_or(e, |m| m.max(e))))
}

/// The fixed-step methods of the largest-step scan.
fn fixed_step(methods: &[Method]) -> Vec<Method> {
    methods.iter().copied().filter(|m| m.by_steps()).collect()
}

/// `references[i]` is `q(T)` of `problems[i]`.
/// The problems of the hard-orbit runs.
const HARD_ORBITS: usize = 2;

fn stress(
    config: &Config,
    methods: &[Method],
    problems: &[Box<dyn Problem>],
    references: &[&[f64]],
    progress: &Progress,
) -> Stress {
    let suite = config.suite;
    let mut out = Stress::default();
    // Largest step: scanning down from one period by 2^{1/2}, the first step
    // that integrates the (scaled) horizon with the energy within 10%.
    let conserved =
        "largest h = period·2^(-k/2) that runs to T without a failure and keeps |E − E0|/|E0| ≤ 0.1 at 50 samples";
    // The runs of the others record no energy: their final state is held to the reference instead.
    let not_conserved = "(energy not conserved) largest h = period·2^(-k/2) that runs to T without a failure and ends \
                         with max|q(T) − q_ref(T)| ≤ 0.1·max(1, max|q_ref(T)|)";
    let fixed = fixed_step(methods);
    for (p, reference) in problems.iter().zip(references) {
        progress.unit(format_args!("stress: largest step on {}", p.id()));
        let far = 0.1 * reference.iter().fold(1.0f64, |m, x| m.max(x.abs()));
        for &m in fixed.iter().filter(|&&m| p.applies(m)) {
            let t_end = p.horizon();
            let mut found = None;
            for k in 0..40 {
                let h = p.time_scale() * 2f64.powf(-(k as f64) / 2.0);
                let n = (t_end / h).ceil() as usize;
                let run = p.run(m, Setting::Steps(n), t_end, 50);
                let bounded = if p.conservative() {
                    run.energy.iter().all(|s| s.1.abs() <= 0.1)
                } else {
                    calibrate::error_of(&run.q, reference).is_some_and(|e| e <= far)
                };
                if run.failure.is_none() && bounded && !run.q.is_empty() {
                    found = Some(t_end / n as f64);
                    break;
                }
            }
            out.largest_step.push(LargestStep {
                problem: p.id().to_string(),
                method: m.name(),
                h: found,
                h_over_period: found.map(|h| h / p.time_scale()),
                criterion: if p.conservative() { conserved } else { not_conserved }.to_string(),
            });
        }
    }
    // Hard orbits.
    let (per_orbit, tolerances) = suite.hard_settings();
    let hard: [Box<dyn Problem>; HARD_ORBITS] = [
        problem::all(suite.scale()).into_iter().find(|p| p.id() == "kepler-0.9").expect("kepler-0.9 is a problem"),
        problem::kepler_099(suite.scale()),
    ];
    for p in &hard {
        progress.unit(format_args!("stress: hard orbit {}", p.id()));
        let t_end = p.horizon();
        let reference = p.reference(t_end, config.reference_tolerance);
        for &m in methods.iter().filter(|&&m| p.applies(m)) {
            let settings: Vec<Setting> = if let Some(sigma0) = m.sigma0() {
                [1.0, 0.25, 0.0625].iter().map(|&f| Setting::Sigma(f * sigma0)).collect()
            } else if m.adaptive() {
                tolerances.iter().map(|&t| Setting::Tolerance(t)).collect()
            } else {
                per_orbit
                    .iter()
                    .map(|&k| Setting::Steps((k as f64 * t_end / p.time_scale()).round() as usize))
                    .collect()
            };
            for setting in settings {
                let run = p.run(m, setting, t_end, 100);
                let error = reference.as_ref().ok().and_then(|r| calibrate::error_of(&run.q, &r.q));
                let energy_error =
                    (run.failure.is_none()).then(|| run.energy.iter().map(|s| s.1.abs()).fold(0.0, f64::max));
                out.hard_orbits.push(HardOrbit {
                    problem: p.id().to_string(),
                    method: m.name(),
                    setting,
                    error,
                    energy_error,
                    outcome: run.failure.unwrap_or_else(|| "ok".to_string()),
                });
            }
        }
    }
    progress.unit("stress: bad input");
    out.bad_input = bad_input(config, methods);
    out
}

/// The bad-input classes: `(class, problem, q0, v0, t_end)`; `None` keeps the problem's own.
type Case = (&'static str, &'static str, Option<Vec<f64>>, Option<Vec<f64>>, Option<f64>);

fn cases() -> Vec<Case> {
    vec![
        ("NaN initial position", "pendulum", Some(vec![f64::NAN]), None, None),
        ("infinite initial velocity", "pendulum", None, Some(vec![f64::INFINITY]), None),
        ("zero step (T = 0)", "pendulum", None, None, Some(0.0)),
        ("negative step (T < 0)", "pendulum", None, None, Some(-1.0)),
        ("NaN step (T = NaN)", "pendulum", None, None, Some(f64::NAN)),
        ("singular start: Kepler at r = 0", "kepler-0.5", Some(vec![0.0, 0.0]), None, None),
    ]
}

fn bad_input(config: &Config, methods: &[Method]) -> Vec<BadInput> {
    let cases = cases();
    // Panics are outcomes here, not noise on the terminal.
    let hook = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let mut out = Vec::new();
    for (class, id, q0, v0, t_end) in cases {
        let applies = |m: Method| problem::all(config.suite.scale()).iter().any(|p| p.id() == id && p.applies(m));
        for &m in methods.iter().filter(|&&m| applies(m)) {
            let (tx, rx) = mpsc::channel();
            let (q0, v0) = (q0.clone(), v0.clone());
            let scale = config.suite.scale();
            let setting = match m.sigma0() {
                Some(sigma0) => Setting::Sigma(sigma0),
                None if m.adaptive() => Setting::Tolerance(1e-8),
                None => Setting::Steps(100),
            };
            // A thread, so that a method that never returns is reported instead of hanging the report.
            std::thread::spawn(move || {
                let result = std::panic::catch_unwind(|| {
                    let p = problem::all(scale).into_iter().find(|p| p.id() == id).expect("a known problem");
                    if !p.applies(m) {
                        return None;
                    }
                    let t = t_end.unwrap_or(p.horizon());
                    let (dq, dv) = initial_of(&*p);
                    Some(p.run_from(q0.unwrap_or(dq), v0.unwrap_or(dv), m, setting, t))
                });
                let _ = tx.send(result);
            });
            let outcome = match rx.recv_timeout(config.suite.bad_input_timeout()) {
                Ok(Ok(None)) => continue,
                Ok(Ok(Some(run))) => match run.failure {
                    Some(f) => f,
                    None => {
                        format!("no error: q(T) = {:?}", run.q.iter().map(|x| format!("{x:.3e}")).collect::<Vec<_>>())
                    }
                },
                Ok(Err(panic)) => format!("panicked: {}", panic_message(&*panic)),
                Err(_) => format!("did not return within {} s", config.suite.bad_input_timeout().as_secs()),
            };
            out.push(BadInput { class: class.to_string(), method: m.name(), outcome });
        }
    }
    std::panic::set_hook(hook);
    out
}

fn initial_of(p: &dyn Problem) -> (Vec<f64>, Vec<f64>) {
    p.initial()
}

fn panic_message(panic: &(dyn std::any::Any + Send)) -> String {
    panic
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| panic.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "(no message)".to_string())
}
