//! [`RunTimeStepping`] for the run-time-sized explicit splitting, so that
//! landing, thinning, save times, events and the
//! [`Solution`](crate::Solution) are those of every other driver.

use super::RunTimeSplitting;
use crate::error::Error;
use crate::integrator::Stats;
use crate::solution::RunTimeStepping;
use crate::state::PhasePoint;
use crate::system::DynLagrangian;

/// Steps of `σ` in `s` read in physical time; landing by the partial step
/// in `s` that ends on the target; dense output by the cubic Hermite of the
/// nodes (the compile-time splitting's own too).
impl<S: DynLagrangian + Clone> RunTimeStepping for RunTimeSplitting<S> {
    type System = S;

    fn system(&self) -> &S {
        RunTimeSplitting::system(self)
    }

    fn state(&self) -> &PhasePoint {
        RunTimeSplitting::state(self)
    }

    fn velocity(&self) -> Result<Vec<f64>, Error> {
        RunTimeSplitting::velocity(self)
    }

    fn energy(&self) -> Result<f64, Error> {
        RunTimeSplitting::energy(self)
    }

    fn discrete_energy(&self) -> f64 {
        RunTimeSplitting::discrete_energy(self)
    }

    /// Steps in `s` (the gradient evaluations and landing trials are in
    /// [`splitting_stats`](RunTimeSplitting::splitting_stats)).
    fn stats(&self) -> Stats {
        *RunTimeSplitting::stats(self)
    }

    fn step(&mut self) -> Result<(), Error> {
        RunTimeSplitting::step(self).map(|_| ())
    }

    fn step_toward(&mut self, t_end: f64) -> Result<(), Error> {
        RunTimeSplitting::step_toward(self, t_end)
    }

    /// `σ`, the step in `s`.
    fn step_size(&self) -> f64 {
        self.sigma
    }

    fn last_step_size(&self) -> Option<f64> {
        self.last_dt
    }

    /// A new `σ`; the floor on the time step stays that of the start.
    fn set_step_size(&mut self, sigma: f64) -> Result<(), Error> {
        if !(sigma.is_finite() && sigma > 0.0) {
            return Err(Error::InvalidSetting { reason: "the step in `s` must be finite and positive" });
        }
        self.sigma = sigma;
        Ok(())
    }
}
