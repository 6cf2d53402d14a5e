//! How each method of the report is run on a [`Model`].

use lagrangian::galerkin::StageIteration;
use lagrangian::prelude::*;
use lagrangian::{Composition as Generated, GalerkinIntegrator, StepBounds};

use crate::compositions::{Composition, Stepper};
use crate::invariants::Sampler;
use crate::methods::{Method, Setting};
use crate::problems::{Model, Transformed};
use crate::run::{AUTO_NODES, AutoReport, Run};

/// Runs `method` with `setting` from `(q0, v0)` at `t = 0` to `t_end`; with
/// `samples > 0` and a conservative model, records the relative energy error
/// at about that many evenly spaced times (the timing then includes the sampling).
pub fn run<M: Model<N>, const N: usize, const D: usize>(
    model: &M,
    (q0, v0): ([f64; N], [f64; N]),
    method: Method,
    setting: Setting,
    t_end: f64,
    samples: usize,
) -> Run {
    assert_eq!(D, 2 * N, "the first-order state has 2N components");
    // The auto run keeps its nodes when asked, for its error along the run.
    let keep_nodes = samples > 0;
    // The energy of a time-dependent or forced problem changes by physics: nothing to record.
    let samples = if M::CONSERVATIVE { samples } else { 0 };
    let mut sampler = Sampler::new(model, &q0, &v0, t_end, samples);
    let mut record = |t: f64, q: &[f64; N], v: &[f64; N]| sampler.record(t, q, v);
    let start = crate::clock::Clock::start();
    let mut out = match (method, setting) {
        (Method::OdeSolversDop853 | Method::DiffEqDop853 | Method::DiffEqGauss6, Setting::Tolerance(tol)) => {
            crate::peers::run::<M, N, D>(model, (q0, v0), method, tol, t_end, samples)
        }
        (Method::Verlet | Method::Yoshida6 | Method::KahanLi8, Setting::Steps(n)) => {
            let Some(minv) = model.inverse_mass() else {
                return Run::failed("not applicable: the Hamiltonian is not separable".into(), 0.0);
            };
            let c = match method {
                Method::Verlet => Composition::Verlet,
                Method::Yoshida6 => Composition::Yoshida6,
                _ => Composition::KahanLi8,
            };
            let force = |q: &[f64; N]| model.force(q);
            let mut s = Stepper::new(c, minv, &force, t_end / n as f64, q0, v0);
            for k in 0..n {
                s.step(&force);
                if samples > 0 {
                    record((k + 1) as f64 * t_end / n as f64, &s.q, &s.velocity());
                }
            }
            let finite = s.q.iter().all(|x| x.is_finite());
            Run {
                q: if finite { s.q.to_vec() } else { Vec::new() },
                failure: (!finite).then(|| "non-finite state".to_string()),
                steps: n as u64,
                evaluations: Some(s.evaluations),
                ..Run::default()
            }
        }
        (Method::Galerkin(s) | Method::GalerkinFixedPoint(s), Setting::Steps(n)) => {
            let iteration = match method {
                Method::GalerkinFixedPoint(_) => StageIteration::Automatic,
                _ => StageIteration::Newton,
            };
            macro_rules! degree {
                ($($s:literal)*) => {
                    match s {
                        $($s => galerkin::<M, N, $s>(model, (q0, v0), iteration, n, t_end, samples, &mut record),)*
                        _ => Run::failed(format!("no Galerkin degree {s} in the report (2 to 8)"), 0.0),
                    }
                };
            }
            degree!(2 3 4 5 6 7 8)
        }
        (Method::Midpoint, Setting::Steps(n)) => {
            variational(model, (q0, v0), Midpoint, n, t_end, false, samples, &mut record)
        }
        (Method::Trapezoid, Setting::Steps(n)) => {
            variational(model, (q0, v0), Trapezoid, n, t_end, false, samples, &mut record)
        }
        (Method::AlphaBeta, Setting::Steps(n)) => {
            variational(model, (q0, v0), AlphaBeta::EULER_A, n, t_end, false, samples, &mut record)
        }
        (Method::EnergyMidpoint, Setting::Steps(n)) => {
            variational(model, (q0, v0), Midpoint, n, t_end, true, samples, &mut record)
        }
        // Explicit Störmer–Verlet sub-steps where the macro proves a constant mass
        // matrix, Newton sub-steps otherwise (time-dependent, forced, non-separable).
        (Method::GeneratedYoshida4, Setting::Steps(n)) => {
            variational(model, (q0, v0), Generated::YOSHIDA4, n, t_end, false, samples, &mut record)
        }
        (Method::GeneratedYoshida6, Setting::Steps(n)) => {
            variational(model, (q0, v0), Generated::YOSHIDA6, n, t_end, false, samples, &mut record)
        }
        (Method::GeneratedKahanLi8, Setting::Steps(n)) => {
            variational(model, (q0, v0), Generated::KAHAN_LI8, n, t_end, false, samples, &mut record)
        }
        (Method::TimeTransformed(s), Setting::Sigma(sigma)) => model
            .time_transformed(Transformed::Galerkin(s), sigma, t_end, &mut record)
            .unwrap_or_else(|| Run::failed("not applicable: no step density for this problem".into(), 0.0)),
        (Method::TimeTransformedAuto(s), Setting::Sigma(sigma)) => model
            .time_transformed(Transformed::GalerkinAuto(s), sigma, t_end, &mut record)
            .unwrap_or_else(|| Run::failed("not applicable: no step density for this problem".into(), 0.0)),
        (Method::TimeTransformedSplit, Setting::Sigma(sigma)) => model
            .time_transformed(Transformed::Splitting, sigma, t_end, &mut record)
            .unwrap_or_else(|| Run::failed("not applicable: no step density for this problem".into(), 0.0)),
        (Method::Auto, Setting::Tolerance(tol)) => auto(model, (q0, v0), tol, t_end, keep_nodes, &mut record),
        (m, s) => Run::failed(format!("{} cannot be run with {s:?}", m.name()), 0.0),
    };
    out.seconds = start.seconds();
    sampler.finish(&mut out);
    out
}

