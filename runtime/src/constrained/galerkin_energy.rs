//! Energy-preserving variable steps of the constrained Galerkin rules:
//! autonomous, unforced systems with constraints `g(q)`, as for the
//! unconstrained Galerkin rules (`galerkin/energy.rs`).
//!
//! ```text
//! unknowns (D_1 … D_s, Λ, λ_k, h):   the constrained node equations at step size h,
//!                                    E(D, h) − E_k = 0,   E = −∂A/∂h = Σ_j b_j E_L(q_h(c_j), q̇_h(c_j))
//! ```
//!
//! The constraints do not depend on time, so the time component of the
//! constrained variational principle carries no multiplier: the energy
//! equation is the unconstrained rule's. At each trial `h` the constrained
//! step is solved as for a fixed step (`galerkin.rs`), and the step size
//! is found by the search of the one-point rules ([`EnergySearch`]). The
//! probes carry no slope: the search takes the secant through its
//! bracket. The first step has the given size, whose discrete energy is
//! the one conserved.

use super::Constrained;
use super::galerkin::{Segment, Solved, commit, predict, solve_step, step_energy};
use crate::error::{Error, Unplaced};
use crate::galerkin::{Galerkin, point_gradient};
use crate::integrator::{Clock, EnergyFallback, EnergySearch, Integrator, Method, Probe, StepBounds, Taken};
use crate::state::State;
use crate::system::Lagrangian;

impl<Sys, const N: usize, const S: usize, const R: usize, const M: usize>
    Integrator<Sys, Constrained<Galerkin<S, R>, M>, N>
where
    Sys: Lagrangian<N>,
{
    /// One energy-preserving step (the first has the given size); on
    /// failure nothing in the integrator has changed but the saddle-point
    /// storage.
    pub(super) fn constrained_node_energy_step(&mut self, bounds: StepBounds) -> Result<(), Error> {
        // `start` refuses these (`supports`); no energy-step code for them.
        if const { Sys::HAS_FORCE || Sys::HAS_DISSIPATION || !Sys::AUTONOMOUS || !Sys::CONSTRAINTS_AUTONOMOUS } {
            return Err(Error::Unsupported { what: "energy-preserving galerkin steps for this system" });
        }
        let Some(last) = self.memory.last else {
            let (h, t1) = (self.h, self.state.t + self.h);
            <Constrained<Galerkin<S, R>, M> as Method<f64>>::fixed_step(self, h, t1)?;
            self.reread_constrained_node_energy();
            return Ok(());
        };
        let (lo, hi) = bounds.bracket(last.h);
        let guess = self.h.clamp(lo, hi);
        match self.bracketed(guess, lo, hi, false, 0) {
            Ok(((h, mut solved), report, taken)) => {
                let t0 = self.state.t;
                let y = h - self.time_error;
                let t1 = t0 + y;
                solved.iterations = report.iterations;
                commit(self, h, t1, &solved);
                self.time_error = (t1 - t0) - y;
                if taken != Taken::Root {
                    // A least-mismatch step changed the energy: conserve its new value.
                    self.reread_constrained_node_energy();
                    self.stats.energy_fallbacks += 1;
                }
                self.stats.last = report;
                self.h = h;
                self.clock = Clock { t: self.state.t, step: self.state.step };
                Ok(())
            }
            Err(error) => {
                self.stats.failed_steps += 1;
                Err(error)
            }
        }
    }

    /// Sets the energy target to the discrete energy of the last step.
    pub(super) fn reread_constrained_node_energy(&mut self) {
        self.energy_carry = 0.0;
        if let Some(last) = &self.memory.last {
            self.energy = step_energy(&self.system, &self.method.rule, last);
        }
    }
}

impl<Sys, const N: usize, const S: usize, const R: usize, const M: usize> EnergySearch
    for Integrator<Sys, Constrained<Galerkin<S, R>, M>, N>
where
    Sys: Lagrangian<N>,
{
    /// The step size and the solved step.
    type Trial = (f64, Solved<N, S, M>);

    fn probe(&mut self, h: f64, spent: &mut usize) -> Result<Probe<Self::Trial>, Unplaced> {
        let state = self.state;
        let State { t: t0, q: q0, p: p0, .. } = state;
        let rule = &self.method.rule;
        let v = if self.memory.last.is_some() { self.memory.velocity } else { self.v0 };
        let guess = predict(rule, h, &self.memory, &v);
        let times = (t0, h, t0 + h);
        let solved = solve_step(&self.system, rule, &self.newton, times, (&q0, &p0), guess, &mut self.memory.work)?;
        *spent += solved.iterations;
        let seg = Segment { t0, h, q0, d: solved.d };
        let energy = step_energy(&self.system, rule, &seg);
        let g = energy - self.energy;
        if !g.is_finite() {
            let iterations = *spent;
            return Err(Unplaced::new(|state| Error::NonFinite { state, h, iterations, quantity: "energy equation" }));
        }
        // The size of the terms whose sum is E: `v·∂L/∂v` and `L` at the
        // quadrature points, with their weights.
        let mut scale = self.energy.abs();
        for j in 0..R {
            let (t, q, v) = rule.point(t0, h, (&q0, &[0.0; N]), &solved.d, j);
            let (l, _, lv) = point_gradient(&self.system, t, q, v);
            let vlv = (0..N).map(|i| v[i] * lv[i]).sum::<f64>();
            scale = scale.max(rule.quadrature().weights()[j].abs() * (vlv.abs() + l.abs()));
        }
        Ok(Probe { trial: (h, solved), h, g, slope: f64::NAN, scale })
    }

    fn place(&self, failure: Unplaced) -> Error {
        failure.at(self.state)
    }

    fn fallback(&self) -> EnergyFallback {
        self.fallback
    }

    fn no_energy_step(&self, lo: f64, hi: f64, best: &Probe<Self::Trial>, spent: usize) -> Error {
        best.no_energy_step(self.state, (lo, hi), spent, None)
    }
}
