//! Calibration: sweep a method's step count (or tolerance) from coarse to
//! fine, then pick, for each target error, the coarsest setting for which it
//! *and the next two finer ones* meet the target — the error of a fixed-step
//! method is not monotone in `h`, so one lucky setting is not enough.

use serde::{Deserialize, Serialize};

use crate::methods::{Method, Setting};
use crate::problem::Problem;
use crate::run::Run;

/// One run of a sweep.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Point {
    /// Step count or tolerance.
    pub setting: Setting,
    /// `max_i |q_i(T) − q_i^ref(T)|`; `None` when the run failed.
    pub error: Option<f64>,
    /// CPU seconds of the run (one run).
    pub seconds: f64,
    /// Steps taken.
    pub steps: u64,
    /// Newton iterations per step (project methods).
    pub newton_per_step: Option<f64>,
    /// Force or right-hand-side evaluations (peers, compositions).
    pub evaluations: Option<u64>,
    /// The method's error message when the run failed.
    pub failure: Option<String>,
    /// What the tolerance-driven solve chose (`auto` only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub auto: Option<AutoChoice>,
}

/// The method a tolerance-driven solve ran and its pilot's share.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct AutoChoice {
    /// The method it ran.
    pub method: String,
    /// Steps of the survey and pilot (the rest are the final run's).
    pub pilot_steps: u64,
    /// Seconds of the choice and pilot (wall clock).
    pub pilot_seconds: f64,
}

/// How far a sweep may go.
#[derive(Clone, Copy, Debug)]
pub struct Limits {
    /// Stop once the last three points meet this error.
    pub smallest_target: f64,
    /// Stop after a single run takes longer than this (seconds).
    pub run_budget: f64,
    /// Settings per factor 2 in step count (per decade in tolerance: the same number).
    pub per_octave: u32,
}

/// `max_i |a_i − b_i|`, or `None` when `a` is empty (a failed run).
pub fn error_of(q: &[f64], reference: &[f64]) -> Option<f64> {
    if q.len() != reference.len() || q.is_empty() {
        return None;
    }
    let e = q.iter().zip(reference).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
    e.is_finite().then_some(e)
}

/// A point from a run.
pub fn point(setting: Setting, run: &Run, reference: &[f64]) -> Point {
    Point {
        setting,
        error: if run.failure.is_none() { error_of(&run.q, reference) } else { None },
        seconds: run.seconds,
        steps: run.steps,
        newton_per_step: run.newton_per_step,
        evaluations: run.evaluations,
        failure: run.failure.clone(),
        auto: run.auto.as_ref().map(|a| AutoChoice {
            method: a.method.clone(),
            pilot_steps: a.pilot_steps,
            pilot_seconds: a.pilot_seconds,
        }),
    }
}

/// The settings of a sweep, coarse to fine.
pub fn settings(problem: &dyn Problem, method: Method, per_octave: u32) -> impl Iterator<Item = Setting> {
    let adaptive = method.adaptive();
    let sigma0 = method.sigma0();
    let n0 = problem.coarsest_steps().max(1) as f64;
    let mut last = 0;
    (0..400u32).filter_map(move |k| {
        if let Some(sigma0) = sigma0 {
            // From `σ0` down, `per_octave` settings per factor 2.
            Some(Setting::Sigma(sigma0 * 2f64.powf(-(k as f64) / per_octave as f64)))
        } else if adaptive {
            // From 1e-3 down to 1e-15, `per_octave` tolerances per decade.
            let tol = 1e-3 * 10f64.powf(-(k as f64) / per_octave as f64);
            (tol >= 1e-15).then_some(Setting::Tolerance(tol))
        } else {
            let n = (n0 * 2f64.powf(k as f64 / per_octave as f64)).round() as usize;
            // Small counts repeat after rounding: skip them.
            (n > last).then(|| {
                last = n;
                Setting::Steps(n)
            })
        }
    })
}

/// Octaves of settings that all fail after which a sweep gives up.
pub const FAILED_OCTAVES: usize = 3;

/// Sweeps `method` on `problem` to `t_end`, calling `progress` after each run.
pub fn sweep(
    problem: &dyn Problem,
    method: Method,
    reference: &[f64],
    t_end: f64,
    limits: Limits,
    mut progress: impl FnMut(&Point),
) -> Vec<Point> {
    let mut points: Vec<Point> = Vec::new();
    for setting in settings(problem, method, limits.per_octave) {
        let run = problem.run(method, setting, t_end, 0);
        let p = point(setting, &run, reference);
        progress(&p);
        let slow = p.seconds > limits.run_budget;
        points.push(p);
        let done = points.len() >= 3
            && points[points.len() - 3..].iter().all(|p| p.error.is_some_and(|e| e <= limits.smallest_target));
        // A method that fails over three octaves of settings in a row (energy-preserving
        // steps losing the energy root at the same point of the orbit at every step size)
        // will not start to succeed: without this the sweep would go on to absurd step
        // counts, each failing run quick enough to stay under the budget.
        let failing = points.len() >= FAILED_OCTAVES * limits.per_octave as usize
            && points[points.len() - FAILED_OCTAVES * limits.per_octave as usize..].iter().all(|p| p.failure.is_some());
        if done || slow || failing {
            break;
        }
    }
    points
}

/// The index of the coarsest point that, with the next two, meets `target`.
pub fn select(points: &[Point], target: f64) -> Option<usize> {
    (0..points.len().saturating_sub(2)).find(|&k| points[k..k + 3].iter().all(|p| p.error.is_some_and(|e| e <= target)))
}

/// The worst error of the selected point and the next two.
pub fn worst_of_three(points: &[Point], k: usize) -> Option<f64> {
    points[k..k + 3].iter().map(|p| p.error).try_fold(0.0f64, |m, e| e.map(|e| m.max(e)))
}
