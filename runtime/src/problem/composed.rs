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

use super::extend::Extended;
use super::stepper::{Driver, DriverBox, step_of};
use crate::dense::{Hermite, Node};
use crate::dim::Dim;
use crate::error::Error;
use crate::integrator::{Clock, Composition, F64Readouts, Integrator, Stats};
use crate::solution::Stepping;
use crate::state::State;
use crate::system::Lagrangian;

/// A symmetric composition of steps of a base driver with fixed step `h`.
pub struct Composed<S: Lagrangian<N> + Clone, const N: usize>
where
    Dim<N>: Extended<N>,
{
    /// The base driver, stepped by sub-steps of sizes `γ_i h`.
    base: DriverBox<S, N>,
    /// The base as it was before the step in progress: a failed sub-step
    /// puts it back (copied in place, no allocation).
    before: DriverBox<S, N>,
    weights: Composition,
    h: f64,
    /// `t_k = clock.t + (k − clock.step) h`, reset after a landing.
    clock: Clock<f64>,
    /// Composed steps taken: the node index `k`.
    steps: u64,
    /// Composed steps that failed.
    failed_steps: u64,
}

impl<S: Lagrangian<N> + Clone, const N: usize> Clone for Composed<S, N>
where
    Dim<N>: Extended<N>,
{
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

/// The next step of `it` (a fixed-step integrator), of size `h` and
/// ending at `t1`: its own step, which stamps `clock.at(k + 1, h) = t1 + 0·h`,
/// exactly `t1`. The sub-steps run through the stepper's own out-of-line
/// step of each driver ([`step_of`]), so a composition adds no copy of any
/// base's step to the code compiled for a system.
#[inline(always)]
fn sub_step<S: Lagrangian<N>, M: F64Readouts, const N: usize>(
    it: &mut Integrator<S, M, N>,
    h: f64,
    t1: f64,
) -> Result<(), Error> {
    it.h = h;
    it.clock = Clock { t: t1, step: it.state.step + 1 };
    step_of(it)
}

/// Why a driver is not a base of [`Composed`] ([`supports`](super::supports)
/// refuses those compositions before a driver is built).
const NOT_A_BASE: &str =
    "a composition of this method: the sub-steps of a composition are of a one-point or Galerkin rule";

impl<S: Lagrangian<N> + Clone, const N: usize> Driver<S, N>
where
    Dim<N>: Extended<N>,
{
    /// One step of size `h` (negative for some sub-steps of a composition)
    /// ending at `t1`; on failure the driver is unchanged.
    fn step_by(&mut self, h: f64, t1: f64) -> Result<(), Error> {
        match self {
            Driver::Midpoint(d) => sub_step(d, h, t1),
            Driver::Trapezoid(d) => sub_step(d, h, t1),
            Driver::AlphaBeta(d) => sub_step(d, h, t1),
            Driver::Gauss2(d) => sub_step(d, h, t1),
            Driver::Gauss3(d) => sub_step(d, h, t1),
            Driver::Gauss4(d) => sub_step(d, h, t1),
            Driver::Gauss5(d) => sub_step(d, h, t1),
            Driver::Gauss6(d) => sub_step(d, h, t1),
            Driver::Gauss7(d) => sub_step(d, h, t1),
            Driver::Gauss8(d) => sub_step(d, h, t1),
            Driver::Lobatto2(d) => sub_step(d, h, t1),
            Driver::Lobatto3(d) => sub_step(d, h, t1),
            Driver::Lobatto4(d) => sub_step(d, h, t1),
            Driver::Composition(_) | Driver::Composed(_) | Driver::Transformed(_) | Driver::Splitting(_) => {
                Err(Error::Unsupported { what: NOT_A_BASE })
            }
        }
    }
}

impl<S: Lagrangian<N> + Clone, const N: usize> Composed<S, N>
where
    Dim<N>: Extended<N>,
{
    /// The composition with `weights` of `base`, a driver that has not
    /// stepped, with fixed step `h`.
    pub(super) fn new(base: Box<Driver<S, N>>, weights: Composition, h: f64) -> Self {
        let base = DriverBox(base);
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
            if let Err(e) = self.base.step_by(gamma * h, ti) {
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

impl<S: Lagrangian<N> + Clone, const N: usize> Stepping<N> for Composed<S, N>
where
    Dim<N>: Extended<N>,
{
    type System = S;
    type Native = Hermite<N>;

    fn system(&self) -> &S {
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
