//! A symmetric composition of any symmetric base method, written once over
//! the drivers at a compile-time size.
//!
//! ```text
//! Φ_h = Ψ_{γ_m h} ∘ … ∘ Ψ_{γ_1 h},   Ψ = a step of the base driver,   Σ γ_i = 1,   γ_i = γ_{m+1−i}
//! ```
//!
//! [`Composed`] steps its base driver (midpoint, α-β at `α = ½`, a
//! Galerkin rule) by sub-steps of sizes `γ_i h`, each the base's own step
//! of that size: a composition of variational steps is variational, and
//! with the weights of a symmetric base of order 2 it raises a symmetric
//! base to `max(p, q)`. The base's predictor extrapolates its last step in
//! physical time, whatever the sign and size of that step (the one-point
//! rules' secant velocities, a Galerkin rule's step polynomial), so the
//! sub-steps of other sizes start from a guess of the same order as a run
//! of equal steps. The trapezoid compositions are not made here: they are
//! the fused const-generic [`Composition`] method, whose explicit
//! Störmer–Verlet sub-steps on a separable system run without Newton.
//!
//! The node `k` of the composition is the base's node after `k·m`
//! sub-steps, its state, momenta and energy the base's there; a failed
//! sub-step restores the base from its copy before the step, so the
//! stepper is as it was. Dense output is the cubic Hermite through the
//! nodes of the whole step.

use crate::dense::{Hermite, Node};
use crate::error::Error;
use crate::integrator::{Clock, Composition, Stats};
use crate::solution::Stepping;
use crate::state::State;
use crate::system::Lagrangian;

/// What a composition asks of its base driver: a step of any size (negative
/// for some sub-steps) ending on a given time, and the readouts of its node.
/// The stepper's driver implements it, so this file names no driver.
pub trait SubSteps<const N: usize>: Clone {
    /// The integrated system.
    type System: Lagrangian<N>;
    /// One step of size `h` ending at `t1`; on failure the driver is
    /// unchanged.
    fn sub_step(&mut self, h: f64, t1: f64) -> Result<(), Error>;
    /// The system.
    fn system(&self) -> &Self::System;
    /// The node.
    fn state(&self) -> State<N>;
    /// The velocity at the node.
    fn velocity(&self) -> Result<[f64; N], Error>;
    /// The counters.
    fn stats(&self) -> Stats;
}

/// A symmetric composition of steps of a base driver `B` with fixed step `h`.
pub struct Composed<B, const N: usize> {
    /// The base driver, stepped by sub-steps of sizes `γ_i h`.
    base: B,
    /// The base as it was before the step in progress: a failed sub-step
    /// puts it back (copied in place, no allocation).
    before: B,
    weights: Composition,
    h: f64,
    /// `t_k = clock.t + (k − clock.step) h`, reset after a landing.
    clock: Clock<f64>,
    /// Composed steps taken: the node index `k`.
    steps: u64,
    /// Composed steps that failed.
    failed_steps: u64,
}

impl<B: Clone, const N: usize> Clone for Composed<B, N> {
    fn clone(&self) -> Self {
        Self {
            base: self.base.clone(),
            before: self.before.clone(),
            weights: self.weights,
            h: self.h,
            clock: self.clock,
            steps: self.steps,
            failed_steps: self.failed_steps,
        }
    }

    /// The drivers in place (`solve` copies the stepper before every step).
    fn clone_from(&mut self, source: &Self) {
        self.base.clone_from(&source.base);
        self.before.clone_from(&source.before);
        (self.weights, self.h, self.clock) = (source.weights, source.h, source.clock);
        (self.steps, self.failed_steps) = (source.steps, source.failed_steps);
    }
}

impl<B: SubSteps<N>, const N: usize> Composed<B, N> {
    /// The composition with `weights` of `base`, a driver that has not
    /// stepped, with fixed step `h`.
    pub(super) fn new(base: B, weights: Composition, h: f64) -> Self {
        let t = base.state().t;
        Self { before: base.clone(), base, weights, h, clock: Clock { t, step: 0 }, steps: 0, failed_steps: 0 }
    }

    /// One composed step of size `h` ending at `t1`; on failure the base is
    /// restored and the error carries the state of the composed node.
    fn step_by(&mut self, h: f64, t1: f64) -> Result<(), Error> {
        self.before.clone_from(&self.base);
        let t0 = self.base.state().t;
        let weights = self.weights.weights();
        let mut elapsed = 0.0;
        for (i, gamma) in weights.iter().enumerate() {
            elapsed += gamma;
            // The sub-node times as the fused compositions stamp them; the
            // last is the node's own.
            let ti = if i + 1 == weights.len() { t1 } else { t0 + elapsed * h };
            if let Err(e) = self.base.sub_step(gamma * h, ti) {
                core::mem::swap(&mut self.base, &mut self.before);
                self.failed_steps += 1;
                return Err(e.at_state(Stepping::state(self)));
            }
        }
        self.steps += 1;
        Ok(())
    }

    /// Whether a step from `t` ends within `10⁻⁹ h` of `t_end` or beyond it:
    /// the landing rule of the integrators' `run_until`.
    fn reaches(&self, t_end: f64) -> bool {
        let t = Stepping::state(self).t;
        t + self.h >= t_end - 1e-9 * self.h
    }

    /// The step that ends on `t_end` exactly, with the clock restarted there.
    fn land_step(&mut self, t_end: f64) -> Result<(), Error> {
        let t = Stepping::state(self).t;
        self.step_by(t_end - t, t_end)?;
        self.clock = Clock { t: t_end, step: self.steps };
        Ok(())
    }
}

impl<B: SubSteps<N>, const N: usize> Stepping<N> for Composed<B, N> {
    type System = B::System;
    type Native = Hermite<N>;

    fn system(&self) -> &B::System {
        self.base.system()
    }

    /// The base's node, counted in composed steps.
    fn state(&self) -> State<N> {
        State { step: self.steps, ..self.base.state() }
    }

    fn velocity(&self) -> Result<[f64; N], Error> {
        self.base.velocity()
    }

    /// Composed steps; the Newton iterations of every sub-step.
    fn stats(&self) -> Stats {
        Stats { steps: self.steps, failed_steps: self.failed_steps, ..self.base.stats() }
    }

    fn step(&mut self) -> Result<(), Error> {
        let t1 = self.clock.at(self.steps + 1, self.h);
        self.step_by(self.h, t1)
    }

    fn step_toward(&mut self, t_end: f64, _last_h: Option<f64>) -> Result<(), Error> {
        if self.reaches(t_end) { Stepping::land(self, t_end) } else { Stepping::step(self) }
    }

    fn land(&mut self, t: f64) -> Result<(), Error> {
        let now = Stepping::state(self);
        if !t.is_finite() || t < now.t {
            return Err(Error::InvalidTarget { target: t, state: now.into() });
        }
        while Stepping::state(self).t < t {
            if self.reaches(t) {
                return self.land_step(t);
            }
            Stepping::step(self)?;
        }
        Ok(())
    }

    /// The cubic Hermite through both nodes of the whole step.
    fn native(&self, start: &Node<N>, end: &Node<N>) -> Hermite<N> {
        Hermite::cubic(start, end)
    }
}