#[allow(clippy::too_many_arguments)]
fn variational<M: Model<N>, L: F64Readouts, const N: usize>(
    model: &M,
    (q0, v0): ([f64; N], [f64; N]),
    method: L,
    n: usize,
    t_end: f64,
    energy_preserving: bool,
    samples: usize,
    record: &mut impl FnMut(f64, &[f64; N], &[f64; N]),
) -> Run {
    let h = t_end / n as f64;
    let builder = Integrator::new(model.system(), method, h);
    let started = if energy_preserving {
        builder.energy_preserving(StepBounds::around(h)).start(0.0, q0, v0)
    } else {
        builder.start(0.0, q0, v0)
    };
    let mut sim = match started {
        Ok(sim) => sim,
        Err(e) => return Run::failed(e.to_string(), 0.0),
    };
    let observe = |sim: &Integrator<M::Sys, L, N>| {
        if samples > 0 {
            let s = sim.state();
            if let Ok(v) = sim.velocity() {
                record(s.t, &s.q, &v);
            }
        }
    };
    let result = if energy_preserving { sim.run_until(t_end, observe) } else { sim.run(n, observe) };
    let stats = sim.stats();
    let per_step = (stats.steps > 0).then(|| stats.newton_iterations as f64 / stats.steps as f64);
    match result {
        Ok(()) => Run { q: sim.state().q.to_vec(), steps: stats.steps, newton_per_step: per_step, ..Run::default() },
        Err(e) => Run { failure: Some(e.to_string()), steps: stats.steps, newton_per_step: per_step, ..Run::default() },
    }
}

