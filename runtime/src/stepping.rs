//! The one place where the workflow tools (solutions, dense output, events,
//! ensembles, progress) meet the integrators.
//!
//! [`Stepping`] (defined in [`crate::solution`]) is what `solve` needs from
//! an integrator: one step, a landing step, the state and velocity at the
//! node, and the method's own interpolant of the last step. It is implemented here for
//! the one [`Integrator`] in `f64`, once per family of methods (they differ
//! only in their own interpolant), using only its public accessors; `solve`
//! lives here too.

use crate::dense::{GalerkinPolynomial, Hermite, Node};
use crate::discrete::DiscreteLagrangian;
use crate::error::Error;
use crate::galerkin::GalerkinIntegrator;
use crate::integrator::{F64Readouts, Integrator, Stats, StepPolicy};
use crate::solution::{Plan, Solution, SolveError, Stepping, solve};
use crate::state::State;
use crate::system::Lagrangian;

/// `true` when a fixed step of size `h` from `t` ends within `10⁻⁹ h` of
/// `t_end` or beyond it: the rule of the integrators' `run_until`.
fn fixed_reaches(t: f64, h: f64, t_end: f64) -> bool {
    t + h >= t_end - 1e-9 * h
}

/// Whether the next step of `run_until(t_end)` is its landing step.
fn reaches<S: Lagrangian<N>, M: F64Readouts, const N: usize>(it: &Integrator<S, M, N>, t_end: f64) -> bool {
    let t = it.state().t;
    match it.policy() {
        StepPolicy::Fixed => fixed_reaches(t, it.step_size(), t_end),
        StepPolicy::EnergyPreserving(b) => match it.last_step_size() {
            Some(h) => t_end - t <= b.bracket(h).1,
            None => t_end - t <= it.step_size(),
        },
    }
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
        reaches(self, t_end)
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

    fn reaches(&self, t_end: f64, _last_h: Option<f64>) -> bool {
        reaches(self, t_end)
    }

    fn land(&mut self, t: f64) -> Result<(), Error<N>> {
        self.run_until(t, |_| {})
    }

    fn native(&self, start: &Node<N>, end: &Node<N>) -> GalerkinPolynomial<N, S> {
        let nodes = self.last_nodes().unwrap_or([end.q; S]);
        GalerkinPolynomial::new(start.t, end.t - start.t, *self.method().control_nodes(), start.q, nodes)
    }
}

impl<S: Lagrangian<N> + Clone, M: F64Readouts, const N: usize> Integrator<S, M, N>
where
    Self: Stepping<N>,
{
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
