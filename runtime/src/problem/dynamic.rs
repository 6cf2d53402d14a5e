//! The run-time size of [`Problem`] and [`Stepper`]: the same [`Scheme`] and
//! [`Policy`] values on a [`DynLagrangian`], stepped by the reverse-mode
//! [`DynIntegrator`] (a composition of its midpoint, α-β or Galerkin steps
//! by the adapter of both sizes, [`Composed`]; the implicit time
//! transformation: in `s`, on the
//! extended system of `n + 1` coordinates, by [`RunTimeAdaptive`]; the
//! explicit time-transformed splitting by [`RunTimeSplitting`]); what those
//! drivers do not have is refused by
//! [`supports`](super::supports) with [`Error::Unsupported`]. The
//! drivers are [`RunTimeStepping`]s, and so are the enum of them and the
//! stepper: one `match` on the driver per call.

use super::composed::{Composed, SubSteps};
use super::scheme::{GalerkinQuadrature, OnePoint, Scheme};
use super::statement::Problem;
use super::stepper::{Steppable, Stepper};
use super::support::{Capability, Combination, Policy, Size, supports};
use crate::dim::Dyn;
use crate::discrete::{AlphaBeta, Midpoint, Trapezoid};
use crate::error::Error;
use crate::integrator::{Composition, DynIntegrator, DynMethod, RunTimeGalerkin, Stats};
use crate::solution::{Plan, RunTimeStepping, Solution, SolveError};
use crate::state::PhasePoint;
use crate::system::DynLagrangian;
use crate::time_transform::{RuleInS, RunTimeAdaptive, RunTimeSplitting, SplittingStats};

/// The driver of a run-time-sized [`Stepper`].
#[derive(Debug)]
pub enum DynDriver<S> {
    Midpoint(DynIntegrator<S, Midpoint>),
    Trapezoid(DynIntegrator<S, Trapezoid>),
    AlphaBeta(DynIntegrator<S, AlphaBeta>),
    Composition(DynIntegrator<S, Composition>),
    Galerkin(DynIntegrator<S, RunTimeGalerkin>),
    /// Boxed: it holds its base driver twice (the copy from before the
    /// step), and the type is recursive.
    Composed(Box<Composed<DynDriver<S>>>),
    // Boxed: the driver in `s` and its copy from before the step.
    TimeTransformed(Box<RunTimeAdaptive<S>>),
    /// Boxed: its trial points and buffers make it several times the
    /// size of the other drivers.
    Splitting(Box<RunTimeSplitting<S>>),
}

/// Runs `$body` with `$d` bound to the driver of whichever variant `$x` is
/// (`ref`: shared, `mut`: exclusive; the boxed ones unboxed).
macro_rules! each {
    (ref $x:expr, $d:ident => $body:expr) => {
        match $x {
            DynDriver::Midpoint($d) => $body,
            DynDriver::Trapezoid($d) => $body,
            DynDriver::AlphaBeta($d) => $body,
            DynDriver::Composition($d) => $body,
            DynDriver::Galerkin($d) => $body,
            DynDriver::Composed($d) => {
                let $d = &**$d;
                $body
            }
            DynDriver::TimeTransformed($d) => {
                let $d = &**$d;
                $body
            }
            DynDriver::Splitting($d) => {
                let $d = &**$d;
                $body
            }
        }
    };
    (mut $x:expr, $d:ident => $body:expr) => {
        match $x {
            DynDriver::Midpoint($d) => $body,
            DynDriver::Trapezoid($d) => $body,
            DynDriver::AlphaBeta($d) => $body,
            DynDriver::Composition($d) => $body,
            DynDriver::Galerkin($d) => $body,
            DynDriver::Composed($d) => {
                let $d = &mut **$d;
                $body
            }
            DynDriver::TimeTransformed($d) => {
                let $d = &mut **$d;
                $body
            }
            DynDriver::Splitting($d) => {
                let $d = &mut **$d;
                $body
            }
        }
    };
}

/// A copy in place when both drivers are of one kind: `solve` refreshes its
/// copy of the stepper, and a composition its copy of the base, before
/// every step.
impl<S: Clone> Clone for DynDriver<S> {
    fn clone(&self) -> Self {
        match self {
            Self::Midpoint(d) => Self::Midpoint(d.clone()),
            Self::Trapezoid(d) => Self::Trapezoid(d.clone()),
            Self::AlphaBeta(d) => Self::AlphaBeta(d.clone()),
            Self::Composition(d) => Self::Composition(d.clone()),
            Self::Galerkin(d) => Self::Galerkin(d.clone()),
            Self::Composed(d) => Self::Composed(d.clone()),
            Self::TimeTransformed(d) => Self::TimeTransformed(d.clone()),
            Self::Splitting(d) => Self::Splitting(d.clone()),
        }
    }

