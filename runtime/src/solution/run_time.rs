//! The run-time-sized counterpart of [`Stepping`](super::Stepping): what
//! [`solve`](super::solve) and the landing loop need from a driver whose
//! state is on the heap, written once for all of them.

use super::{Plan, Solution, Solvable, SolveError, solve};
use crate::dense::{HermiteRows, Point, RunTimeStep, StepPolynomial};
use crate::error::Error;
use crate::integrator::{Sliced, Stats, tape_energy, tape_momentum};
use crate::state::PhasePoint;
use crate::system::DynLagrangian;

/// A driver of a run-time-sized system ([`DynLagrangian`]): one step, one
/// step toward a target, the state, velocity and energies at the node, and
/// the work counters. [`run`](Self::run), [`run_until`](Self::run_until)
/// (the landing loop) and [`solve`](Self::solve) are written once, here.
///
/// [`Stepper<S, Dyn>`](crate::Stepper) implements it by dispatching to
/// the driver of its [`Scheme`](crate::Scheme), as `Stepper<S, Dim<N>>`
/// implements [`Stepping<N>`](super::Stepping); it also has every method as
/// an inherent one, so that the trait need not be in scope.
///
/// `state()` has one meaning for every driver: the node `(k, t_k, q_k,
/// p_k)` in physical time with the physical momenta; `k` counts steps (in
/// `s` for the time-transformed schemes).
pub trait RunTimeStepping {
    /// The integrated system.
    type System: DynLagrangian;

    /// The system.
    fn system(&self) -> &Self::System;

    /// The state `(k, t_k, q_k, p_k)` at the current node.
    fn state(&self) -> &PhasePoint;

    /// The velocity whose momentum is the current `p_k`.
    fn velocity(&self) -> Result<Vec<f64>, Error>;

    /// The energy at the current node: `E_L(t_k, q_k, v_k)` with `v_k` the
    /// velocity of `p_k`.
    fn energy(&self) -> Result<f64, Error>;

    /// The energy the method's steps conserve: the discrete energy
    /// `E_k = −∂A(x_{k−1}, x_k)/∂t_k` of the last step (at `k = 0`, the
    /// energy of the initial data); under a time transformation `−p_t`, the
    /// momentum of time.
    fn discrete_energy(&self) -> f64;

    /// Work counters.
    fn stats(&self) -> Stats;

    /// One step of the driver's own size (in `s` for the time-transformed
    /// schemes; under energy-preserving steps, of the size the energy
    /// equation picks). On failure nothing changes.
    fn step(&mut self) -> Result<(), Error>;

    /// One step toward `t_end`: the driver's own step, or, when that step
    /// would reach `t_end` or pass it, the step that ends on `t_end`
    /// exactly; a no-op at or beyond `t_end`. On failure nothing changes.
    fn step_toward(&mut self, t_end: f64) -> Result<(), Error>;

    /// The size of the step the driver takes next: `h` in `t`, or `σ` in
    /// `s` for the time-transformed schemes (under energy-preserving steps,
    /// the guess of the next one).
    fn step_size(&self) -> f64;

    /// The physical time the last step advanced; `None` before the first.
    fn last_step_size(&self) -> Option<f64>;

    /// Changes the size of the following steps ([`step_size`](Self::step_size)'s
    /// meaning), for example to retry a failed step with a smaller one;
    /// [`Error::InvalidStepSize`] (or [`Error::InvalidSetting`] for a step
    /// in `s`) for a step that is not finite and positive, or outside the
    /// bounds of energy-preserving steps, and nothing changes.
    fn set_step_size(&mut self, h: f64) -> Result<(), Error>;

    /// The last step's polynomial where the method has one (a Galerkin
    /// rule): its length `h`, the differences `D_m = Q_m − q_0` of its
    /// control nodes (coordinate `i`'s at `i·s + m − 1`) and the node times
    /// `τ_0 = 0, …, τ_s` in units of `h`. `None`: dense output is the cubic
    /// Hermite of the nodes.
    fn step_polynomial(&self) -> Option<(f64, &[f64], &[f64])> {
        None
    }

    /// `n` steps, calling `observe` after each; stops at the first failure,
    /// at the last good node.
    fn run(&mut self, n: usize, mut observe: impl FnMut(&Self)) -> Result<(), Error>
    where
        Self: Sized,
    {
        for _ in 0..n {
            self.step()?;
            observe(self);
        }
        Ok(())
    }

