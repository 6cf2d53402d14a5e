//! The report's data: one JSON file, `report.json`, with this schema
//! (`schema_version` 6; fields are never renamed or removed within a version,
//! and the deserialising structs below refuse unknown fields, so a file that
//! parses into [`Report`] matches the schema). Version 2 added `machine`'s
//! load averages, `problems[].twins` and `step_costs` (absent in a version 1
//! file, read as empty); version 3 the angular-momentum errors of the long
//! runs (`energy[].momentum_*`) and `stress.long_runs` (absent before: read as
//! empty); version 4 measures every `seconds` as CPU time of the thread that
//! ran the integrator (wall-clock before; no field changed); version 5 added
//! `command` (absent before: read as empty) and renamed the suites: the
//! default suite of version 4 is `full` from version 5 on, its `full` is
//! `exhaustive`, and `default` is the short suite that `quick` was; version
//! 6 added `problems[].constraints`, for problems with holonomic
//! constraints (absent for the others and before: read as empty).
//!
//! ```text
//! Report
//!   schema_version: 5
//!   suite: "tiny" | "default" | "full" | "exhaustive"
//!   command                              the command line that ran it
//!   crate_version, machine { cores, os, arch, load_start | null, load_end | null }
//!   horizon_scale, calibration_only       --scale (default 1), --calibration-only (default false)
//!                                        1-minute load averages when the suite started and ended
//!   targets: [f64]                       target errors, max_i |q_i(T) − q_i^ref(T)|
//!   problems: [ProblemReport]
//!     id, title, dim, horizon
//!     reference: { q, kind, check, agreement, accepted, seconds }
//!     sweeps: [{ method, family, order, points: [Point] }]
//!       Point { setting: {"steps": n} | {"tolerance": t} | {"sigma": σ}, error | null, seconds, steps,
//!               newton_per_step | null, evaluations | null, failure | null,
//!               auto?: { method, pilot_steps, pilot_seconds } (only `auto`) }
//!     calibrated: [{ method, family, target, setting | null, error | null,
//!                    worst_of_three | null, seconds | null, repeats, newton_per_step | null, evaluations | null }]
//!     recommendations: [{ target, best | null, best_project | null, best_peer | null, best_hand_written | null }]
//!       each best: { method, seconds, setting }
//!     energy: [{ method, setting, t_end, failure | null, max_abs: f64 | null, samples: [[t, (E − E0)/|E0|]],
//!                momentum_max_abs: f64 | null, momentum_samples: [[t, |L − L0|/|L0|]] }]
//!                                        L the angular momentum, for problems that conserve it
//!     twins: [{ generated, hand_written, target, generated_seconds | null, hand_written_seconds | null,
//!               generated_steps | null, hand_written_steps | null, ratio | null, per_step_ratio | null }]
//!                                        a project composition against the hand-written one of the same map
//!     constraints?: [{ method, target, setting, samples, energy_max_abs | null, position_max | null,
//!                      velocity_max | null, failure | null }]
//!                                        problems with constraints only: a run at each calibrated setting,
//!                                        max over its samples of |E − E0|/|E0|, of the rods' length errors
//!                                        over their lengths and of the rates of change of their lengths
//!   step_costs: [{ system, method, h, steps, repeats, ns_per_step, newton_per_step | null }]
//!                                        ns per step at a fixed h, best of `repeats` runs of `steps` steps
//!   stress
//!     largest_step: [{ problem, method, h | null, h_over_period | null, criterion }]
//!     hard_orbits: [{ problem, method, setting, error | null, energy_error | null, outcome }]
//!     bad_input: [{ class, method, outcome }]
//!     long_runs: [{ problem, method, setting, steps, t_end, seconds, energy_max_abs | null,
//!                   momentum_max_abs | null, outcome }]
//!                                        10⁷ steps (10⁵ in the default suite) at the calibrated step
//! ```
//!
//! `seconds` are CPU times of the thread that ran the integrator ([`crate::clock`]); `calibrated.seconds` is the
//! minimum over `repeats` runs of the selected setting, the sweeps' times are
//! single runs.

use serde::{Deserialize, Serialize};

use crate::calibrate::Point;
use crate::methods::{Family, Setting};
use crate::problem::Reference;

/// The version of the schema described in the module docs.
pub const SCHEMA_VERSION: u32 = 6;

