//! The methods of the report and how each one is run on a [`Model`].

use lagrangian::prelude::*;
use lagrangian::{Composition as Generated, GalerkinIntegrator, StepBounds};
use serde::{Deserialize, Serialize};

use crate::compositions::{Composition, Stepper};
use crate::problems::{Model, Transformed};

/// Every method of the report.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub enum Method {
    /// Project: midpoint discrete Lagrangian, fixed steps (order 2).
    Midpoint,
    /// Project: trapezoid discrete Lagrangian, fixed steps (order 2).
    Trapezoid,
    /// Project: α-β discrete Lagrangian with α = 1 (symplectic Euler, order 1).
    AlphaBeta,
    /// Project: Galerkin of degree `s` with `s` Gauss points (order `2s`).
    Galerkin(u8),
    /// Project: midpoint with energy-preserving variable steps (`StepBounds::around(h0)`).
    EnergyMidpoint,
    /// Project: Yoshida's order 4 composition of trapezoid steps (`Composition::YOSHIDA4`).
    GeneratedYoshida4,
    /// Project: Yoshida's order 6 composition of trapezoid steps (`Composition::YOSHIDA6`).
    GeneratedYoshida6,
    /// Project: Kahan–Li's order 8 composition of trapezoid steps (`Composition::KAHAN_LI8`).
    GeneratedKahanLi8,
    /// Peer: ode_solvers 0.6 DOP853 (rtol = atol = tol, sparse output).
    OdeSolversDop853,
    /// Peer: differential-equations 0.5 DOP853 (rtol = atol = tol).
    DiffEqDop853,
    /// Peer: differential-equations 0.5 adaptive Gauss–Legendre IRK, 3 stages, order 6 (finite-difference Jacobian).
    DiffEqGauss6,
    /// Hand-written: Störmer–Verlet.
    Verlet,
    /// Hand-written: Yoshida's order 6 composition.
    Yoshida6,
    /// Hand-written: Kahan–Li order 8 composition.
    KahanLi8,
    /// Project: time-transformed (Sundman–Poincaré) Galerkin of degree `s`,
    /// uniform steps `σ` in the new time, with the problem's own step density
    /// (Kepler: `r^{3/2}`); only problems that define one.
    TimeTransformed(u8),
    /// Project: as [`Method::TimeTransformed`] with the automatic monitor
    /// (`Curvature`, floor 1e-3), on the same problems.
    TimeTransformedAuto(u8),
    /// Project: the explicit time-transformed splitting (logarithmic
    /// Hamiltonian, Kahan–Li 8 of the drift–kick–drift leapfrog, uniform
    /// steps `σ` in the new time), on the problems with a step density.
    TimeTransformedSplit,
    /// Project: the tolerance-driven solve (`lagrangian::Auto`): it chooses
    /// the method, its order and its step from `rtol = tol`; the time
    /// includes its survey and pilot.
    Auto,
}

/// Who wrote a method.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Family {
    /// This project.
    Project,
    /// Another crate.
    Peer,
    /// Hand-written in this crate.
    HandWritten,
}

/// What a method is calibrated by.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Setting {
    /// A number of fixed steps over the horizon (initial step `T/n` for variable steps).
    Steps(usize),
    /// `rtol = atol`.
    Tolerance(f64),
    /// The uniform step `σ` in the transformed time of a time-transformed method.
    Sigma(f64),
}

impl Method {
    /// All methods, in report order.
    pub fn all() -> Vec<Method> {
        let mut m = vec![Method::Midpoint, Method::Trapezoid, Method::AlphaBeta];
        m.extend((2..=8).map(Method::Galerkin));
        m.extend([
            Method::EnergyMidpoint,
            Method::GeneratedYoshida4,
            Method::GeneratedYoshida6,
            Method::GeneratedKahanLi8,
            Method::OdeSolversDop853,
            Method::DiffEqDop853,
            Method::DiffEqGauss6,
            Method::Verlet,
            Method::Yoshida6,
            Method::KahanLi8,
            Method::TimeTransformed(4),
            Method::TimeTransformed(6),
            Method::TimeTransformedAuto(6),
            Method::TimeTransformedSplit,
            Method::Auto,
        ]);
        m
    }