    fn clone_from(&mut self, source: &Self) {
        match (self, source) {
            (Self::Midpoint(a), Self::Midpoint(b)) => a.clone_from(b),
            (Self::Trapezoid(a), Self::Trapezoid(b)) => a.clone_from(b),
            (Self::AlphaBeta(a), Self::AlphaBeta(b)) => a.clone_from(b),
            (Self::Composition(a), Self::Composition(b)) => a.clone_from(b),
            (Self::Galerkin(a), Self::Galerkin(b)) => a.clone_from(b),
            (Self::Composed(a), Self::Composed(b)) => a.clone_from(b),
            (Self::TimeTransformed(a), Self::TimeTransformed(b)) => a.clone_from(b),
            (Self::Splitting(a), Self::Splitting(b)) => a.clone_from(b),
            (this, _) => *this = source.clone(),
        }
    }
}

/// Why a driver is not a base of [`Composed`] ([`supports`] refuses those
/// compositions before a driver is built).
const NOT_A_BASE: &str =
    "a composition of this method: the sub-steps of a composition are of a one-point or Galerkin rule";

/// Whichever driver as the base of a composition ([`Composed`]): the
/// integrators' own step of a given size.
impl<S: DynLagrangian + Clone> SubSteps for DynDriver<S> {
    fn sub_step(&mut self, h: f64, t1: f64) -> Result<(), Error> {
        match self {
            Self::Midpoint(d) => d.sub_step(h, t1),
            Self::Trapezoid(d) => d.sub_step(h, t1),
            Self::AlphaBeta(d) => d.sub_step(h, t1),
            Self::Galerkin(d) => d.sub_step(h, t1),
            Self::Composition(_) | Self::Composed(_) | Self::TimeTransformed(_) | Self::Splitting(_) => {
                Err(Error::Unsupported { what: NOT_A_BASE })
            }
        }
    }

    fn time(&self) -> f64 {
        RunTimeStepping::state(self).t
    }

    fn number(&mut self, k: u64) {
        match self {
            Self::Midpoint(d) => d.number_node(k),
            Self::Trapezoid(d) => d.number_node(k),
            Self::AlphaBeta(d) => d.number_node(k),
            Self::Galerkin(d) => d.number_node(k),
            // Never a base (`sub_step` refuses them).
            Self::Composition(_) | Self::Composed(_) | Self::TimeTransformed(_) | Self::Splitting(_) => {}
        }
    }
}

impl<S: DynLagrangian + Clone> Steppable<Dyn> for S {
    type Driver = DynDriver<S>;
}

/// A system whose number of coordinates is known at run time, with its
/// initial data: stated by `Vec<f64>` coordinates, stepped in reverse mode
/// on a tape.
///
/// ```
/// use lagrangian_runtime::problem::{Capability, Problem, Scheme};
/// use lagrangian_runtime::{Composition, DynLagrangian, Plan, Scalar};
///
/// /// Uncoupled oscillators, as many as `n`.
/// #[derive(Clone)]
/// struct Oscillators { n: usize }
/// impl DynLagrangian for Oscillators {
///     const AUTONOMOUS: bool = true;
///     fn dimension(&self) -> usize { self.n }
///     fn lagrangian<D: Scalar>(&self, _t: D, q: &[D], v: &[D]) -> D {
///         let mut l = D::from(0.0);
///         for i in 0..q.len() {
///             l += (v[i] * v[i] - q[i] * q[i]) * 0.5;
///         }
///         l
///     }
/// }
///
/// let problem = Problem::new(Oscillators { n: 3 }, 0.0, vec![1.0; 3], vec![0.0; 3]);
/// let mut sim = problem.stepper(&Scheme::MIDPOINT, 0.01)?;
/// sim.run_until(1.0)?;
/// assert_eq!(sim.state().t, 1.0);
/// assert!((sim.state().q[2] - 1f64.cos()).abs() < 1e-4);
/// // A Galerkin rule of degree 3 (order 6): the same oscillators to 1e-9.
/// let mut galerkin = problem.stepper(&Scheme::galerkin(3), 0.1)?;
/// galerkin.run_until(1.0)?;
/// assert!((galerkin.state().q[2] - 1f64.cos()).abs() < 1e-8);
/// // The implicit time transformation: fixed steps in `s`, landing exactly in `t`.
/// let curvature = lagrangian_runtime::Curvature::new(1.0).unwrap();
/// let mut adaptive = problem.stepper(&Scheme::MIDPOINT.time_transformed(curvature), 0.01)?;
/// adaptive.run_until(1.0)?;
/// assert_eq!(adaptive.state().t, 1.0);
/// assert!((adaptive.state().q[2] - 1f64.cos()).abs() < 1e-4);
/// // `solve(Plan)` gives the same `Solution` as at a compile-time size.
/// assert!(problem.supports(&Scheme::MIDPOINT, 0.01, Capability::Solve).is_ok());
/// let solution = problem.solve(&Scheme::MIDPOINT, 0.01, Plan::until(1.0).every(10))?;
/// assert_eq!((solution.len(), solution.width()), (11, 3));
/// assert_eq!(solution.q.last(), Some(&sim.state().q[..]));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
impl<S: DynLagrangian + Clone> Problem<S, Dyn> {
    /// The initial data `(t0, q0, v0)`.
    pub fn initial(&self) -> (f64, &[f64], &[f64]) {
        (self.t0, &self.q0, &self.v0)
    }

