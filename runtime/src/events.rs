//! Events: sign changes of user functions `g(t, q, v)` along a solution.
//!
//! After every step [`solve`](crate::solution) compares the sign of each
//! event function at the new node with its sign at the last one. Where it
//! changed (in the direction the event asks for), the crossing is located
//! on the step's [dense output](crate::dense) by the Illinois variant of
//! regula falsi, a bracketing method that keeps the root enclosed and
//! converges superlinearly, until the bracket is narrower than the event's
//! time tolerance. The event's [`Action`] then says what happens:
//! [`Record`](Action::Record) it, [`Stop`](Action::Stop) the run there, or
//! [`Land`](Action::Land) a node on it and go on.
//!
//! Stopping and landing redo the step from its start with a step that ends
//! on the event time `t*` (the integrators' `run_until`), so the integrator
//! holds a genuine node at `t*` and can be continued from it. That node's
//! state differs from the dense output at `t*` by the method's local error;
//! [`EventRecord`] keeps the dense-output state, where `g` is zero to the
//! tolerance.
//!
//! Events located at the same time as the first stop or landing are all
//! recorded (two identical stop events give two records; the run's
//! [`Status::Stopped`](crate::Status::Stopped) names the first in the plan's
//! order); later ones in that step are not reached.
//!
//! Limits: two crossings within one step (or between the samples set by
//! [`Event::samples`]) cancel and are not seen; a crossing at the initial time
//! is not reported.

/// Which sign changes of `g` count.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Direction {
    /// Both.
    #[default]
    Either,
    /// From negative to non-negative.
    Rising,
    /// From positive to non-positive.
    Falling,
}

/// What happens at an event.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Action {
    /// Record it and go on; the steps are not changed.
    #[default]
    Record,
    /// Record it and end the run with the integrator at a node at the event time.
    Stop,
    /// Record it, put a node at the event time, then go on to the end of the
    /// step that was interrupted (fixed steps keep their grid).
    Land,
}

/// A located event.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct EventRecord {
    /// Which event (its index in the plan).
    pub event: usize,
    /// The time of the crossing.
    #[cfg_attr(feature = "serde", serde(with = "crate::serde_arrays::float"))]
    pub t: f64,
    /// The position there, by dense output.
    #[cfg_attr(feature = "serde", serde(with = "crate::serde_arrays::column"))]
    pub q: Vec<f64>,
    /// The velocity there, by dense output.
    #[cfg_attr(feature = "serde", serde(with = "crate::serde_arrays::column"))]
    pub v: Vec<f64>,
    /// `true` when `g` was rising through zero.
    pub rising: bool,
}

/// The event function's type: `g(t, q, v)`, with `q` and `v` slices of the
/// system's size (compile-time or run-time).
pub type EventFn<'a> = Box<dyn FnMut(f64, &[f64], &[f64]) -> f64 + 'a>;

/// An event function with its direction, action and tolerance.
///
/// The crossings of `g(t, q, v) = 0` between nodes are located on the dense
/// output; [`Action::Record`] keeps them in the solution's `events`,
/// [`Action::Stop`] also ends the run there. The zeros of an oscillator
/// `q = cos t` going down, recorded over two periods:
///
/// ```
/// # use lagrangian_runtime::{Action, Direction, Event, Galerkin, Integrator, Lagrangian, Plan, Scalar};
/// # use lagrangian_runtime::Stepping;
/// /// `L = ½v² − ½q²`.
/// #[derive(Clone)]
/// struct Oscillator;
/// impl Lagrangian<1> for Oscillator {
///     const AUTONOMOUS: bool = true;
///     const CYCLIC: [bool; 1] = [false];
///     fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 1], v: [D; 1]) -> D {
///         (v[0] * v[0] - q[0] * q[0]) * 0.5
///     }
/// }
///
/// let mut sim = Integrator::new(Oscillator, Galerkin::<3, 3>::gauss(), 0.1).start(0.0, [1.0], [0.0])?;
/// let plan = Plan::until(4.0 * std::f64::consts::PI)
///     .event(Event::new(|_t, q, _v| q[0]).direction(Direction::Falling).action(Action::Record));
/// let solution = sim.solve(plan)?.into_result()?;
/// let zeros: Vec<f64> = solution.events.iter().map(|e| e.t).collect();
/// let pi = std::f64::consts::PI;
/// assert_eq!(zeros.len(), 2);
/// assert!((zeros[0] - pi / 2.0).abs() < 1e-8 && (zeros[1] - 5.0 * pi / 2.0).abs() < 1e-8);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub struct Event<'a> {
    pub(crate) g: EventFn<'a>,
    pub(crate) direction: Direction,
    pub(crate) action: Action,
    pub(crate) tolerance: f64,
    pub(crate) samples: usize,
}

impl core::fmt::Debug for Event<'_> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Event")
            .field("direction", &self.direction)
            .field("action", &self.action)
            .field("tolerance", &self.tolerance)
            .field("samples", &self.samples)
            .finish_non_exhaustive()
    }
}

impl<'a> Event<'a> {
    /// An event at the zeros of `g(t, q, v)`: recorded, in either direction,
    /// located to a time tolerance of `1e-14 · max(1, |t|)`.
    pub fn new(g: impl FnMut(f64, &[f64], &[f64]) -> f64 + 'a) -> Self {
        Self { g: Box::new(g), direction: Direction::Either, action: Action::Record, tolerance: 1e-14, samples: 1 }
    }

    /// Only sign changes in this direction.
    pub fn direction(mut self, direction: Direction) -> Self {
        self.direction = direction;
        self
    }

    /// What to do at the event.
    pub fn action(mut self, action: Action) -> Self {
        self.action = action;
        self
    }

    /// The relative time tolerance: the crossing is bracketed to
    /// `tolerance · max(1, |t|)` (at least a few units of round-off).
    pub fn tolerance(mut self, tolerance: f64) -> Self {
        self.tolerance = tolerance;
        self
    }

    /// Evaluate `g` at `samples − 1` equally spaced points inside each step
    /// too (on the dense output), so that two crossings closer than a step
    /// are seen when they fall into different samples (default 1: the nodes only).
    pub fn samples(mut self, samples: usize) -> Self {
        self.samples = samples;
        self
    }

    /// `true` when `a → b` is a sign change this event counts.
    pub(crate) fn crosses(&self, a: f64, b: f64) -> bool {
        let rising = a < 0.0 && b >= 0.0;
        let falling = a > 0.0 && b <= 0.0;
        match self.direction {
            Direction::Either => rising || falling,
            Direction::Rising => rising,
            Direction::Falling => falling,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn directions_filter_sign_changes() {
        let e = Event::new(|_, q, _| q[0]);
        assert!(e.crosses(-1.0, 1.0) && e.crosses(1.0, -1.0) && e.crosses(-1.0, 0.0));
        assert!(!e.crosses(0.0, 1.0) && !e.crosses(1.0, 2.0));
        let rising = Event::new(|_, q, _| q[0]).direction(Direction::Rising);
        assert!(rising.crosses(-1.0, 1.0) && !rising.crosses(1.0, -1.0));
        let falling = Event::new(|_, q, _| q[0]).direction(Direction::Falling);
        assert!(!falling.crosses(-1.0, 1.0) && falling.crosses(1.0, -1.0));
    }
}
