//! The one place where the workflow tools (solutions, dense output, events,
//! ensembles, progress) meet the integrators.
//!
//! [`Stepping`] (defined in [`crate::solution`]) is what `solve` needs from
//! a const-size integrator: one step, a landing step, the state and velocity at the
//! node, and the method's own interpolant of the last step. It is implemented here once for
//! the one [`Integrator`] in `f64`, for every method (one-point rules,
//! Galerkin, compositions: they differ only in their own interpolant, which
//! the method brings), using only its public accessors; `solve` is the
//! trait's provided method. The run-time-sized [`DynIntegrator`] is driven
//! by the same `solve` through the size-free [`Solvable`], implemented here
//! too: its nodes are `Vec<f64>` and its dense output the cubic Hermite of
//! the nodes (the one-point rules' and compositions' own at a compile-time
//! size as well).

use crate::dense::{Hermite, HermiteRows, Node, Point, RunTimeStep, StepPolynomial};
use crate::error::Error;
use crate::integrator::{DynIntegrator, DynMethod, F64Readouts, Integrator, Stats, StepPolicy};
use crate::solution::{Plan, Solution, Solvable, SolveError, Stepping, solve};
use crate::state::State;
use crate::system::{DynLagrangian, Lagrangian};
use crate::time_transform::{Adaptive, ExplicitAdaptive, SStepper, StepDensity, TimeTransformed};

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

/// `solve` on a run-time-sized integrator: the nodes as `Vec<f64>`, dense
/// output by a Galerkin rule's step polynomial or the cubic Hermite of the
/// nodes (each method's own interpolant at a compile-time size too), momenta
/// and energies between nodes by the integrator's reverse sweeps. No
/// acceleration: quintic dense output is refused before the run.
pub(crate) struct RunTimeSize<S, M>(core::marker::PhantomData<(S, M)>);

impl<S: DynLagrangian + Clone, M: DynMethod + Clone> Solvable for RunTimeSize<S, M> {
    type Sim = DynIntegrator<S, M>;
    type Vector = Vec<f64>;
    type Native = RunTimeStep;
    type Hermite = HermiteRows;
    const ACCELERATION: bool = false;

    fn width(sim: &Self::Sim) -> usize {
        sim.dimension()
    }

    fn time(sim: &Self::Sim) -> f64 {
        sim.state().t
    }

    fn node(sim: &Self::Sim) -> (u64, f64, Vec<f64>, Vec<f64>) {
        let s = sim.state();
        (s.step, s.t, s.q.clone(), s.p.clone())
    }

    fn velocity(sim: &Self::Sim) -> Result<Vec<f64>, Error> {
        sim.velocity()
    }

    fn stats(sim: &Self::Sim) -> Stats {
        *sim.stats()
    }

    fn step_toward(sim: &mut Self::Sim, t_end: f64, _last_h: Option<f64>) -> Result<(), Error> {
        if sim.lands(t_end) { sim.run_until(t_end, |_| {}) } else { sim.step().map(|_| ()) }
    }

    fn land(sim: &mut Self::Sim, t: f64) -> Result<(), Error> {
        sim.run_until(t, |_| {})
    }

    /// A Galerkin rule's step polynomial (the step just taken, `start →
    /// end`), the cubic Hermite of the nodes for the other methods.
    fn native(sim: &Self::Sim, start: &Point<Vec<f64>>, end: &Point<Vec<f64>>) -> RunTimeStep {
        match sim.galerkin_nodes() {
            Some((h, d, tau)) => RunTimeStep::Polynomial(StepPolynomial {
                t0: start.t,
                h,
                tau: tau.to_vec(),
                q0: start.q.clone(),
                d: d.to_vec(),
            }),
            None => RunTimeStep::Hermite(HermiteRows::new(start, end, None)),
        }
    }

    fn hermite(start: &Point<Vec<f64>>, end: &Point<Vec<f64>>, a: Option<(&Vec<f64>, &Vec<f64>)>) -> HermiteRows {
        HermiteRows::new(start, end, a)
    }

    fn energy(sim: &Self::Sim, t: f64, q: &Vec<f64>, v: &Vec<f64>) -> f64 {
        sim.energy_at(t, q, v)
    }

    fn momentum(sim: &Self::Sim, t: f64, q: &Vec<f64>, v: &Vec<f64>) -> Vec<f64> {
        sim.momentum_at(t, q, v)
    }

    fn acceleration(_sim: &Self::Sim, _t: f64, _q: &Vec<f64>, _v: &Vec<f64>) -> Option<Vec<f64>> {
        None
    }
}

impl<S: DynLagrangian + Clone, M: DynMethod + Clone> DynIntegrator<S, M> {
    /// Integrates as `plan` says and returns the [`Solution`], as
    /// [`Stepping::solve`] does for a const-size integrator: the same
    /// driver, rows, events and failures. Dense output (save times, events)
    /// is a Galerkin rule's step polynomial, and the cubic Hermite of the
    /// nodes for the one-point rules and compositions (each method's own at a
    /// compile-time size too);
    /// [`DenseKind::Quintic`](crate::DenseKind::Quintic) is refused
    /// ([`SolveError::InvalidPlan`]): no acceleration is computed at a
    /// run-time size.
    ///
    /// ```
    /// use lagrangian_runtime::{DynIntegrator, DynLagrangian, Event, Midpoint, Plan, Scalar};
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
    /// let mut sim = DynIntegrator::new(Oscillators { n: 3 }, Midpoint, 0.01).start(0.0, &[1.0; 3], &[0.0; 3])?;
    /// let plan = Plan::until(2.0).every(10).save_at(vec![0.125]).event(Event::new(|_t, q, _v| q[0]));
    /// let solution = sim.solve(plan)?.into_result()?;
    /// assert_eq!(solution.width(), 3);
    /// // Nodes 0 and 10, then the save time, interpolated.
    /// assert_eq!((solution.t[2], solution.step[2]), (0.125, None));
    /// assert!((solution.q[2][2] - 0.125f64.cos()).abs() < 1e-4);
    /// // cos t crosses zero at π/2.
    /// assert!((solution.events[0].t - std::f64::consts::FRAC_PI_2).abs() < 1e-4);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn solve(&mut self, plan: Plan<'_>) -> Result<Solution, SolveError> {
        solve::<RunTimeSize<S, M>>(self, plan)
    }
}
