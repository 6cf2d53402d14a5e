//! The one place where the workflow tools (solutions, dense output, events,
//! ensembles, progress) meet the integrators.
//!
//! [`Stepping`] (defined in [`crate::solution`]) is what `solve` needs from
//! an integrator: one step, a landing step, the state and velocity at the
//! node, and the method's own interpolant of the last step. It is implemented here for
//! [`Integrator`] and for [`GalerkinIntegrator`] in `f64`, using only their
//! public accessors; the `solve` methods of both live here too.

use crate::dense::{GalerkinPolynomial, Hermite, Node};
use crate::discrete::DiscreteLagrangian;
use crate::error::Error;
use crate::galerkin::GalerkinIntegrator;
use crate::integrator::{Integrator, Stats, StepPolicy};
use crate::solution::{Plan, Solution, SolveError, Stepping, solve};
use crate::state::State;
use crate::system::Lagrangian;

/// `true` when a fixed step of size `h` from `t` ends within `10⁻⁹ h` of
/// `t_end` or beyond it: the rule of the integrators' `run_until`.
fn fixed_reaches(t: f64, h: f64, t_end: f64) -> bool {
    t + h >= t_end - 1e-9 * h
}

impl<S: Lagrangian<N>, M: DiscreteLagrangian, const N: usize> Stepping<N> for Integrator<S, M, N> {
    type System = S;
    type Native = Hermite<N>;

    fn system(&self) -> &S {
        Integrator::system(self)
    }

    fn state(&self) -> State<N> {
        *Integrator::state(self)
    }

    fn velocity(&self) -> Result<[f64; N], Error<N>> {
        Integrator::velocity(self)
    }

    fn stats(&self) -> Stats {
        *Integrator::stats(self)
    }

    fn step(&mut self) -> Result<(), Error<N>> {
        Integrator::step(self).map(|_| ())
    }

    fn reaches(&self, t_end: f64, _last_h: Option<f64>) -> bool {
        let t = Integrator::state(self).t;
        match self.policy() {
            StepPolicy::Fixed => fixed_reaches(t, self.step_size(), t_end),
            StepPolicy::EnergyPreserving(b) => match self.last_step() {
                Some(last) => t_end - t <= b.bracket(last.h).1,
                None => t_end - t <= self.step_size(),
            },
        }
    }

    fn land(&mut self, t: f64) -> Result<(), Error<N>> {
        self.run_until(t, |_| {})
    }

    /// The one-point rules have no interpolant of their own (their step is a
    /// straight line): the cubic Hermite through both nodes.
    fn native(&self, start: &Node<N>, end: &Node<N>) -> Hermite<N> {
        Hermite::cubic(start, end)
    }
}

impl<Sys: Lagrangian<N>, const N: usize, const S: usize, const R: usize> Stepping<N>
    for GalerkinIntegrator<Sys, N, S, R>
{
    type System = Sys;
    type Native = GalerkinPolynomial<N, S>;

    fn system(&self) -> &Sys {
        GalerkinIntegrator::system(self)
    }

    fn state(&self) -> State<N> {
        *GalerkinIntegrator::state(self)
    }

    fn velocity(&self) -> Result<[f64; N], Error<N>> {
        GalerkinIntegrator::velocity(self)
    }

    fn stats(&self) -> Stats {
        *GalerkinIntegrator::stats(self)
    }

    fn step(&mut self) -> Result<(), Error<N>> {
        GalerkinIntegrator::step(self).map(|_| ())
    }

    fn reaches(&self, t_end: f64, last_h: Option<f64>) -> bool {
        let t = GalerkinIntegrator::state(self).t;
        match (self.policy(), last_h) {
            (None, _) => fixed_reaches(t, self.step_size(), t_end),
            (Some(b), Some(h)) => t_end - t <= b.bracket(h).1,
            (Some(_), None) => t_end - t <= self.step_size(),
        }
    }

    fn land(&mut self, t: f64) -> Result<(), Error<N>> {
        self.run_until(t, |_| {})
    }

    fn native(&self, start: &Node<N>, end: &Node<N>) -> GalerkinPolynomial<N, S> {
        let nodes = self.last_nodes().unwrap_or([end.q; S]);
        GalerkinPolynomial::new(start.t, end.t - start.t, *self.method().control_nodes(), start.q, nodes)
    }
}

impl<S: Lagrangian<N> + Clone, M: DiscreteLagrangian + Clone, const N: usize> Integrator<S, M, N> {
    /// Integrates as `plan` says and returns the [`Solution`]: the nodes
    /// (from the current one on), values at requested times by dense output,
    /// events, statistics and how the run ended. See [`crate::solution`].
    ///
    /// Returns `Err` only for a plan that cannot run (nothing is integrated
    /// then); a failure during the run ends it with the partial solution,
    /// whose [`status`](Solution::status) and [`error`](Solution::error) say
    /// what failed. The integrator is left at the last node of the solution.
    pub fn solve(&mut self, plan: Plan<'_, N>) -> Result<Solution<N>, SolveError<N>> {
        solve(self, plan)
    }
}

impl<Sys: Lagrangian<N> + Clone, const N: usize, const S: usize, const R: usize> GalerkinIntegrator<Sys, N, S, R> {
    /// Integrates as `plan` says and returns the [`Solution`]; see
    /// [`Integrator::solve`].
    pub fn solve(&mut self, plan: Plan<'_, N>) -> Result<Solution<N>, SolveError<N>> {
        solve(self, plan)
    }
}