    /// `Ok` when `scheme` under `policy` can do `capability` on a
    /// run-time-sized system; otherwise [`Error::Unsupported`] naming
    /// the combination.
    pub fn supports(&self, scheme: &Scheme, policy: impl Into<Policy>, capability: Capability) -> Result<(), Error> {
        let combination = Combination {
            scheme,
            policy: policy.into(),
            size: Size::Dynamic,
            forced: S::HAS_FORCE || S::HAS_DISSIPATION,
            constraints: 0,
            capability,
        };
        supports(&combination).map_err(|what| Error::Unsupported { what })
    }

    /// A stepper of `scheme` under `policy`; [`Error::Unsupported`] for
    /// what [`supports`](super::supports) refuses, else the driver's own
    /// errors of `start`.
    pub fn stepper(&self, scheme: &Scheme, policy: impl Into<Policy>) -> Result<Stepper<S, Dyn>, Error> {
        let policy = policy.into();
        self.supports(scheme, policy, Capability::Step)?;
        let driver = match scheme {
            Scheme::OnePoint(OnePoint::Midpoint) => DynDriver::Midpoint(self.start(Midpoint, policy)?),
            Scheme::OnePoint(OnePoint::Trapezoid) => DynDriver::Trapezoid(self.start(Trapezoid, policy)?),
            Scheme::OnePoint(OnePoint::AlphaBeta(m)) => DynDriver::AlphaBeta(self.start(*m, policy)?),
            Scheme::Composition { weights, base } if **base == Scheme::TRAPEZOID => {
                DynDriver::Composition(self.start(*weights, policy)?)
            }
            // Fixed steps of the base (`supports` refuses variable ones).
            Scheme::Composition { weights, base } => {
                let base = self.stepper(base, Policy::Fixed { h: policy.step() })?.driver;
                DynDriver::Composed(Box::new(Composed::new(base, *weights, policy.step())))
            }
            Scheme::Galerkin { degree, nodes, quadrature } => {
                let lobatto = *quadrature == GalerkinQuadrature::GaussLobatto;
                DynDriver::Galerkin(self.start(RunTimeGalerkin::new(*degree, *nodes, lobatto), policy)?)
            }
            Scheme::TimeTransformed { inner, density } => DynDriver::TimeTransformed(Box::new(RunTimeAdaptive::start(
                self.system.clone(),
                rule_in_s(inner)?,
                *density,
                policy.step(),
                self.newton,
                self.t0,
                &self.q0,
                &self.v0,
            )?)),
            Scheme::Splitting { function, composition } => {
                let data = (self.t0, &self.q0[..], &self.v0[..]);
                let split = RunTimeSplitting::start(self.system.clone(), *function, *composition, policy.step(), data)?;
                DynDriver::Splitting(Box::new(split))
            }
        };
        Ok(Stepper { driver, scheme: scheme.clone(), policy })
    }

    /// Integrates with `scheme` under `policy` as `plan` says: the same
    /// [`Solution`] and [`SolveError`] as at a compile-time size (see
    /// [`Stepper::solve`]). A refused
    /// combination or a failed start is `SolveError::Step`.
    pub fn solve(&self, scheme: &Scheme, policy: impl Into<Policy>, plan: Plan<'_>) -> Result<Solution, SolveError> {
        let policy = policy.into();
        self.supports(scheme, policy, Capability::Solve)?;
        self.stepper(scheme, policy)?.solve(plan)
    }