    /// The name used on the command line, in the JSON and in tables.
    pub fn name(self) -> String {
        match self {
            Method::Midpoint => "midpoint".into(),
            Method::Trapezoid => "trapezoid".into(),
            Method::AlphaBeta => "alpha-beta".into(),
            Method::Galerkin(s) => format!("galerkin-{s}"),
            Method::EnergyMidpoint => "energy-midpoint".into(),
            Method::GeneratedYoshida4 => "composition-yoshida4".into(),
            Method::GeneratedYoshida6 => "composition-yoshida6".into(),
            Method::GeneratedKahanLi8 => "composition-kahan-li8".into(),
            Method::OdeSolversDop853 => "ode_solvers-dop853".into(),
            Method::DiffEqDop853 => "diffeq-dop853".into(),
            Method::DiffEqGauss6 => "diffeq-gauss6".into(),
            Method::Verlet => "verlet".into(),
            Method::Yoshida6 => "yoshida6".into(),
            Method::KahanLi8 => "kahan-li8".into(),
            Method::TimeTransformed(s) => format!("tt-galerkin-{s}"),
            Method::TimeTransformedAuto(s) => format!("tt-auto-galerkin-{s}"),
            Method::TimeTransformedSplit => "tt-split-logh-kahan-li-8".into(),
            Method::Auto => "auto".into(),
        }
    }

    /// The method with this [`name`](Method::name).
    pub fn parse(name: &str) -> Option<Method> {
        Method::all().into_iter().find(|m| m.name() == name)
    }

    /// Who wrote it.
    pub fn family(self) -> Family {
        match self {
            Method::Midpoint
            | Method::Trapezoid
            | Method::AlphaBeta
            | Method::Galerkin(_)
            | Method::EnergyMidpoint
            | Method::GeneratedYoshida4
            | Method::GeneratedYoshida6
            | Method::GeneratedKahanLi8
            | Method::TimeTransformed(_)
            | Method::TimeTransformedAuto(_)
            | Method::TimeTransformedSplit
            | Method::Auto => Family::Project,
            Method::OdeSolversDop853 | Method::DiffEqDop853 | Method::DiffEqGauss6 => Family::Peer,
            Method::Verlet | Method::Yoshida6 | Method::KahanLi8 => Family::HandWritten,
        }
    }

    /// The classical order.
    pub fn order(self) -> u32 {
        match self {
            Method::Midpoint | Method::Trapezoid | Method::EnergyMidpoint | Method::Verlet => 2,
            Method::AlphaBeta => 1,
            Method::Galerkin(s) | Method::TimeTransformed(s) | Method::TimeTransformedAuto(s) => 2 * s as u32,
            Method::OdeSolversDop853 | Method::DiffEqDop853 => 8,
            Method::DiffEqGauss6 | Method::Yoshida6 | Method::GeneratedYoshida6 => 6,
            Method::GeneratedYoshida4 => 4,
            Method::KahanLi8 | Method::GeneratedKahanLi8 | Method::TimeTransformedSplit => 8,
            // Chosen per problem and tolerance; the highest it may choose.
            Method::Auto => 16,
        }
    }

    /// `true` when the method is calibrated by a tolerance rather than a step count.
    pub fn adaptive(self) -> bool {
        matches!(self, Method::OdeSolversDop853 | Method::DiffEqDop853 | Method::DiffEqGauss6 | Method::Auto)
    }

    /// The coarsest `σ` of a time-transformed method's sweep; `None` for the others.
    pub fn sigma0(self) -> Option<f64> {
        match self {
            // Where Newton starts to fail on Kepler e = 0.9 (r^{3/2}); the automatic monitor
            // is about 5^{-1/4} r^{3/2} there, so its σ is larger for the same steps.
            Method::TimeTransformed(s) => Some(0.2 * s as f64),
            Method::TimeTransformedAuto(s) => Some(0.5 * s as f64),
            // The 10-orbit Kepler e = 0.9 problem meets 1e-4 already at this σ (the
            // sweep's first setting), so its time there is an upper bound.
            Method::TimeTransformedSplit => Some(0.8),
            _ => None,
        }
    }