    /// Steps to `t_end` exactly: the step that would reach or pass it is
    /// replaced by the one that ends on it (a shortened step in `t`, or the
    /// partial step in `s` solved for under a time transformation), and
    /// the state then reports `t = t_end` exactly. A target equal to the
    /// current time is a no-op; one before it, or not finite, is
    /// [`Error::InvalidTarget`].
    fn run_until(&mut self, t_end: f64) -> Result<(), Error> {
        if !t_end.is_finite() || t_end < self.state().t {
            return Err(Error::InvalidTarget { target: t_end, state: self.state().clone() });
        }
        while self.state().t < t_end {
            self.step_toward(t_end)?;
        }
        Ok(())
    }

    /// Integrates as `plan` says: the same [`Solution`] and [`SolveError`]
    /// as [`Stepping::solve`](super::Stepping::solve) at a compile-time
    /// size. Dense output (save times, events) is a Galerkin rule's step
    /// polynomial, and the cubic Hermite of the nodes for the other methods
    /// (their own at a compile-time size too);
    /// [`DenseKind::Quintic`](crate::DenseKind::Quintic) is refused
    /// ([`SolveError::InvalidPlan`]): no acceleration is computed at a
    /// run-time size. The driver is left at the last node of the solution.
    ///
    /// ```
    /// use lagrangian_runtime::problem::{Problem, Scheme};
    /// use lagrangian_runtime::{DynLagrangian, Event, Plan, Scalar};
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
    fn solve(&mut self, plan: Plan<'_>) -> Result<Solution, SolveError>
    where
        Self: Sized + Clone,
    {
        solve::<RunTimeSize<Self>>(self, plan)
    }
}

/// [`Solvable`] for every [`RunTimeStepping`] driver: nodes as `Vec<f64>`,
/// momenta and energies between nodes by reverse sweeps of the physical
/// system's `L` (the same at every rule: they read `L` at a point), no
/// acceleration.
pub(crate) struct RunTimeSize<D>(core::marker::PhantomData<D>);

/// The physical system as the reverse sweeps read it (`L` at a point: the
/// rule's quadrature points are not used).
fn model<S: DynLagrangian>(system: &S) -> Sliced<'_, S> {
    Sliced::new(system, [0.5, 0.5])
}

impl<D: RunTimeStepping + Clone> Solvable for RunTimeSize<D> {
    type Sim = D;
    type Vector = Vec<f64>;
    type Native = RunTimeStep;
    type Hermite = HermiteRows;
    const ACCELERATION: bool = false;

    fn width(sim: &D) -> usize {
        sim.state().q.len()
    }

    fn time(sim: &D) -> f64 {
        sim.state().t
    }

    fn node(sim: &D) -> (u64, f64, Vec<f64>, Vec<f64>) {
        let s = sim.state();
        (s.step, s.t, s.q.clone(), s.p.clone())
    }

    fn velocity(sim: &D) -> Result<Vec<f64>, Error> {
        sim.velocity()
    }

    fn stats(sim: &D) -> Stats {
        sim.stats()
    }

    fn step_toward(sim: &mut D, t_end: f64, _last_h: Option<f64>) -> Result<(), Error> {
        sim.step_toward(t_end)
    }

    fn land(sim: &mut D, t: f64) -> Result<(), Error> {
        sim.run_until(t)
    }

    /// A Galerkin rule's step polynomial (the step just taken, `start →
    /// end`), the cubic Hermite of the nodes for the other methods.
    fn native(sim: &D, start: &Point<Vec<f64>>, end: &Point<Vec<f64>>) -> RunTimeStep {
        match sim.step_polynomial() {
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

    fn energy(sim: &D, t: f64, q: &Vec<f64>, v: &Vec<f64>) -> f64 {
        tape_energy(&model(sim.system()), t, q, v)
    }

    fn momentum(sim: &D, t: f64, q: &Vec<f64>, v: &Vec<f64>) -> Vec<f64> {
        let mut p = vec![0.0; q.len()];
        if tape_momentum(&model(sim.system()), t, q, v, &mut p).is_none() {
            p.fill(f64::NAN);
        }
        p
    }

    fn acceleration(_sim: &D, _t: f64, _q: &Vec<f64>, _v: &Vec<f64>) -> Option<Vec<f64>> {
        None
    }
}
