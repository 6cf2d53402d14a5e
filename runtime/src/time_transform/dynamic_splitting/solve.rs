//! `solve(Plan)` on the run-time-sized explicit splitting: the size-free
//! [`Solvable`] of `solution.rs`, so that thinning, save times, events and
//! the [`Solution`] are those of every other driver.

use super::RunTimeSplitting;
use crate::dense::{HermiteRows, Point};
use crate::error::Error;
use crate::integrator::{Sliced, Stats, tape_energy, tape_momentum};
use crate::solution::{Plan, Solution, Solvable, SolveError, solve};
use crate::system::DynLagrangian;

/// [`Solvable`] for [`RunTimeSplitting`]: nodes in physical time as
/// `Vec<f64>`, dense output by the cubic Hermite of the nodes (the
/// compile-time splitting's own too), no acceleration (quintic dense output
/// is refused before the run).
pub(crate) struct Splitting<S>(core::marker::PhantomData<S>);

impl<S: DynLagrangian + Clone> Solvable for Splitting<S> {
    type Sim = RunTimeSplitting<S>;
    type Vector = Vec<f64>;
    type Native = HermiteRows;
    type Hermite = HermiteRows;
    const ACCELERATION: bool = false;

    fn width(sim: &Self::Sim) -> usize {
        sim.state().q.len()
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
        sim.step_toward(t_end)
    }

    fn land(sim: &mut Self::Sim, t: f64) -> Result<(), Error> {
        sim.run_until(t, |_| {})
    }

    /// The cubic Hermite through both nodes in physical time.
    fn native(_sim: &Self::Sim, start: &Point<Vec<f64>>, end: &Point<Vec<f64>>) -> HermiteRows {
        HermiteRows::new(start, end, None)
    }

    fn hermite(start: &Point<Vec<f64>>, end: &Point<Vec<f64>>, a: Option<(&Vec<f64>, &Vec<f64>)>) -> HermiteRows {
        HermiteRows::new(start, end, a)
    }

    fn energy(sim: &Self::Sim, t: f64, q: &Vec<f64>, v: &Vec<f64>) -> f64 {
        tape_energy(&Sliced::new(sim.system(), [0.5, 0.5]), t, q, v)
    }

    fn momentum(sim: &Self::Sim, t: f64, q: &Vec<f64>, v: &Vec<f64>) -> Vec<f64> {
        let mut p = vec![0.0; q.len()];
        if tape_momentum(&Sliced::new(sim.system(), [0.5, 0.5]), t, q, v, &mut p).is_none() {
            p.fill(f64::NAN);
        }
        p
    }

    fn acceleration(_sim: &Self::Sim, _t: f64, _q: &Vec<f64>, _v: &Vec<f64>) -> Option<Vec<f64>> {
        None
    }
}

impl<S: DynLagrangian + Clone> RunTimeSplitting<S> {
    /// Integrates as `plan` says: the same [`Solution`] and
    /// [`SolveError`] as every driver, its nodes the steps in `s` in
    /// physical time, save times and events by the cubic Hermite of the
    /// nodes; [`DenseKind::Quintic`](crate::DenseKind::Quintic) is refused
    /// ([`SolveError::InvalidPlan`]). The stepper is left at the last node
    /// of the solution.
    pub fn solve(&mut self, plan: Plan<'_>) -> Result<Solution, SolveError> {
        solve::<Splitting<S>>(self, plan)
    }
}