    fn start<M: DynMethod>(&self, method: M, policy: Policy) -> Result<DynIntegrator<S, M>, Error> {
        let mut builder = DynIntegrator::new(self.system.clone(), method, policy.step())
            .summation(self.summation)
            .energy_fallback(self.fallback);
        if let Some(options) = self.newton {
            builder = builder.newton(options);
        }
        if let Some(bounds) = policy.bounds() {
            builder = builder.energy_preserving(bounds);
        }
        builder.start(self.t0, &self.q0, &self.v0)
    }
}

/// The method in `s` of a time transformation at a run-time size (the
/// schemes [`supports`] accepts there).
fn rule_in_s(inner: &Scheme) -> Result<RuleInS, Error> {
    let rule = match inner {
        Scheme::OnePoint(OnePoint::Midpoint) => RuleInS::one_point(&Midpoint),
        Scheme::OnePoint(OnePoint::Trapezoid) => RuleInS::one_point(&Trapezoid),
        Scheme::OnePoint(OnePoint::AlphaBeta(m)) => RuleInS::one_point(m),
        Scheme::Galerkin { degree, nodes, quadrature } => {
            let lobatto = *quadrature == GalerkinQuadrature::GaussLobatto;
            Some(RuleInS::Galerkin(RunTimeGalerkin::new(*degree, *nodes, lobatto)))
        }
        _ => None,
    };
    rule.ok_or(Error::Unsupported { what: "this method in `s` under the time transformation" })
}

/// The inherent names of [`RunTimeStepping`], so that the trait need not
/// be in scope (as `Stepper<S, Dim<N>>` has those of
/// [`Stepping`](crate::Stepping)), and what one driver has alone.
impl<S: DynLagrangian + Clone> Stepper<S, Dyn> {
    /// The state `(k, t_k, q_k, p_k)` at the current node: physical time
    /// and momenta for every scheme, `k` counting steps (in `s` for the
    /// time-transformed ones); vectors, where `Stepper<S, Dim<N>>` has
    /// arrays.
    pub fn state(&self) -> &PhasePoint {
        RunTimeStepping::state(self)
    }

    /// The momenta `p_k` at the current node.
    pub fn momenta(&self) -> &[f64] {
        &self.state().p
    }

    /// The velocity whose momentum is `p_k`.
    pub fn velocity(&self) -> Result<Vec<f64>, Error> {
        RunTimeStepping::velocity(self)
    }

    /// The energy `E_L(t_k, q_k, v_k)` at the current node.
    pub fn energy(&self) -> Result<f64, Error> {
        RunTimeStepping::energy(self)
    }

    /// The discrete energy `E_k = −∂A(x_{k−1}, x_k)/∂t_k` of the last step:
    /// the energy that [`Policy::EnergyPreserving`] steps conserve (at
    /// `k = 0`, the energy of the initial data). Under the implicit time
    /// transformation and the explicit splitting, `−p_t`: the momentum of
    /// time, which their steps in `s` conserve for an autonomous system.
    pub fn discrete_energy(&self) -> f64 {
        RunTimeStepping::discrete_energy(self)
    }

    /// Work counters (steps; Newton iterations and the last step's
    /// [`NewtonReport`](crate::NewtonReport) of the implicit schemes).
    pub fn stats(&self) -> Stats {
        RunTimeStepping::stats(self)
    }

    /// The system.
    pub fn system(&self) -> &S {
        RunTimeStepping::system(self)
    }

    /// The size of the next step: `h` in `t` (under energy-preserving
    /// steps, the guess of the next one), `σ` in `s` for the
    /// time-transformed schemes.
    pub fn step_size(&self) -> f64 {
        RunTimeStepping::step_size(self)
    }

    /// The physical time the last step advanced; `None` before the first.
    pub fn last_step_size(&self) -> Option<f64> {
        RunTimeStepping::last_step_size(self)
    }

    /// Changes the size of the following steps (`h`, or `σ` in `s`), for
    /// example to retry a failed step with a smaller one; a size that is
    /// not finite and positive, or outside the bounds of energy-preserving
    /// steps, is refused and nothing changes.
    pub fn set_step_size(&mut self, h: f64) -> Result<(), Error> {
        RunTimeStepping::set_step_size(self, h)
    }

    /// The explicit splitting's own counters (gradient evaluations, landing
    /// trials); `None` for the other schemes.
    pub fn splitting_stats(&self) -> Option<SplittingStats> {
        match &self.driver {
            DynDriver::Splitting(d) => Some(d.splitting_stats()),
            _ => None,
        }
    }