    /// `true` for the methods calibrated by a step count (fixed steps, and
    /// energy-preserving steps from `h0 = T/n`).
    pub fn by_steps(self) -> bool {
        !self.adaptive() && self.sigma0().is_none()
    }

    /// `true` for the time-transformed methods, which need a problem with a step density.
    pub fn needs_time_transform(self) -> bool {
        self.sigma0().is_some()
    }

    /// `true` for the hand-written compositions, which need a separable Hamiltonian.
    pub fn needs_separable(self) -> bool {
        self.family() == Family::HandWritten
    }

    /// The hand-written composition that computes the same map as this
    /// project composition on a separable constant-mass problem (the
    /// trapezoid rule is Störmer–Verlet there), for the generated against
    /// hand-written comparison.
    pub fn hand_written_twin(self) -> Option<Method> {
        match self {
            Method::Trapezoid => Some(Method::Verlet),
            Method::GeneratedYoshida6 => Some(Method::Yoshida6),
            Method::GeneratedKahanLi8 => Some(Method::KahanLi8),
            _ => None,
        }
    }

    /// `true` for symplectic methods (bounded energy error expected).
    pub fn symplectic(self) -> bool {
        !matches!(self, Method::OdeSolversDop853 | Method::DiffEqDop853)
    }
}

/// The outcome of one run.
#[derive(Clone, Debug, Default)]
pub struct Run {
    /// Final positions (empty when the run failed).
    pub q: Vec<f64>,
    /// The failure, if any (the method's own error message).
    pub failure: Option<String>,
    /// Steps taken (accepted steps for adaptive methods).
    pub steps: u64,
    /// Newton iterations per step (project methods; for Gauss Galerkin
    /// rules, fixed-point and Newton iterations).
    pub newton_per_step: Option<f64>,
    /// Right-hand-side or force evaluations (peers and compositions);
    /// derivative evaluations of `L` at quadrature points (Galerkin rules).
    pub evaluations: Option<u64>,
    /// Wall-clock seconds of the integration alone.
    pub seconds: f64,
    /// `(t, (E − E0)/|E0|)` samples, when asked for.
    pub energy: Vec<(f64, f64)>,
    /// `(t, |L − L0|/|L0|)` samples of the angular momentum `L`, at the same
    /// times, when asked for and the problem conserves it.
    pub momentum: Vec<(f64, f64)>,
    /// What the tolerance-driven solve reported ([`Method::Auto`] only).
    pub auto: Option<AutoReport>,
}

/// The estimate and choice of a [`Method::Auto`] run.
#[derive(Clone, Debug, Default)]
pub struct AutoReport {
    /// The estimated global error at the end.
    pub estimate: f64,
    /// The absolute error asked for, `rtol · Q`.
    pub requested: f64,
    /// The method it ran.
    pub method: String,
    /// Steps of the survey and pilot.
    pub pilot_steps: u64,
    /// Wall-clock seconds of the choice and pilot.
    pub pilot_seconds: f64,
    /// The step of the final run (`h`, or `σ` of a time transformation).
    pub step: f64,
    /// The error growth the pilot measured.
    pub growth: String,
}

/// The relative errors of the conserved quantities of a model at a state.
pub(crate) struct Invariants<'a, M, const N: usize> {
    model: &'a M,
    e0: f64,
    l0: Option<[f64; 3]>,
}

impl<'a, M: Model<N>, const N: usize> Invariants<'a, M, N> {
    pub(crate) fn new(model: &'a M, q0: &[f64; N], v0: &[f64; N]) -> Self {
        Self { model, e0: model.energy(q0, v0), l0: model.angular_momentum(q0, v0) }
    }

