//! A symmetric composition of any symmetric base method, written once over
//! the drivers at both sizes.
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
//! the fused [`Composition`] method, whose explicit Störmer–Verlet
//! sub-steps on a separable system run without Newton.
//!
//! The node `k` of the composition is the base's node after `k·m`
//! sub-steps, its state, momenta and energy the base's there; a failed
//! sub-step restores the base from its copy before the step, so the
//! stepper is as it was. Dense output is the cubic Hermite through the
//! nodes of the whole step. The same adapter serves a compile-time size
//! ([`Stepping`], over the const-generic drivers) and a run-time size
//! ([`RunTimeStepping`], over the reverse-mode drivers); only the readouts
//! of the node differ.

use crate::dense::{Hermite, Node};
use crate::error::Error;
use crate::integrator::{Clock, Composition, Stats, fixed_step_lands};
use crate::solution::{RunTimeStepping, Stepping};
use crate::state::{PhasePoint, State};
use crate::system::Lagrangian;

/// What a composition asks of its base driver at either size: a step of any
/// size (negative for some sub-steps) ending on a given time. The steppers'
/// drivers implement it, so this file names no driver.
pub trait SubSteps: Clone {
    /// One step of size `h` ending at `t1`; on failure the driver is
    /// unchanged.
    fn sub_step(&mut self, h: f64, t1: f64) -> Result<(), Error>;
    /// The time of the node.
    fn time(&self) -> f64;
    /// Numbers the node `k`: a composition counts its nodes, not its
    /// sub-steps. A driver that hands out its node by reference (a run-time
    /// size) stamps it; one that hands it out by value leaves the number to
    /// the composition.
    fn number(&mut self, _k: u64) {}
}

/// The readouts of a base driver's node at a compile-time size.
pub trait ConstSubSteps<const N: usize>: SubSteps {
    /// The integrated system.
    type System: Lagrangian<N>;
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
pub struct Composed<B> {
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
    /// The size of the last composed step; `None` before the first.
    last_h: Option<f64>,
}

impl<B: Clone> Clone for Composed<B> {
    fn clone(&self) -> Self {
        Self {
            base: self.base.clone(),
            before: self.before.clone(),
            weights: self.weights,
            h: self.h,
            clock: self.clock,
            steps: self.steps,
            failed_steps: self.failed_steps,
            last_h: self.last_h,
        }
    }

    /// The drivers in place (`solve` copies the stepper before every step).
    fn clone_from(&mut self, source: &Self) {
        self.base.clone_from(&source.base);
        self.before.clone_from(&source.before);
        (self.weights, self.h, self.clock) = (source.weights, source.h, source.clock);
        (self.steps, self.failed_steps, self.last_h) = (source.steps, source.failed_steps, source.last_h);
    }
}

impl<B: core::fmt::Debug> core::fmt::Debug for Composed<B> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Composed")
            .field("weights", &self.weights)
            .field("h", &self.h)
            .field("steps", &self.steps)
            .field("base", &self.base)
            .finish()
    }
}

/// The composition itself, the same at both sizes; its errors carry the
/// sub-node's state until the size's readouts put the composed node's in.
impl<B: SubSteps> Composed<B> {
    /// The composition with `weights` of `base`, a driver that has not
    /// stepped, with fixed step `h`.
    pub(super) fn new(base: B, weights: Composition, h: f64) -> Self {
        let t = base.time();
        let (steps, failed_steps, last_h) = (0, 0, None);
        Self { before: base.clone(), base, weights, h, clock: Clock { t, step: 0 }, steps, failed_steps, last_h }
    }

