//! Energy-preserving steps of the Galerkin rules on run-time-sized
//! systems (docs/theory.md §3, §9): each step size solves the discrete
//! energy equation `E(D(h), h) = E_k` together with the `sN` node
//! equations, as `galerkin/energy.rs` does at a compile-time size.
//!
//! The search over `h` is the one of the one-point rules (`energy.rs`:
//! Newton on `g(h)` from the extrapolated step, then
//! [`EnergySearch::bracketed`](crate::integrator::EnergySearch)); the rule
//! supplies the probe: the node equations solved at a trial `h` by the
//! step's banded (or dense) Newton iteration, then `g(h) = E − E_k` and
//! `g'(h)` from one more reverse sweep with the seed on `h` and one solve
//! with the Newton block's factors (`tape_step/galerkin_energy.rs`), `O(N)`
//! per probe for a banded `L`. The step taken is the chosen probe's: its
//! nodes, their momentum and energy from one reverse sweep.
//!
//! Autonomous systems without forces, as at a compile-time size (`start`
//! refuses the rest).

use super::energy::Latest;
use super::{DynIntegrator, DynMethod, Sliced, node_at};
use crate::error::{Error, Unplaced};
use crate::integrator::tape_step::EnergyTerms;
use crate::integrator::{Clock, Probe, Taken};
use crate::newton::NewtonReport;
use crate::system::DynLagrangian;

/// The error of an energy step whose driver lost its Galerkin work or its
/// energy steps' state (a broken invariant, never a user's input).
const INTERNAL: Error = Error::Unsupported { what: "Galerkin energy steps without their state (internal error)" };

impl<S: DynLagrangian, M: DynMethod> DynIntegrator<S, M> {
    /// `g(h)` and `g'(h)` with the node equations solved at step `h`.
    pub(super) fn node_probe(&mut self, h: f64, spent: &mut usize) -> Result<Probe<(f64, u64)>, Unplaced> {
        let model = Sliced { system: &self.system, points: self.points };
        let node = node_at(&self.state, (&self.carry, &self.p_carry), self.summation);
        let (Some(galerkin), Some(steps)) = (self.galerkin.as_deref_mut(), self.variable.as_deref_mut()) else {
            return Err(Unplaced::new(|_| INTERNAL));
        };
        let probed = galerkin.energy_probe(&model, &node, h, (&self.v0, steps.warm), &self.newton);
        let (report, terms) = probed.map_err(|failure| Unplaced::newton(failure, h))?;
        *spent += report.iterations;
        let target = steps.energy + steps.behind;
        let g = terms.energy - target;
        steps.serial += 1;
        let energy = EnergyTerms { d_t0: terms.energy, time_shift: 0.0, slope: terms.slope, work: 0.0 };
        let latest = Latest { serial: steps.serial, h, dq: Vec::new(), terms: energy };
        if let Some(old) = steps.latest.replace(latest) {
            self.work.recycle(old.dq);
        }
        if !g.is_finite() {
            let iterations = *spent;
            return Err(Unplaced::new(|state| Error::NonFinite { state, h, iterations, quantity: "energy equation" }));
        }
        Ok(Probe { trial: (h, steps.serial), h, g, slope: terms.slope, scale: target.abs().max(terms.scale) })
    }

    /// Takes the chosen trial step: the nodes of its probe (solved again
    /// at its size where a later probe replaced them, to the same bits),
    /// their momentum and energy, and the Kahan-summed time.
    pub(super) fn accept_nodes(
        &mut self,
        (h, serial): (f64, u64),
        report: NewtonReport,
        taken: Taken,
    ) -> Result<(), Error> {
        let latest = self.variable.as_deref_mut().and_then(|steps| steps.latest.take());
        let fresh = latest.as_ref().is_some_and(|latest| latest.serial == serial);
        if let Some(latest) = latest {
            self.work.recycle(latest.dq);
        }
        if !fresh {
            let mut spent = 0;
            if let Err(failure) = self.node_probe(h, &mut spent) {
                self.stats.failed_steps += 1;
                return Err(self.place_probe(failure));
            }
            if let Some(latest) = self.variable.as_deref_mut().and_then(|steps| steps.latest.take()) {
                self.work.recycle(latest.dq);
            }
        }
        let (Some(galerkin), Some(steps)) = (self.galerkin.as_deref_mut(), self.variable.as_deref_mut()) else {
            return Err(INTERNAL);
        };
        let t0 = self.state.t;
        let y = h - steps.time_error;
        let t1 = t0 + y;
        let model = Sliced { system: &self.system, points: self.points };
        let node = node_at(&self.state, (&self.carry, &self.p_carry), self.summation);
        let outcome = galerkin.take_probe(&model, &node, (h, t1), report, &mut self.work);
        let (step, e1) = match outcome {
            Some(Ok(x)) => x,
            Some(Err(failure)) => {
                self.stats.failed_steps += 1;
                return Err(Error::from_newton(failure, self.state.clone(), h));
            }
            None => return Err(INTERNAL),
        };
        steps.time_error = (t1 - t0) - y;
        if taken != Taken::Root {
            // A least-mismatch step changed the energy: conserve its new value.
            (steps.energy, steps.energy_carry) = (e1, 0.0);
        }
        self.commit(step, h, t1);
        self.work.energy = Some(e1);
        self.h = h;
        self.clock = Clock { t: t1, step: self.state.step };
        match taken {
            Taken::Root => {}
            Taken::LeastSquares => self.stats.energy_fallbacks += 1,
            Taken::Capped(defect) => {
                self.stats.accuracy_capped_steps += 1;
                self.stats.largest_capped_energy_defect = self.stats.largest_capped_energy_defect.max(defect);
            }
        }
        Ok(())
    }

    /// A probe's failure at the state the step started from.
    fn place_probe(&self, failure: Unplaced) -> Error {
        failure.at(self.state.clone())
    }
}