/// The whole report.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Report {
    /// [`SCHEMA_VERSION`].
    pub schema_version: u32,
    /// Which suite produced it.
    pub suite: String,
    /// The command that ran it (`cargo run --release -p lagrangian-bench -- …`).
    #[serde(default)]
    pub command: String,
    /// Version of `lagrangian-bench`.
    pub crate_version: String,
    /// Where it ran.
    pub machine: Machine,
    /// Target errors.
    pub targets: Vec<f64>,
    /// Multiplies every problem's horizon beyond the suite's own (`--scale`;
    /// 1 unless asked).
    #[serde(default = "one")]
    pub horizon_scale: f64,
    /// Only the work–precision calibration ran (`--calibration-only`): no long
    /// energy runs, stress section or step costs.
    #[serde(default)]
    pub calibration_only: bool,
    /// One entry per problem.
    pub problems: Vec<ProblemReport>,
    /// The stress section.
    pub stress: Stress,
    /// Cost of one step at a fixed step size, generated against hand-written.
    #[serde(default)]
    pub step_costs: Vec<StepCost>,
}

fn one() -> f64 {
    1.0
}

/// ns per step of one method on one system.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct StepCost {
    /// `"pendulum"` or `"double pendulum"`.
    pub system: String,
    /// `"generated midpoint"`, `"hand-written midpoint"`, ….
    pub method: String,
    /// Step size.
    pub h: f64,
    /// Steps per timed run.
    pub steps: u64,
    /// Timed runs.
    pub repeats: u32,
    /// CPU ns per step, best of the runs.
    pub ns_per_step: f64,
    /// Newton iterations per step (generated methods).
    pub newton_per_step: Option<f64>,
}

/// A project composition against the hand-written composition that computes
/// the same map (on a separable constant-mass problem), both calibrated to
/// the same target.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Twin {
    /// Project method name.
    pub generated: String,
    /// Hand-written method name.
    pub hand_written: String,
    /// Target error.
    pub target: f64,
    /// Time of one run of the project method at its calibrated setting
    /// (minimum of runs alternating with the hand-written one's).
    pub generated_seconds: Option<f64>,
    /// The same for the hand-written one.
    pub hand_written_seconds: Option<f64>,
    /// Steps of the project method's calibrated setting.
    pub generated_steps: Option<u64>,
    /// Steps of the hand-written one's.
    pub hand_written_steps: Option<u64>,
    /// `generated_seconds / hand_written_seconds`: the cost ratio at equal error.
    pub ratio: Option<f64>,
    /// The same per step (time / steps of each).
    pub per_step_ratio: Option<f64>,
}

/// The machine.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Machine {
    /// Available parallelism.
    pub cores: usize,
    /// `std::env::consts::OS`.
    pub os: String,
    /// `std::env::consts::ARCH`.
    pub arch: String,
    /// 1-minute load average when the suite started (`/proc/loadavg`; `None` elsewhere).
    #[serde(default)]
    pub load_start: Option<f64>,
    /// The same when it ended.
    #[serde(default)]
    pub load_end: Option<f64>,
}

/// One problem.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ProblemReport {
    /// Short name.
    pub id: String,
    /// Title.
    pub title: String,
    /// Degrees of freedom.
    pub dim: usize,
    /// Final time `T` of the work–precision runs.
    pub horizon: f64,
    /// The reference `q(T)` and its check.
    pub reference: Reference,
    /// Every run of every sweep.
    pub sweeps: Vec<Sweep>,
    /// The selected setting per method and target.
    pub calibrated: Vec<Calibrated>,
    /// The fastest methods per target.
    pub recommendations: Vec<Recommendation>,
    /// Energy error over a long run.
    pub energy: Vec<EnergySeries>,
    /// Project compositions against their hand-written twins.
    #[serde(default)]
    pub twins: Vec<Twin>,
    /// The drift of the constraints and the energy at each calibrated
    /// setting, for problems with constraints (empty, and left out of the
    /// JSON, for the others).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub constraints: Vec<ConstraintDrift>,
}

/// How well one calibrated run holds the constraints and the energy.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ConstraintDrift {
    /// Method name.
    pub method: String,
    /// The target its setting was calibrated to.
    pub target: f64,
    /// The calibrated setting.
    pub setting: Setting,
    /// Evenly spaced sampling times over the run (accepted steps of adaptive
    /// methods: the first at or after each).
    pub samples: usize,
    /// `max |E − E0|/|E0|` over the samples.
    pub energy_max_abs: Option<f64>,
    /// The largest position error of the constraints over the samples (the
    /// double pendulum's: `max_i |‖r_i − r_{i−1}‖ − l_i| / l_i`).
    pub position_max: Option<f64>,
    /// The largest velocity error over the samples (the rates of change of
    /// the rods' lengths, `G v` of the constraints written as lengths).
    pub velocity_max: Option<f64>,
    /// The failure, if the run stopped.
    pub failure: Option<String>,
}

