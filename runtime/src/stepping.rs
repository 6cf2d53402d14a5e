//! The one place where the workflow tools (solutions, dense output, events,
//! ensembles, progress) meet the integrators.
//!
//! [`Stepping`] (defined in [`crate::solution`]) is what `solve` needs from
//! a const-size integrator: one step, a landing step, the state and velocity at the
//! node, and the method's own interpolant of the last step. It is implemented here once for
//! the one [`Integrator`] in `f64`, for every method (one-point rules,
//! Galerkin, compositions: they differ only in their own interpolant, which
//! the method brings), using only its public accessors; `solve` is the
//! trait's provided method. The run-time-sized [`DynIntegrator`] implements
//! its run-time counterpart, [`RunTimeStepping`], here too: its nodes are
//! `Vec<f64>` and its dense output a Galerkin rule's step polynomial or the
//! cubic Hermite of the nodes (each method's own at a compile-time size as
//! well).

use crate::dense::{Hermite, Node};
use crate::error::Error;
use crate::integrator::{DynIntegrator, DynMethod, F64Readouts, Integrator, Stats, StepPolicy, fixed_step_lands};
use crate::solution::{RunTimeStepping, Stepping};
use crate::state::{PhasePoint, State};
use crate::system::{DynLagrangian, Lagrangian};
use crate::time_transform::{Adaptive, ExplicitAdaptive, SStepper, StepDensity, TimeTransformed};

/// Whether the next step of `run_until(t_end)` is its landing step.
fn reaches<S: Lagrangian<N>, M: F64Readouts, const N: usize>(it: &Integrator<S, M, N>, t_end: f64) -> bool {
    let t = it.state().t;
    match it.policy() {
        StepPolicy::Fixed => fixed_step_lands(t + it.step_size(), it.step_size(), t_end),
        StepPolicy::EnergyPreserving(b) => match it.last_step_size() {
            Some(h) => t_end - t <= b.bracket(h).1,
            None => t_end - t <= it.step_size(),
        },
    }
}

impl<S: Lagrangian<N>, M: F64Readouts, const N: usize> Stepping<N> for Integrator<S, M, N> {
    type System = S;
    type Native = M::Native<N>;

    fn system(&self) -> &S {
        Integrator::system(self)
    }

    fn state(&self) -> State<N> {
        *Integrator::state(self)
    }

    fn velocity(&self) -> Result<[f64; N], Error> {
        Integrator::velocity(self)
    }

    fn stats(&self) -> Stats {
        *Integrator::stats(self)
    }

    #[inline]
    fn step(&mut self) -> Result<(), Error> {
        Integrator::step(self).map(|_| ())
    }

    fn step_toward(&mut self, t_end: f64, _last_h: Option<f64>) -> Result<(), Error> {
        if reaches(self, t_end) { self.run_until(t_end, |_| {}) } else { Integrator::step(self).map(|_| ()) }
    }

    fn land(&mut self, t: f64) -> Result<(), Error> {
        self.run_until(t, |_| {})
    }

    /// The method's own interpolant: the cubic Hermite for the one-point
    /// rules and compositions, the step polynomial for Galerkin.
    fn native(&self, start: &Node<N>, end: &Node<N>) -> M::Native<N> {
        M::native(self, start, end)
    }
}