fn galerkin<M: Model<N>, const N: usize, const S: usize>(
    model: &M,
    (q0, v0): ([f64; N], [f64; N]),
    iteration: StageIteration,
    n: usize,
    t_end: f64,
    samples: usize,
    record: &mut impl FnMut(f64, &[f64; N], &[f64; N]),
) -> Run {
    let method = Galerkin::<S, S>::gauss().with_iteration(iteration);
    let mut sim = match GalerkinIntegrator::new(model.system(), method, t_end / n as f64).start(0.0, q0, v0) {
        Ok(sim) => sim,
        Err(e) => return Run::failed(e.to_string(), 0.0),
    };
    let result = sim.run(n, |sim| {
        if samples > 0 {
            let s = sim.state();
            if let Ok(v) = sim.velocity() {
                record(s.t, &s.q, &v);
            }
        }
    });
    let stats = sim.stats();
    let per_step = (stats.steps > 0).then(|| stats.newton_iterations as f64 / stats.steps as f64);
    // Derivative evaluations of L at quadrature points: gradients, with the
    // whole Hessian (Newton) or the Hessian in v only (fixed-point steps).
    let points = sim.point_evaluations();
    let evaluations = Some(points.gradients + points.hessians + points.velocity_hessians);
    let steps = stats.steps;
    match result {
        Ok(()) => Run { q: sim.state().q.to_vec(), steps, newton_per_step: per_step, evaluations, ..Run::default() },
        Err(e) => Run { failure: Some(e.to_string()), steps, newton_per_step: per_step, evaluations, ..Run::default() },
    }
}

/// The tolerance-driven solve with `rtol = tol`, pilot included; with
/// `keep_nodes` every node is kept and recorded (`record` thins them), and
/// [`AUTO_NODES`] of them are reported.
fn auto<M: Model<N>, const N: usize>(
    model: &M,
    (q0, v0): ([f64; N], [f64; N]),
    tol: f64,
    t_end: f64,
    keep_nodes: bool,
    record: &mut impl FnMut(f64, &[f64; N], &[f64; N]),
) -> Run {
    // Only the last node unless the energy or the nodes are sampled.
    let plan = if keep_nodes { Plan::until(t_end) } else { Plan::until(t_end).every(usize::MAX).without_velocities() };
    match Auto::new(model.system(), 0.0, q0, v0).tolerance(Tolerance::relative(tol)).solve(plan) {
        Ok(solved) => {
            let sol = &solved.solution;
            if keep_nodes {
                for ((t, q), v) in sol.t.iter().zip(&sol.q).zip(&sol.v) {
                    if let (Ok(q), Ok(v)) = (q.try_into(), v.try_into()) {
                        record(*t, q, v);
                    }
                }
            }
            let est = &solved.estimate;
            let steps = sol.stats.steps + est.pilot.steps;
            let auto = Some(AutoReport {
                estimate: est.error,
                requested: est.requested,
                method: est.method_name.clone(),
                pilot_steps: est.pilot.steps,
                pilot_seconds: est.pilot.seconds,
                step: est.step,
                growth: format!("{:?}", est.growth),
                reason: est.reason.clone(),
                nodes: if keep_nodes && !sol.t.is_empty() {
                    let n = sol.t.len() - 1;
                    (1..=AUTO_NODES).map(|k| n * k / AUTO_NODES).map(|i| (sol.t[i], sol.q[i].to_vec())).collect()
                } else {
                    Vec::new()
                },
            });
            match (sol.error.as_ref(), sol.q.last()) {
                (None, Some(q)) => Run { q: q.to_vec(), steps, auto, ..Run::default() },
                (Some(e), _) => Run { failure: Some(e.to_string()), steps, auto, ..Run::default() },
                (None, None) => Run { failure: Some("no node kept".into()), steps, auto, ..Run::default() },
            }
        }
        Err(e) => Run::failed(e.to_string(), 0.0),
    }
}