    /// One composed step of size `h` ending at `t1`; on failure the base is
    /// restored.
    fn step_by(&mut self, h: f64, t1: f64) -> Result<(), Error> {
        self.before.clone_from(&self.base);
        let t0 = self.base.time();
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
                return Err(e);
            }
        }
        self.steps += 1;
        self.base.number(self.steps);
        self.last_h = Some(h);
        Ok(())
    }

    /// The next step of size `h`, on the clock.
    fn step_on_clock(&mut self) -> Result<(), Error> {
        let t1 = self.clock.at(self.steps + 1, self.h);
        self.step_by(self.h, t1)
    }

    /// One step toward `t_end`: the step of size `h`, or, when a step from
    /// `t` ends within `10⁻⁹ h` of `t_end` or beyond it (the landing rule
    /// of the integrators' `run_until`), the step that ends on `t_end`
    /// exactly, with the clock restarted there; a no-op at or beyond `t_end`.
    fn toward(&mut self, t_end: f64) -> Result<(), Error> {
        let t = self.base.time();
        if t.is_nan() || t >= t_end {
            return Ok(());
        }
        if !fixed_step_lands(t + self.h, self.h, t_end) {
            return self.step_on_clock();
        }
        self.step_by(t_end - t, t_end)?;
        self.clock = Clock { t: t_end, step: self.steps };
        Ok(())
    }

    /// Changes the size of the following steps, the clock restarted at the
    /// node; a size that is not finite and positive is refused.
    fn set_h(&mut self, h: f64) -> Result<(), Error> {
        Error::check_step(h)?;
        self.clock = Clock { t: self.base.time(), step: self.steps };
        self.h = h;
        Ok(())
    }

    /// The counters of the base, with the composed steps.
    fn count(&self, base: Stats) -> Stats {
        Stats { steps: self.steps, failed_steps: self.failed_steps, ..base }
    }
}

/// At a compile-time size: the base's node by value, numbered here.
impl<B: ConstSubSteps<N>, const N: usize> Stepping<N> for Composed<B> {
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
        self.count(self.base.stats())
    }

    fn step(&mut self) -> Result<(), Error> {
        self.step_on_clock().map_err(|e| e.at_state(Stepping::state(self)))
    }

    fn step_toward(&mut self, t_end: f64, _last_h: Option<f64>) -> Result<(), Error> {
        self.toward(t_end).map_err(|e| e.at_state(Stepping::state(self)))
    }

    /// The landing loop of [`RunTimeStepping::run_until`], which the
    /// run-time size runs over [`step_toward`](RunTimeStepping::step_toward).
    fn land(&mut self, t: f64) -> Result<(), Error> {
        let now = Stepping::state(self);
        if !t.is_finite() || t < now.t {
            return Err(Error::InvalidTarget { target: t, state: now.into() });
        }
        while self.base.time() < t {
            Stepping::step_toward(self, t, self.last_h)?;
        }
        Ok(())
    }

    /// The cubic Hermite through both nodes of the whole step.
    fn native(&self, start: &Node<N>, end: &Node<N>) -> Hermite<N> {
        Hermite::cubic(start, end)
    }
}

/// At a run-time size: the base's node by reference, numbered by the base
/// ([`SubSteps::number`]); `run_until` is the trait's landing loop.
impl<B: SubSteps + RunTimeStepping> RunTimeStepping for Composed<B> {
    type System = B::System;

    fn system(&self) -> &B::System {
        self.base.system()
    }

    fn state(&self) -> &PhasePoint {
        self.base.state()
    }

    fn velocity(&self) -> Result<Vec<f64>, Error> {
        self.base.velocity()
    }

    fn energy(&self) -> Result<f64, Error> {
        self.base.energy()
    }

    /// That of the last sub-step.
    fn discrete_energy(&self) -> f64 {
        self.base.discrete_energy()
    }

    /// Composed steps; the Newton iterations of every sub-step.
    fn stats(&self) -> Stats {
        self.count(self.base.stats())
    }

    fn step(&mut self) -> Result<(), Error> {
        self.step_on_clock().map_err(|e| e.at_state(self.base.state().clone()))
    }

    fn step_toward(&mut self, t_end: f64) -> Result<(), Error> {
        self.toward(t_end).map_err(|e| e.at_state(self.base.state().clone()))
    }

    fn step_size(&self) -> f64 {
        self.h
    }

    fn last_step_size(&self) -> Option<f64> {
        self.last_h
    }

    fn set_step_size(&mut self, h: f64) -> Result<(), Error> {
        self.set_h(h)
    }

    /// `None`: dense output is the cubic Hermite of the whole step (a
    /// Galerkin base's polynomial is that of its last sub-step only).
    fn step_polynomial(&self) -> Option<(f64, &[f64], &[f64])> {
        None
    }
}