    /// One step; on failure nothing changes.
    pub fn step(&mut self) -> Result<&PhasePoint, Error> {
        RunTimeStepping::step(self)?;
        Ok(self.state())
    }

    /// `n` steps, calling `observe` after each.
    pub fn run(&mut self, n: usize, observe: impl FnMut(&Self)) -> Result<(), Error> {
        RunTimeStepping::run(self, n, observe)
    }

    /// Steps to `t_end` exactly (see [`RunTimeStepping::run_until`]).
    pub fn run_until(&mut self, t_end: f64) -> Result<(), Error> {
        RunTimeStepping::run_until(self, t_end)
    }

    /// Integrates as `plan` says (see [`RunTimeStepping::solve`]): the same
    /// [`Solution`] and [`SolveError`] as at a compile-time size. The
    /// stepper is left at the last node of the solution.
    pub fn solve(&mut self, plan: Plan<'_>) -> Result<Solution, SolveError> {
        RunTimeStepping::solve(self, plan)
    }
}

/// Each call is one `match` on the driver.
impl<S: DynLagrangian + Clone> RunTimeStepping for DynDriver<S> {
    type System = S;

    fn system(&self) -> &S {
        each!(ref self, d => RunTimeStepping::system(d))
    }

    fn state(&self) -> &PhasePoint {
        each!(ref self, d => RunTimeStepping::state(d))
    }

    fn velocity(&self) -> Result<Vec<f64>, Error> {
        each!(ref self, d => RunTimeStepping::velocity(d))
    }

    fn energy(&self) -> Result<f64, Error> {
        each!(ref self, d => RunTimeStepping::energy(d))
    }

    fn discrete_energy(&self) -> f64 {
        each!(ref self, d => RunTimeStepping::discrete_energy(d))
    }

    fn stats(&self) -> Stats {
        each!(ref self, d => RunTimeStepping::stats(d))
    }

    #[inline]
    fn step(&mut self) -> Result<(), Error> {
        each!(mut self, d => RunTimeStepping::step(d))
    }

    fn step_toward(&mut self, t_end: f64) -> Result<(), Error> {
        each!(mut self, d => RunTimeStepping::step_toward(d, t_end))
    }

    fn step_size(&self) -> f64 {
        each!(ref self, d => RunTimeStepping::step_size(d))
    }

    fn last_step_size(&self) -> Option<f64> {
        each!(ref self, d => RunTimeStepping::last_step_size(d))
    }

    fn set_step_size(&mut self, h: f64) -> Result<(), Error> {
        each!(mut self, d => RunTimeStepping::set_step_size(d, h))
    }

    fn step_polynomial(&self) -> Option<(f64, &[f64], &[f64])> {
        each!(ref self, d => RunTimeStepping::step_polynomial(d))
    }
}

/// The driver's, through one `match` on it.
impl<S: DynLagrangian + Clone> RunTimeStepping for Stepper<S, Dyn> {
    type System = S;

    fn system(&self) -> &S {
        RunTimeStepping::system(&self.driver)
    }

    fn state(&self) -> &PhasePoint {
        RunTimeStepping::state(&self.driver)
    }

    fn velocity(&self) -> Result<Vec<f64>, Error> {
        RunTimeStepping::velocity(&self.driver)
    }

    fn energy(&self) -> Result<f64, Error> {
        RunTimeStepping::energy(&self.driver)
    }

    fn discrete_energy(&self) -> f64 {
        RunTimeStepping::discrete_energy(&self.driver)
    }

    fn stats(&self) -> Stats {
        RunTimeStepping::stats(&self.driver)
    }

    #[inline]
    fn step(&mut self) -> Result<(), Error> {
        RunTimeStepping::step(&mut self.driver)
    }

    fn step_toward(&mut self, t_end: f64) -> Result<(), Error> {
        RunTimeStepping::step_toward(&mut self.driver, t_end)
    }

    fn step_size(&self) -> f64 {
        RunTimeStepping::step_size(&self.driver)
    }

    fn last_step_size(&self) -> Option<f64> {
        RunTimeStepping::last_step_size(&self.driver)
    }

    fn set_step_size(&mut self, h: f64) -> Result<(), Error> {
        RunTimeStepping::set_step_size(&mut self.driver, h)
    }

    fn step_polynomial(&self) -> Option<(f64, &[f64], &[f64])> {
        RunTimeStepping::step_polynomial(&self.driver)
    }
}