/// The implicit time-transformed driver in `f64`: its steps are steps of
/// `σ` in `s`; landing solves for the partial step in `s` that ends on the
/// physical time asked for.
impl<I, Sys, G, const N: usize, const M: usize> Stepping<N> for Adaptive<I, Sys, G, N, M>
where
    I: SStepper<M, System = TimeTransformed<Sys, G, N>>,
    Sys: Lagrangian<N>,
    G: StepDensity<N>,
{
    type System = Sys;
    type Native = Hermite<N>;

    fn system(&self) -> &Sys {
        Adaptive::system(self)
    }

    fn state(&self) -> State<N> {
        Adaptive::state(self)
    }

    fn velocity(&self) -> Result<[f64; N], Error> {
        Adaptive::velocity(self)
    }

    fn stats(&self) -> Stats {
        Adaptive::stats(self)
    }

    fn step(&mut self) -> Result<(), Error> {
        Adaptive::step(self).map(|_| ())
    }

    fn step_toward(&mut self, t_end: f64, _last_h: Option<f64>) -> Result<(), Error> {
        Adaptive::step_toward(self, t_end)
    }

    fn land(&mut self, t: f64) -> Result<(), Error> {
        self.run_until(t, |_| {})
    }

    /// The cubic Hermite through both nodes in physical time.
    fn native(&self, start: &Node<N>, end: &Node<N>) -> Hermite<N> {
        Hermite::cubic(start, end)
    }
}

/// The explicit time-transformed splitting: steps of `σ` in `s`, landing
/// by the partial step in `s` that ends on the physical time asked for.
impl<Sys: Lagrangian<N>, const N: usize> Stepping<N> for ExplicitAdaptive<Sys, f64, N> {
    type System = Sys;
    type Native = Hermite<N>;

    fn system(&self) -> &Sys {
        ExplicitAdaptive::system(self)
    }

    fn state(&self) -> State<N> {
        ExplicitAdaptive::state(self)
    }

    fn velocity(&self) -> Result<[f64; N], Error> {
        Ok(ExplicitAdaptive::velocity(self))
    }

    /// Steps in `s`; the gradient evaluations of `V` are not Newton
    /// iterations and are not counted here (see [`ExplicitAdaptive::stats`]).
    fn stats(&self) -> Stats {
        Stats { steps: ExplicitAdaptive::stats(self).steps, ..Stats::default() }
    }

    fn step(&mut self) -> Result<(), Error> {
        ExplicitAdaptive::step(self).map(|_| ())
    }

    fn step_toward(&mut self, t_end: f64, _last_h: Option<f64>) -> Result<(), Error> {
        ExplicitAdaptive::step_toward(self, t_end)
    }

    fn land(&mut self, t: f64) -> Result<(), Error> {
        self.run_until(t, |_| {})
    }

    /// The cubic Hermite through both nodes in physical time.
    fn native(&self, start: &Node<N>, end: &Node<N>) -> Hermite<N> {
        Hermite::cubic(start, end)
    }
}

/// The run-time-sized integrator: fixed steps of `h` (or energy-preserving
/// ones), the landing step shortened to end on the target.
impl<S: DynLagrangian, M: DynMethod> RunTimeStepping for DynIntegrator<S, M> {
    type System = S;

    fn system(&self) -> &S {
        DynIntegrator::system(self)
    }

    fn state(&self) -> &PhasePoint {
        DynIntegrator::state(self)
    }

    fn velocity(&self) -> Result<Vec<f64>, Error> {
        DynIntegrator::velocity(self)
    }

    fn energy(&self) -> Result<f64, Error> {
        DynIntegrator::energy(self)
    }

    fn discrete_energy(&self) -> f64 {
        DynIntegrator::discrete_energy(self)
    }

    fn stats(&self) -> Stats {
        *DynIntegrator::stats(self)
    }

    #[inline]
    fn step(&mut self) -> Result<(), Error> {
        DynIntegrator::step(self).map(|_| ())
    }

    fn step_toward(&mut self, t_end: f64) -> Result<(), Error> {
        DynIntegrator::step_toward(self, t_end)
    }

    fn step_size(&self) -> f64 {
        DynIntegrator::step_size(self)
    }

    fn last_step_size(&self) -> Option<f64> {
        DynIntegrator::last_step_size(self)
    }

    fn set_step_size(&mut self, h: f64) -> Result<(), Error> {
        DynIntegrator::set_step_size(self, h)
    }

    /// A Galerkin rule's step polynomial.
    fn step_polynomial(&self) -> Option<(f64, &[f64], &[f64])> {
        self.galerkin_nodes()
    }
}