/// The sweep of one method.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Sweep {
    /// Method name.
    pub method: String,
    /// Who wrote it.
    pub family: Family,
    /// Classical order.
    pub order: u32,
    /// Coarse to fine.
    pub points: Vec<Point>,
}

/// A method calibrated to a target.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Calibrated {
    /// Method name.
    pub method: String,
    /// Who wrote it.
    pub family: Family,
    /// Target error.
    pub target: f64,
    /// The selected setting; `None` when the sweep never met the target.
    pub setting: Option<Setting>,
    /// The error of the selected setting.
    pub error: Option<f64>,
    /// The worst error of it and the next two finer settings.
    pub worst_of_three: Option<f64>,
    /// Minimum seconds over `repeats` runs.
    pub seconds: Option<f64>,
    /// Runs timed.
    pub repeats: u32,
    /// Newton iterations per step.
    pub newton_per_step: Option<f64>,
    /// Evaluations.
    pub evaluations: Option<u64>,
}

/// The fastest method meeting a target.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Best {
    /// Method name.
    pub method: String,
    /// Its time.
    pub seconds: f64,
    /// Its setting.
    pub setting: Setting,
}

/// Recommendations at one target.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Recommendation {
    /// Target error.
    pub target: f64,
    /// Fastest of all.
    pub best: Option<Best>,
    /// Fastest project method.
    pub best_project: Option<Best>,
    /// Fastest peer crate.
    pub best_peer: Option<Best>,
    /// Fastest hand-written composition.
    pub best_hand_written: Option<Best>,
}

/// Energy error samples of one long run.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct EnergySeries {
    /// Method name.
    pub method: String,
    /// Its setting (calibrated at the loosest target).
    pub setting: Setting,
    /// Final time of the long run.
    pub t_end: f64,
    /// The failure, if the run stopped.
    pub failure: Option<String>,
    /// `max |E − E0|/|E0|` over the samples.
    pub max_abs: Option<f64>,
    /// `(t, (E − E0)/|E0|)`.
    pub samples: Vec<(f64, f64)>,
    /// `max |L − L0|/|L0|` of the angular momentum `L`, for problems that conserve it.
    #[serde(default)]
    pub momentum_max_abs: Option<f64>,
    /// `(t, |L − L0|/|L0|)` at the times of `samples`.
    #[serde(default)]
    pub momentum_samples: Vec<(f64, f64)>,
}

/// The stress section.
#[derive(Clone, Debug, Default, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Stress {
    /// Largest step each fixed-step method survives.
    pub largest_step: Vec<LargestStep>,
    /// Kepler e = 0.9 and 0.99.
    pub hard_orbits: Vec<HardOrbit>,
    /// What each method does with bad input.
    pub bad_input: Vec<BadInput>,
    /// Runs of ten million steps.
    #[serde(default)]
    pub long_runs: Vec<LongRun>,
}

/// A run of many steps (10⁷ in the full suite) at a calibrated step size.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct LongRun {
    /// Problem id.
    pub problem: String,
    /// Method name.
    pub method: String,
    /// Steps or tolerance (calibrated at the loosest target).
    pub setting: Setting,
    /// Steps taken (accepted steps of an adaptive method).
    pub steps: u64,
    /// Final time.
    pub t_end: f64,
    /// CPU seconds of the run's thread (including 1000 samples of the invariants).
    pub seconds: f64,
    /// `max |E − E0|/|E0|` over the samples.
    pub energy_max_abs: Option<f64>,
    /// `max |L − L0|/|L0|` over the samples, when `L` is conserved.
    pub momentum_max_abs: Option<f64>,
    /// `"ok"`, or the failure.
    pub outcome: String,
}

/// Largest surviving step.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct LargestStep {
    /// Problem id.
    pub problem: String,
    /// Method name.
    pub method: String,
    /// The largest step on the grid that survived, scanning down.
    pub h: Option<f64>,
    /// `h` over the problem's period.
    pub h_over_period: Option<f64>,
    /// What "survived" means.
    pub criterion: String,
}

/// One run on a hard orbit.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct HardOrbit {
    /// Problem id.
    pub problem: String,
    /// Method name.
    pub method: String,
    /// Steps or tolerance.
    pub setting: Setting,
    /// Final position error.
    pub error: Option<f64>,
    /// `max |E − E0|/|E0|` over the run.
    pub energy_error: Option<f64>,
    /// `"ok"`, or the failure.
    pub outcome: String,
}

/// One bad-input case.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct BadInput {
    /// The class of bad input.
    pub class: String,
    /// Method name.
    pub method: String,
    /// The error it returned, `"panicked: …"`, `"no error: …"`, or `"did not return within …"`.
    pub outcome: String,
}