    /// `(E − E0)/|E0|`.
    pub(crate) fn energy(&self, q: &[f64; N], v: &[f64; N]) -> f64 {
        (self.model.energy(q, v) - self.e0) / self.e0.abs().max(f64::MIN_POSITIVE)
    }

    /// `|L − L0|/|L0|` (Euclidean norms), when the model conserves `L`.
    pub(crate) fn momentum(&self, q: &[f64; N], v: &[f64; N]) -> Option<f64> {
        let (l0, l) = (self.l0?, self.model.angular_momentum(q, v)?);
        let norm = |x: [f64; 3]| x.iter().map(|c| c * c).sum::<f64>().sqrt();
        Some(norm([l[0] - l0[0], l[1] - l0[1], l[2] - l0[2]]) / norm(l0).max(f64::MIN_POSITIVE))
    }
}

impl Run {
    fn failed(message: String, seconds: f64) -> Run {
        Run { failure: Some(message), seconds, ..Run::default() }
    }
}

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
    // The energy of a time-dependent or forced problem changes by physics: nothing to record.
    let samples = if M::CONSERVATIVE { samples } else { 0 };
    let invariants = Invariants::new(model, &q0, &v0);
    let every = if samples > 0 { t_end / samples as f64 } else { f64::INFINITY };
    let mut next = every;
    let mut energy = Vec::with_capacity(samples + 1);
    let mut momentum = Vec::new();
    if samples > 0 {
        energy.push((0.0, 0.0));
        if invariants.momentum(&q0, &v0).is_some() {
            momentum.push((0.0, 0.0));
        }
    }
    let mut record = |t: f64, q: &[f64; N], v: &[f64; N]| {
        if t >= next * (1.0 - 1e-12) {
            energy.push((t, invariants.energy(q, v)));
            if let Some(l) = invariants.momentum(q, v) {
                momentum.push((t, l));
            }
            while next <= t * (1.0 + 1e-12) {
                next += every;
            }
        }
    };
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
        (Method::Galerkin(s), Setting::Steps(n)) => {
            macro_rules! degree {
                ($($s:literal)*) => {
                    match s {
                        $($s => galerkin::<M, N, $s>(model, (q0, v0), n, t_end, samples, &mut record),)*
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
        (Method::Auto, Setting::Tolerance(tol)) => auto(model, (q0, v0), tol, t_end, samples, &mut record),
        (m, s) => Run::failed(format!("{} cannot be run with {s:?}", m.name()), 0.0),
    };
    out.seconds = start.seconds();
    if samples > 0 {
        out.energy.append(&mut energy);
        out.momentum.append(&mut momentum);
        for series in [&mut out.energy, &mut out.momentum] {
            // A run that blew up (its failure says so) would put NaN in the JSON, which has no NaN.
            series.retain(|s| s.1.is_finite());
            series.sort_by(|a, b| a.0.total_cmp(&b.0));
        }
    }
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
    n: usize,
    t_end: f64,
    samples: usize,
    record: &mut impl FnMut(f64, &[f64; N], &[f64; N]),
) -> Run {
    let mut sim =
        match GalerkinIntegrator::new(model.system(), Galerkin::<S, S>::gauss(), t_end / n as f64).start(0.0, q0, v0) {
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
/// `samples > 0` every node is kept and recorded (`record` thins them).
fn auto<M: Model<N>, const N: usize>(
    model: &M,
    (q0, v0): ([f64; N], [f64; N]),
    tol: f64,
    t_end: f64,
    samples: usize,
    record: &mut impl FnMut(f64, &[f64; N], &[f64; N]),
) -> Run {
    // Only the last node unless the energy is sampled.
    let plan = if samples > 0 { Plan::until(t_end) } else { Plan::until(t_end).every(usize::MAX).without_velocities() };
    match Auto::new(model.system(), 0.0, q0, v0).tolerance(Tolerance::relative(tol)).solve(plan) {
        Ok(solved) => {
            let sol = &solved.solution;
            if samples > 0 {
                for ((t, q), v) in sol.t.iter().zip(&sol.q).zip(&sol.v) {
                    record(*t, q, v);
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
