//! Solutions: a run recorded as a table, with values between the nodes,
//! events, statistics and the way the run ended.
//!
//! ```
//! use lagrangian_runtime::{Integrator, Lagrangian, Midpoint, Scalar};
//! use lagrangian_runtime::solution::{Plan, Stepping};
//!
//! #[derive(Clone)]
//! struct Oscillator;
//! impl Lagrangian<1> for Oscillator {
//!     const AUTONOMOUS: bool = true;
//!     const CYCLIC: [bool; 1] = [false];
//!     fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 1], v: [D; 1]) -> D {
//!         (v[0] * v[0] - q[0] * q[0]) * 0.5
//!     }
//! }
//!
//! let mut sim = Integrator::new(Oscillator, Midpoint, 0.01).start(0.0, [1.0], [0.0])?;
//! let solution = sim.solve(Plan::until(1.0).every(10).save_at(vec![0.125, 0.5]))?;
//! assert!(solution.is_finished());
//! // Nodes 0, 10, …, 100 (t = 0 included) and the two requested times, in time order.
//! assert_eq!(solution.len(), 13);
//! assert_eq!(solution.t[0], 0.0);
//! assert_eq!(solution.t[2], 0.125);
//! assert_eq!(solution.step[2], None); // interpolated, not a node
//! assert!((solution.q[2][0] - 0.125f64.cos()).abs() < 1e-4);
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! A [`Plan`] says how far to integrate and what to keep: every `n`-th node
//! ([`Plan::every`]; the first and the last node are always kept), values at
//! given times by [dense output](crate::dense) ([`Plan::save_at`]),
//! [events](crate::events), an observer every `n` steps, an energy watch
//! ([`Plan::energy_tolerance`]) and (feature `progress`) a progress bar.
//! The rows of a [`Solution`] are in time order; `step[i]` is the node index
//! `k` of a node and `None` for an interpolated value. Velocities are those
//! whose momentum is `p_k` (the inverse Legendre transform, one small Newton
//! solve per row) and the energy is `E_L(t, q, v)`;
//! [`Plan::without_velocities`] keeps only `t, q, p` and skips those solves.
//!
//! A step that fails ends the run, and so does a failure of what follows a
//! step (an event function that is not finite, a node velocity that cannot
//! be found): the solution holds everything up to the last good node, which
//! is its last node row (kept even between the nodes [`Plan::every`]
//! keeps, unless that is 0; with NaN velocity and energy if its velocity
//! cannot be found), its [`status`](Solution::status) is
//! [`Status::Failed`] and [`error`](Solution::error) holds the typed error,
//! and the integrator is at that last node: the step that failed, and what
//! it recorded, are undone. [`Solution::into_result`] turns that into an
//! `Err` for callers who want `?`.
//!
//! With the feature `serde`, [`Solution`] is `Serialize`/`Deserialize` (the
//! typed error is not: its message is kept in the status), and
//! `Solution::write_csv`, `read_csv`, `write_json` and `read_json` write and
//! read it through `csv` and
//! `serde_json`. Every `f64` comes back bit for bit, the non-finite ones
//! too: they are written as the texts `inf`, `-inf`, `NaN`, `-NaN` and
//! `NaN:0x…` (the bits of any other NaN), which neither format has a number
//! for. The writers refuse a solution whose columns differ in length, and
//! the readers refuse, with a `TableError` that says what is wrong and
//! where, anything that is not the table of a solution; the number of
//! coordinates comes from the table (the CSV header, the JSON rows).
//!
//! The rows of `q`, `p` and `v` are [`Rows`]: one flat buffer per column,
//! whatever the system's size, indexed as `solution.q[i][j]`.

mod rows;
mod run_time;

pub use rows::{RowIter, Rows};
pub use run_time::RunTimeStepping;

use crate::dense::{Coordinates, DenseStep, Hermite, Interpolant, Node, NodeView, Point, acceleration};
use crate::error::Error;
use crate::events::{Action, Event, EventRecord};
use crate::integrator::Stats;
use crate::mechanics::DiscreteMechanics;
use crate::root::illinois;
use crate::state::State;
use crate::system::Lagrangian;

/// An integrator as the workflow tools drive it, in `f64`: implemented once
/// for the [`Integrator`](crate::Integrator) with every method (one-point
/// rules, Galerkin, compositions), in `stepping.rs`. Its provided method
/// [`solve`](Self::solve) is the one way to a [`Solution`].
pub trait Stepping<const N: usize> {
    /// The integrated system.
    type System: Lagrangian<N>;
    /// The method's own interpolant of one step.
    type Native: DenseStep<N>;

    /// The system.
    fn system(&self) -> &Self::System;

    /// The state at the current node.
    fn state(&self) -> State<N>;

    /// The velocity whose momentum is the current `p_k`.
    fn velocity(&self) -> Result<[f64; N], Error>;

    /// Work counters.
    fn stats(&self) -> Stats;

    /// One step of the integrator's own size (or, under energy-preserving
    /// steps, the size the energy equation picks).
    fn step(&mut self) -> Result<(), Error>;

    /// One step toward `t_end`: the integrator's own step, or, when that
    /// step would reach `t_end` or pass it, the shortened step that ends on
    /// `t_end` exactly; `last_h` is the length of the last step taken
    /// (`None` before the first).
    fn step_toward(&mut self, t_end: f64, last_h: Option<f64>) -> Result<(), Error>;

    /// Steps to `t` exactly (the integrators' `run_until`); from within one
    /// step of `t`, one shortened step.
    fn land(&mut self, t: f64) -> Result<(), Error>;

    /// The method's own interpolant of the last step, which ran from `start`
    /// to the current node `end`.
    fn native(&self, start: &Node<N>, end: &Node<N>) -> Self::Native;

    /// Integrates as `plan` says and returns the [`Solution`]: the nodes
    /// (from the current one on), values at requested times by dense output,
    /// events, statistics and how the run ended (see the [module](self)).
    ///
    /// Returns `Err` only for a plan that cannot run (nothing is integrated
    /// then); a failure during the run ends it with the partial solution,
    /// whose [`status`](Solution::status) and [`error`](Solution::error) say
    /// what failed. The integrator is left at the last node of the solution.
    fn solve(&mut self, plan: Plan<'_>) -> Result<Solution, SolveError>
    where
        Self: Sized + Clone,
    {
        solve::<ConstSize<Self, N>>(self, plan)
    }
}

/// Which interpolant dense output uses (see [`crate::dense`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum DenseKind {
    /// The method's own: the cubic Hermite for the one-point rules (midpoint,
    /// trapezoid, α-β), the step polynomial for Galerkin (order `s + 1`).
    #[default]
    Native,
    /// The cubic Hermite from `q, v` at both nodes (order 4).
    Cubic,
    /// The quintic Hermite from `q, v` and the acceleration at both nodes
    /// (order 6; one more evaluation of the Hessian of `L` per node).
    Quintic,
}

/// An observer called at nodes.
type Observer<'a> = Box<dyn FnMut(NodeView<'_>) + 'a>;

/// What [`solve`](Stepping::solve) does: how far, what it keeps,
/// which events it watches.
///
/// ```
/// # use lagrangian_runtime::{Lagrangian, Scalar};
/// # #[derive(Clone)]
/// # struct Oscillator;
/// # impl Lagrangian<1> for Oscillator {
/// #     const AUTONOMOUS: bool = true;
/// #     const CYCLIC: [bool; 1] = [false];
/// #     fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 1], v: [D; 1]) -> D {
/// #         (v[0] * v[0] - q[0] * q[0]) * 0.5
/// #     }
/// # }
/// use lagrangian_runtime::{Action, DenseKind, Event, Integrator, Midpoint, Plan, Stepping};
///
/// let mut nodes = 0;
/// let plan = Plan::until(10.0)
///     .every(100) // keep every 100th node
///     .save_at(vec![0.05, 2.5]) // and these times, interpolated
///     .dense(DenseKind::Quintic)
///     .energy_tolerance(1e-3) // warn if E_L drifts further
///     .observe_every(1, |_| nodes += 1) // called at every node
///     .event(Event::new(|_t, q, _v| q[0]).action(Action::Record));
/// let mut sim = Integrator::new(Oscillator, Midpoint, 0.01).start(0.0, [1.0], [0.0])?;
/// let solution = sim.solve(plan)?;
/// // Nodes 0, 100, …, 1000 and the two requested times.
/// assert_eq!(solution.len(), 13);
/// // cos t crosses zero at π/2 + kπ: three times before t = 10.
/// assert_eq!(solution.events.len(), 3);
/// assert!((solution.events[0].t - std::f64::consts::FRAC_PI_2).abs() < 1e-4);
/// assert!(solution.energy_warning().is_none());
/// assert!(nodes >= 1000);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub struct Plan<'a> {
    t_end: f64,
    every: usize,
    save_at: Vec<f64>,
    dense: DenseKind,
    events: Vec<Event<'a>>,
    velocities: bool,
    observer: Option<(usize, Observer<'a>)>,
    energy_tolerance: Option<f64>,
    #[cfg(feature = "progress")]
    progress: bool,
}

impl core::fmt::Debug for Plan<'_> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Plan")
            .field("t_end", &self.t_end)
            .field("every", &self.every)
            .field("save_at", &self.save_at)
            .field("dense", &self.dense)
            .field("events", &self.events)
            .field("velocities", &self.velocities)
            .field("energy_tolerance", &self.energy_tolerance)
            .finish_non_exhaustive()
    }
}

impl<'a> Plan<'a> {
    /// Integrate to `t_end` (landing on it exactly) keeping every node.
    pub fn until(t_end: f64) -> Self {
        Self {
            t_end,
            every: 1,
            save_at: Vec::new(),
            dense: DenseKind::Native,
            events: Vec::new(),
            velocities: true,
            observer: None,
            energy_tolerance: None,
            #[cfg(feature = "progress")]
            progress: false,
        }
    }

    /// The end time.
    pub(crate) fn end(&self) -> f64 {
        self.t_end
    }

    /// Which nodes become rows: every `n`-th (and the last); 0 for none.
    pub(crate) fn kept_every(&self) -> usize {
        self.every
    }

    /// Whether some rows or records are interpolated between nodes (save
    /// times, events).
    pub(crate) fn interpolates(&self) -> bool {
        !self.save_at.is_empty() || !self.events.is_empty()
    }

    /// Keep every `n`-th node, counted in steps of this run, and the first
    /// and last; `0` keeps no nodes (only [`save_at`](Self::save_at) values).
    pub fn every(mut self, n: usize) -> Self {
        self.every = n;
        self
    }

    /// Keep the solution at these times (sorted, within `[t_now, t_end]`), by dense output.
    pub fn save_at(mut self, times: Vec<f64>) -> Self {
        self.save_at = times;
        self
    }

    /// The interpolant for [`save_at`](Self::save_at) and events.
    pub fn dense(mut self, kind: DenseKind) -> Self {
        self.dense = kind;
        self
    }

    /// Watch an event.
    pub fn event(mut self, event: Event<'a>) -> Self {
        self.events.push(event);
        self
    }

    /// Keep `t, q, p` only: no velocity or energy columns, no inverse
    /// Legendre solve for rows that do not need one.
    pub fn without_velocities(mut self) -> Self {
        self.velocities = false;
        self
    }

    /// Call `observe` at the start and after every `n`-th step (`n ≥ 1`),
    /// with the node as slices (the same for every system size).
    pub fn observe_every(mut self, n: usize, observe: impl FnMut(NodeView<'_>) + 'a) -> Self {
        self.observer = Some((n, Box::new(observe)));
        self
    }

    /// Watch the energy `E_L` at every node and report in
    /// [`Solution::energy`](Solution::energy_watch) where its relative change
    /// from the start first exceeded `tolerance` (see [`EnergyWatch`]).
    pub fn energy_tolerance(mut self, tolerance: f64) -> Self {
        self.energy_tolerance = Some(tolerance);
        self
    }

    /// Show a progress bar on standard error while solving (hidden when
    /// standard error is not a terminal).
    #[cfg(feature = "progress")]
    pub fn progress(mut self) -> Self {
        self.progress = true;
        self
    }
}

/// How a run ended.
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub enum Status {
    /// It reached the end time.
    Finished,
    /// A [`Stop`](Action::Stop) event ended it at `t`.
    Stopped {
        /// The index of the event.
        event: usize,
        /// The event time (the integrator's last node).
        #[cfg_attr(feature = "serde", serde(with = "crate::serde_arrays::float"))]
        t: f64,
    },
    /// A step or an event function failed; [`Solution::error`] holds the
    /// typed error.
    Failed {
        /// The error's message.
        message: String,
    },
}

/// Counters of a run.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct RunStats {
    /// Steps taken by the integrator over its life (its [`Stats`]).
    pub steps: u64,
    /// Newton iterations over all steps (its [`Stats`]).
    pub newton_iterations: u64,
    /// Failed steps (its [`Stats`]).
    pub failed_steps: u64,
    /// Steps of this run that were taken again to end on an event.
    pub redone_steps: u64,
    /// Inverse Legendre solves for node velocities.
    pub velocity_solves: u64,
    /// Evaluations of event functions.
    pub event_evaluations: u64,
}

/// The energy watch of a run ([`Plan::energy_tolerance`]).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct EnergyWatch {
    /// The tolerance on `|E_L − E_0| / |E_0|`.
    #[cfg_attr(feature = "serde", serde(with = "crate::serde_arrays::float"))]
    pub tolerance: f64,
    /// `E_0`, the energy at the first node.
    #[cfg_attr(feature = "serde", serde(with = "crate::serde_arrays::float"))]
    pub initial: f64,
    /// The largest relative change seen at a node.
    #[cfg_attr(feature = "serde", serde(with = "crate::serde_arrays::float"))]
    pub largest: f64,
    /// Where it happened.
    #[cfg_attr(feature = "serde", serde(with = "crate::serde_arrays::float"))]
    pub largest_at: f64,
    /// The first node time where the change exceeded the tolerance.
    #[cfg_attr(feature = "serde", serde(with = "crate::serde_arrays::option"))]
    pub exceeded_at: Option<f64>,
}

impl EnergyWatch {
    /// A warning text when the tolerance was exceeded.
    pub fn warning(&self) -> Option<String> {
        let t = self.exceeded_at?;
        Some(format!(
            "the energy changed by more than {:e} (relative) from t = {t} on; the largest change was {:e} at t = {}: \
             the step size is probably too large (see `lagrangian_runtime::guidance`)",
            self.tolerance, self.largest, self.largest_at
        ))
    }

    fn observe(&mut self, t: f64, energy: f64) {
        let change = (energy - self.initial).abs() / self.initial.abs().max(f64::MIN_POSITIVE);
        // NaN counts as exceeding.
        if change.is_nan() || change > self.largest {
            self.largest = change;
            self.largest_at = t;
        }
        if self.exceeded_at.is_none() && (change.is_nan() || change > self.tolerance) {
            self.exceeded_at = Some(t);
        }
    }
}

/// What can go wrong in [`solve`](crate::Integrator::solve).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum SolveError {
    /// A step failed (or the velocity of a node could not be found).
    #[error(transparent)]
    Step(#[from] Error),
    /// An end time that is not finite or lies behind the current time.
    #[error("invalid end time {t_end}: the integrator is at t = {t}")]
    InvalidEnd {
        /// The requested end.
        t_end: f64,
        /// The current time.
        t: f64,
    },
    /// A save time that is not finite, out of `[t, t_end]` or out of order.
    #[error("`save_at[{index}]` = {time} is not sorted or not within [{t}, {t_end}]")]
    InvalidSaveTime {
        /// Its index.
        index: usize,
        /// The time.
        time: f64,
        /// The current time.
        t: f64,
        /// The end time.
        t_end: f64,
    },
    /// An event function returned NaN or an infinity.
    #[error("event {event} is not finite at t = {t}")]
    NonFiniteEvent {
        /// Which event.
        event: usize,
        /// Where.
        t: f64,
    },
    /// An event with a tolerance that is not finite and positive, or no samples.
    #[error("invalid event {event}: {reason}")]
    InvalidEvent {
        /// Which event.
        event: usize,
        /// What is wrong.
        reason: &'static str,
    },
    /// Other settings of the plan that cannot work.
    #[error("invalid plan: {reason}")]
    InvalidPlan {
        /// What is wrong.
        reason: &'static str,
    },
    /// The acceleration for quintic dense output does not exist.
    #[error("no acceleration at t = {t}: ∂²L/∂v² is singular or a value is not finite")]
    NoAcceleration {
        /// Where.
        t: f64,
    },
}

/// A recorded run: one row per kept node or requested time, in time order.
///
/// The columns are public vectors of equal length (`v` and `energy` empty
/// under [`Plan::without_velocities`]). A run that fails part-way still
/// returns its rows up to the last good node, with [`status`](Self::status)
/// and [`error`](Self::error) set; [`into_result`](Self::into_result) turns
/// that into an `Err` that carries them.
///
/// ```
/// # use lagrangian_runtime::{Lagrangian, Scalar};
/// # #[derive(Clone)]
/// # struct Oscillator;
/// # impl Lagrangian<1> for Oscillator {
/// #     const AUTONOMOUS: bool = true;
/// #     const CYCLIC: [bool; 1] = [false];
/// #     fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 1], v: [D; 1]) -> D {
/// #         (v[0] * v[0] - q[0] * q[0]) * 0.5
/// #     }
/// # }
/// use lagrangian_runtime::{Event, Integrator, Plan, SolveError, Stepping, Trapezoid};
///
/// let mut sim = Integrator::new(Oscillator, Trapezoid, 0.01).start(0.0, [1.0], [0.0])?;
/// let solution = sim.solve(Plan::until(2.0).every(10))?;
/// assert!(solution.is_finished());
/// let last = solution.len() - 1;
/// assert_eq!((solution.t[last], solution.step[last]), (2.0, Some(200)));
/// assert!((solution.q[last][0] - 2f64.cos()).abs() < 1e-4);
/// assert!((solution.energy[last] - 0.5).abs() < 1e-4); // E_L = ½(v² + q²)
///
/// // An event function that stops being finite ends the run with a typed
/// // error; the rows up to the last good node are kept.
/// let broken = Event::new(|t, _q, _v| if t < 1.0 { 1.0 } else { f64::NAN });
/// let mut sim = Integrator::new(Oscillator, Trapezoid, 0.01).start(0.0, [1.0], [0.0])?;
/// let failed = sim.solve(Plan::until(2.0).event(broken))?.into_result().unwrap_err();
/// assert!(matches!(failed.error, SolveError::NonFiniteEvent { .. }));
/// assert!(*failed.solution.t.last().unwrap() < 1.0 + 1e-9);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Clone, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Solution {
    /// Times.
    #[cfg_attr(feature = "serde", serde(with = "crate::serde_arrays::column"))]
    pub t: Vec<f64>,
    /// The node index `k` of a node row, `None` for an interpolated one.
    pub step: Vec<Option<u64>>,
    /// Positions, one row of the system's size per time.
    pub q: Rows,
    /// Momenta (`p_k` at nodes; `∂L/∂v` of the interpolated `q, v` between them).
    pub p: Rows,
    /// Velocities (empty under [`Plan::without_velocities`]).
    pub v: Rows,
    /// The energy `E_L(t, q, v)` (empty under [`Plan::without_velocities`]).
    #[cfg_attr(feature = "serde", serde(with = "crate::serde_arrays::column"))]
    pub energy: Vec<f64>,
    /// Located events, in time order.
    pub events: Vec<EventRecord>,
    /// Counters.
    pub stats: RunStats,
    /// The energy watch, if the plan asked for one.
    pub energy_watch: Option<EnergyWatch>,
    /// How the run ended.
    pub status: Status,
    /// The typed error of a failed run.
    #[cfg_attr(feature = "serde", serde(skip))]
    pub error: Option<SolveError>,
}

/// A run that failed: the partial solution and the error.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{error} (the partial solution ends at t = {})", .solution.t.last().copied().unwrap_or(f64::NAN))]
pub struct Failed {
    /// Everything recorded up to the last good node.
    pub solution: Box<Solution>,
    /// What failed.
    pub error: SolveError,
}

impl Solution {
    /// A solution without rows for a system of `width` coordinates.
    fn empty(width: usize) -> Self {
        Self {
            t: Vec::new(),
            step: Vec::new(),
            q: Rows::new(width),
            p: Rows::new(width),
            v: Rows::new(width),
            energy: Vec::new(),
            events: Vec::new(),
            stats: RunStats::default(),
            energy_watch: None,
            status: Status::Finished,
            error: None,
        }
    }

    /// The number of rows.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// `true` without rows.
    pub fn is_empty(&self) -> bool {
        self.t.is_empty()
    }

    /// `true` when the run reached its end time.
    pub fn is_finished(&self) -> bool {
        self.status == Status::Finished
    }

    /// `Ok(self)` unless the run failed.
    pub fn into_result(mut self) -> Result<Self, Failed> {
        match self.error.take() {
            None => Ok(self),
            Some(error) => Err(Failed { solution: Box::new(self), error }),
        }
    }

    /// The warning of the energy watch, if it has one.
    pub fn energy_warning(&self) -> Option<String> {
        self.energy_watch.as_ref()?.warning()
    }

    /// The number of coordinates of a row of `q`, `p` and `v`.
    pub fn width(&self) -> usize {
        self.q.width()
    }

    #[inline]
    fn push(&mut self, step: Option<u64>, t: f64, q: &[f64], p: &[f64], v: Option<(&[f64], f64)>) {
        self.t.push(t);
        self.step.push(step);
        self.q.push(q);
        self.p.push(p);
        if let Some((v, e)) = v {
            self.v.push(v);
            self.energy.push(e);
        }
    }

    /// Drops the rows from `rows` on and the events from `events` on.
    fn truncate(&mut self, rows: usize, events: usize) {
        self.t.truncate(rows);
        self.step.truncate(rows);
        self.q.truncate(rows);
        self.p.truncate(rows);
        self.v.truncate(rows);
        self.energy.truncate(rows);
        self.events.truncate(events);
    }
}

/// What [`solve`] drives, at either size: the stepper (`Sim`), the
/// coordinates it carries (`[f64; N]` at a compile-time size, `Vec<f64>` at
/// a run-time size) and how its nodes, velocities and interpolants are
/// read. [`ConstSize`] implements it for every const-size driver through
/// [`Stepping`], `RunTimeSize` (`solution/run_time.rs`) for every
/// run-time-sized one through [`RunTimeStepping`]. One driver, so both
/// sizes keep the same rows, events and failures.
pub(crate) trait Solvable {
    /// The stepper.
    type Sim: Clone;
    /// The coordinates of a node.
    type Vector: Coordinates;
    /// The method's own interpolant of one step.
    type Native: Interpolant<Self::Vector>;
    /// The Hermite interpolant of one step (cubic or quintic).
    type Hermite: Interpolant<Self::Vector>;
    /// `false` where no acceleration is computed (quintic dense output is
    /// then refused before the run).
    const ACCELERATION: bool;

    /// The number of coordinates.
    fn width(sim: &Self::Sim) -> usize;
    /// The current time.
    fn time(sim: &Self::Sim) -> f64;
    /// `(k, t_k, q_k, p_k)` at the current node.
    fn node(sim: &Self::Sim) -> (u64, f64, Self::Vector, Self::Vector);
    /// The velocity whose momentum is the current `p_k`.
    fn velocity(sim: &Self::Sim) -> Result<Self::Vector, Error>;
    /// Work counters.
    fn stats(sim: &Self::Sim) -> Stats;
    /// One step toward `t_end` (see [`Stepping::step_toward`]).
    fn step_toward(sim: &mut Self::Sim, t_end: f64, last_h: Option<f64>) -> Result<(), Error>;
    /// Steps to `t` exactly (see [`Stepping::land`]).
    fn land(sim: &mut Self::Sim, t: f64) -> Result<(), Error>;
    /// The method's own interpolant of the last step, `start → end`.
    fn native(sim: &Self::Sim, start: &Point<Self::Vector>, end: &Point<Self::Vector>) -> Self::Native;
    /// The cubic Hermite of `start → end`, or the quintic with the
    /// accelerations `a` at both ends.
    fn hermite(
        start: &Point<Self::Vector>,
        end: &Point<Self::Vector>,
        a: Option<(&Self::Vector, &Self::Vector)>,
    ) -> Self::Hermite;
    /// `E_L(t, q, v)`.
    fn energy(sim: &Self::Sim, t: f64, q: &Self::Vector, v: &Self::Vector) -> f64;
    /// `∂L/∂v(t, q, v)`.
    fn momentum(sim: &Self::Sim, t: f64, q: &Self::Vector, v: &Self::Vector) -> Self::Vector;
    /// The acceleration of the equations of motion at `(t, q, v)`.
    fn acceleration(sim: &Self::Sim, t: f64, q: &Self::Vector, v: &Self::Vector) -> Option<Self::Vector>;
}

/// [`Solvable`] for a const-size driver `I` (through its [`Stepping`]):
/// the driver carries `[f64; N]`, as the stepper does.
pub(crate) struct ConstSize<I, const N: usize>(core::marker::PhantomData<I>);

impl<I: Stepping<N> + Clone, const N: usize> Solvable for ConstSize<I, N> {
    type Sim = I;
    type Vector = [f64; N];
    type Native = I::Native;
    type Hermite = Hermite<N>;
    const ACCELERATION: bool = true;

    fn width(_sim: &I) -> usize {
        N
    }

    fn time(sim: &I) -> f64 {
        sim.state().t
    }

    fn node(sim: &I) -> (u64, f64, [f64; N], [f64; N]) {
        let s = sim.state();
        (s.step, s.t, s.q, s.p)
    }

    fn velocity(sim: &I) -> Result<[f64; N], Error> {
        sim.velocity()
    }

    fn stats(sim: &I) -> Stats {
        sim.stats()
    }

    #[inline]
    fn step_toward(sim: &mut I, t_end: f64, last_h: Option<f64>) -> Result<(), Error> {
        sim.step_toward(t_end, last_h)
    }

    fn land(sim: &mut I, t: f64) -> Result<(), Error> {
        sim.land(t)
    }

    fn native(sim: &I, start: &Point<[f64; N]>, end: &Point<[f64; N]>) -> I::Native {
        sim.native(&start.into(), &end.into())
    }

    fn hermite(start: &Point<[f64; N]>, end: &Point<[f64; N]>, a: Option<(&[f64; N], &[f64; N])>) -> Hermite<N> {
        let (start, end) = (Node::from(start), Node::from(end));
        match a {
            None => Hermite::cubic(&start, &end),
            Some((a0, a1)) => Hermite::quintic(&start, *a0, &end, *a1),
        }
    }

    fn energy(sim: &I, t: f64, q: &[f64; N], v: &[f64; N]) -> f64 {
        sim.system().energy(t, *q, *v)
    }

    fn momentum(sim: &I, t: f64, q: &[f64; N], v: &[f64; N]) -> [f64; N] {
        sim.system().momentum(t, *q, *v)
    }

    fn acceleration(sim: &I, t: f64, q: &[f64; N], v: &[f64; N]) -> Option<[f64; N]> {
        acceleration(sim.system(), t, *q, *v)
    }
}

/// A node as the driver carries it: the velocity only once it was needed.
#[derive(Clone)]
struct Carried<V> {
    node: Point<V>,
    step: u64,
    has_v: bool,
    a: Option<V>,
}

/// The state of one run of [`solve`].
struct Driver<'s, 'a, K: Solvable> {
    sim: &'s mut K::Sim,
    plan: Plan<'a>,
    sol: Solution,
    next_save: usize,
    steps: u64,
}

enum StepInterpolant<K: Solvable> {
    Native(K::Native),
    Hermite(K::Hermite),
}

impl<K: Solvable> StepInterpolant<K> {
    fn eval(&self, t: f64) -> (K::Vector, K::Vector) {
        match self {
            Self::Native(d) => d.eval(t),
            Self::Hermite(d) => d.eval(t),
        }
    }
}

impl<K: Solvable> Driver<'_, '_, K> {
    fn node(&mut self, with_v: bool) -> Result<Carried<K::Vector>, SolveError> {
        let (step, t, q, p) = K::node(self.sim);
        let v = K::Vector::filled(K::width(self.sim), f64::NAN);
        let mut c = Carried { node: Point { t, q, p, v }, step, has_v: false, a: None };
        if with_v {
            self.velocity(&mut c)?;
        }
        Ok(c)
    }

    fn velocity(&mut self, c: &mut Carried<K::Vector>) -> Result<(), SolveError> {
        if !c.has_v {
            c.node.v = K::velocity(self.sim)?;
            c.has_v = true;
            self.sol.stats.velocity_solves += 1;
        }
        Ok(())
    }

    /// Computes the acceleration at `c` once.
    fn accel(&mut self, c: &mut Carried<K::Vector>) -> Result<(), SolveError> {
        if c.a.is_none() {
            let n = &c.node;
            let a = K::acceleration(self.sim, n.t, &n.q, &n.v).ok_or(SolveError::NoAcceleration { t: n.t })?;
            c.a = Some(a);
        }
        Ok(())
    }

    fn energy(&self, t: f64, q: &K::Vector, v: &K::Vector) -> f64 {
        K::energy(self.sim, t, q, v)
    }

    /// Keeps a node row.
    fn keep_node(&mut self, c: &mut Carried<K::Vector>) -> Result<(), SolveError> {
        let e = if self.plan.velocities {
            self.velocity(c)?;
            Some(self.energy(c.node.t, &c.node.q, &c.node.v))
        } else {
            None
        };
        let n = &c.node;
        self.sol.push(Some(c.step), n.t, n.q.as_ref(), n.p.as_ref(), e.map(|e| (n.v.as_ref(), e)));
        Ok(())
    }

    /// Makes the last good node `c` (where the integrator is after a failed
    /// step) the last node row, unless it is one already or the plan keeps
    /// no nodes. Its velocity and energy are NaN when its velocity cannot be
    /// found.
    fn keep_last_good(&mut self, c: &mut Carried<K::Vector>) {
        let last_node = self.sol.step.iter().rev().find_map(|&k| k);
        if self.plan.every == 0 || last_node == Some(c.step) {
            return;
        }
        if self.keep_node(c).is_err() {
            let nan = K::Vector::filled(K::width(self.sim), f64::NAN);
            let nan = self.plan.velocities.then_some((nan.as_ref(), f64::NAN));
            self.sol.push(Some(c.step), c.node.t, c.node.q.as_ref(), c.node.p.as_ref(), nan);
        }
    }

    /// Keeps the save times in `(after, upto]`, by `dense`.
    fn keep_saved(&mut self, dense: &StepInterpolant<K>, after: f64, upto: f64) {
        while let Some(&t) = self.plan.save_at.get(self.next_save) {
            if t > upto || t <= after {
                break;
            }
            let (q, v) = dense.eval(t);
            let p = K::momentum(self.sim, t, &q, &v);
            let e = self.plan.velocities.then(|| self.energy(t, &q, &v));
            self.sol.push(None, t, q.as_ref(), p.as_ref(), e.map(|e| (v.as_ref(), e)));
            self.next_save += 1;
        }
    }

    fn observe(&mut self, c: &mut Carried<K::Vector>, force: bool) -> Result<(), SolveError> {
        let due = match &self.plan.observer {
            Some((n, _)) => force || self.steps.is_multiple_of(*n as u64),
            None => false,
        };
        if due {
            self.velocity(c)?;
            if let Some((_, f)) = &mut self.plan.observer {
                f(c.node.view());
            }
        }
        Ok(())
    }

    fn interpolant(
        &mut self,
        start: &mut Carried<K::Vector>,
        end: &mut Carried<K::Vector>,
    ) -> Result<StepInterpolant<K>, SolveError> {
        Ok(match self.plan.dense {
            DenseKind::Native => StepInterpolant::Native(K::native(self.sim, &start.node, &end.node)),
            DenseKind::Cubic => StepInterpolant::Hermite(K::hermite(&start.node, &end.node, None)),
            DenseKind::Quintic => {
                self.accel(start)?;
                self.accel(end)?;
                let (Some(a0), Some(a1)) = (&start.a, &end.a) else {
                    return Err(SolveError::NoAcceleration { t: start.node.t });
                };
                StepInterpolant::Hermite(K::hermite(&start.node, &end.node, Some((a0, a1))))
            }
        })
    }

    fn g(&mut self, i: usize, t: f64, q: &[f64], v: &[f64]) -> Result<f64, SolveError> {
        self.sol.stats.event_evaluations += 1;
        let g = (self.plan.events[i].g)(t, q, v);
        if g.is_finite() { Ok(g) } else { Err(SolveError::NonFiniteEvent { event: i, t }) }
    }

    /// Locates the crossings of the events over the step `start → end`,
    /// with `g` their values at `start` on entry and at `end` on return (in
    /// place: no allocation per step). Returns the records and the earliest
    /// stopping or landing one (index into the records).
    fn crossings(
        &mut self,
        dense: &StepInterpolant<K>,
        start: &Point<K::Vector>,
        end: &Point<K::Vector>,
        g: &mut [f64],
    ) -> Result<(Vec<EventRecord>, Option<usize>), SolveError> {
        let mut found = Vec::new();
        for i in 0..self.plan.events.len() {
            let samples = self.plan.events[i].samples;
            let (mut ta, mut ga) = (start.t, g[i]);
            let mut stop_found = false;
            for j in 1..=samples {
                let (tb, gb) = if j == samples {
                    (end.t, self.g(i, end.t, end.q.as_ref(), end.v.as_ref())?)
                } else {
                    let tb = start.t + (end.t - start.t) * (j as f64 / samples as f64);
                    let (q, v) = dense.eval(tb);
                    (tb, self.g(i, tb, q.as_ref(), v.as_ref())?)
                };
                if !stop_found && self.plan.events[i].crosses(ga, gb) {
                    let tol = self.plan.events[i].tolerance * tb.abs().max(1.0) + 4.0 * f64::EPSILON * tb.abs();
                    let mut evals = 0;
                    let event = &mut self.plan.events[i];
                    let root = illinois(
                        |t| {
                            evals += 1;
                            let (q, v) = dense.eval(t);
                            (event.g)(t, q.as_ref(), v.as_ref())
                        },
                        (ta, ga),
                        (tb, gb),
                        tol,
                    );
                    self.sol.stats.event_evaluations += evals;
                    let t = root.map_err(|e| SolveError::NonFiniteEvent { event: i, t: e.t })?;
                    let (q, v) = dense.eval(t);
                    found.push(EventRecord {
                        event: i,
                        t,
                        q: q.as_ref().to_vec(),
                        v: v.as_ref().to_vec(),
                        rising: ga < 0.0,
                    });
                    stop_found = self.plan.events[i].action != Action::Record;
                }
                (ta, ga) = (tb, gb);
            }
            g[i] = ga;
        }
        found.sort_by(|a, b| a.t.total_cmp(&b.t));
        let stop = found.iter().position(|r| self.plan.events[r.event].action != Action::Record);
        if let Some(k) = stop {
            // Events at the very time of the first stop or landing are
            // recorded too (each event gets its record); later ones are not
            // reached.
            let t = found[k].t;
            let keep = found[k..].iter().take_while(|r| r.t == t).count();
            found.truncate(k + keep);
        }
        Ok((found, stop))
    }
}

/// Integrates `sim` as `plan` says (see the [module docs](self)).
pub(crate) fn solve<K: Solvable>(sim: &mut K::Sim, plan: Plan<'_>) -> Result<Solution, SolveError> {
    let t0 = K::time(sim);
    let t_end = plan.t_end;
    if !t_end.is_finite() || t_end < t0 {
        return Err(SolveError::InvalidEnd { t_end, t: t0 });
    }
    let mut previous = t0;
    for (index, &time) in plan.save_at.iter().enumerate() {
        if !(time >= previous && time <= t_end) {
            return Err(SolveError::InvalidSaveTime { index, time, t: t0, t_end });
        }
        previous = time;
    }
    for (event, e) in plan.events.iter().enumerate() {
        if !(e.tolerance.is_finite() && e.tolerance > 0.0) {
            return Err(SolveError::InvalidEvent { event, reason: "the tolerance must be finite and positive" });
        }
        if e.samples == 0 {
            return Err(SolveError::InvalidEvent { event, reason: "at least one sample per step is needed" });
        }
    }
    if matches!(plan.observer, Some((0, _))) {
        return Err(SolveError::InvalidPlan { reason: "an observer needs `n ≥ 1` in `observe_every(n, ..)`" });
    }
    if plan.energy_tolerance.is_some_and(|tol| !(tol.is_finite() && tol > 0.0)) {
        return Err(SolveError::InvalidPlan { reason: "the energy tolerance must be finite and positive" });
    }
    if plan.dense == DenseKind::Quintic && !K::ACCELERATION {
        return Err(SolveError::InvalidPlan {
            reason: "quintic dense output needs the acceleration, which a run-time-sized system does not compute: \
                     use `DenseKind::Native` or `DenseKind::Cubic`",
        });
    }
    let width = K::width(sim);
    let mut d = Driver::<K> { sim, plan, sol: Solution::empty(width), next_save: 0, steps: 0 };
    let error = run(&mut d).err();
    let mut sol = d.sol;
    let stats = K::stats(d.sim);
    sol.stats.steps = stats.steps;
    sol.stats.newton_iterations = stats.newton_iterations;
    sol.stats.failed_steps = stats.failed_steps;
    if let Some(e) = error {
        sol.status = Status::Failed { message: e.to_string() };
        sol.error = Some(e);
    }
    Ok(sol)
}

/// The loop of [`solve`]; an `Err` ends the run with what was recorded.
fn run<K: Solvable>(d: &mut Driver<'_, '_, K>) -> Result<(), SolveError> {
    let t_end = d.plan.t_end;
    let has_events = !d.plan.events.is_empty();
    let dense_needed = has_events || !d.plan.save_at.is_empty();
    let v_each_step = dense_needed || d.plan.energy_tolerance.is_some();
    #[cfg(feature = "progress")]
    let bar = d.plan.progress.then(|| progress_bar(t_end - K::time(d.sim)));

    let mut prev = d.node(v_each_step)?;
    let t0 = prev.node.t;
    if let Some(tolerance) = d.plan.energy_tolerance {
        d.velocity(&mut prev)?;
        let initial = d.energy(t0, &prev.node.q, &prev.node.v);
        d.sol.energy_watch = Some(EnergyWatch { tolerance, initial, largest: 0.0, largest_at: t0, exceeded_at: None });
    }
    // Save times at t0 come before the first node row.
    while d.plan.save_at.get(d.next_save) == Some(&t0) {
        d.velocity(&mut prev)?;
        let n = &prev.node;
        let e = d.plan.velocities.then(|| d.energy(t0, &n.q, &n.v));
        d.sol.push(None, t0, n.q.as_ref(), n.p.as_ref(), e.map(|e| (n.v.as_ref(), e)));
        d.next_save += 1;
    }
    if d.plan.every > 0 {
        d.keep_node(&mut prev)?;
    }
    d.observe(&mut prev, true)?;
    let mut g_prev = Vec::with_capacity(d.plan.events.len());
    for i in 0..d.plan.events.len() {
        let n = &prev.node;
        g_prev.push(d.g(i, n.t, n.q.as_ref(), n.v.as_ref())?);
    }
    // Everything after a step that can fail (velocity solves, accelerations,
    // event functions, the landing step) needs the integrator as it was
    // before the step, to go back to the solution's last node.
    let fallible = v_each_step
        || (d.plan.velocities && d.plan.every > 0)
        || d.plan.observer.is_some()
        || d.plan.dense == DenseKind::Quintic;
    let mut lp = Loop { prev, g_prev, rejoin: None, last_h: None };
    // The copy is made once, on the heap, and refreshed in place before each
    // step: no allocation per step, and no frame holds a large integrator.
    let mut before = (fallible || has_events).then(|| Box::new(d.sim.clone()));
    while lp.prev.node.t < t_end {
        if let Some(before) = before.as_deref_mut() {
            before.clone_from(d.sim);
        }
        let mark = (d.sol.len(), d.sol.events.len(), d.next_save);
        match advance(d, &mut lp, before.as_deref(), dense_needed, v_each_step) {
            Ok(true) => return Ok(()),
            Ok(false) => {}
            Err(e) => {
                // The step (or what follows it) failed: back to the last
                // good node, which becomes the solution's last node row.
                if let Some(before) = before.as_deref_mut() {
                    core::mem::swap(d.sim, before);
                }
                d.sol.truncate(mark.0, mark.1);
                d.next_save = mark.2;
                d.keep_last_good(&mut lp.prev);
                return Err(e);
            }
        }
        #[cfg(feature = "progress")]
        if let Some(bar) = &bar
            && (d.steps.is_multiple_of(64) || lp.prev.node.t >= t_end)
        {
            bar.set_position((((lp.prev.node.t - t0) / (t_end - t0)) * PROGRESS_UNITS as f64) as u64);
        }
    }
    #[cfg(feature = "progress")]
    if let Some(bar) = bar {
        bar.finish();
    }
    Ok(())
}

/// What the loop of [`run`] carries from one step to the next.
struct Loop<V> {
    /// The last node.
    prev: Carried<V>,
    /// The event values there.
    g_prev: Vec<f64>,
    /// The end of a step interrupted by a landing event.
    rejoin: Option<f64>,
    /// The length of the last step.
    last_h: Option<f64>,
}

/// One step of [`run`] with everything it records; `Ok(true)` when a stop
/// event ended the run. `before` is the integrator before the step (when
/// something after the step can fail or an event can stop or land).
fn advance<K: Solvable>(
    d: &mut Driver<'_, '_, K>,
    lp: &mut Loop<K::Vector>,
    before: Option<&K::Sim>,
    dense_needed: bool,
    v_each_step: bool,
) -> Result<bool, SolveError> {
    let t_end = d.plan.t_end;
    let has_events = !d.plan.events.is_empty();
    let result = match lp.rejoin.take() {
        Some(t) => K::land(d.sim, t),
        None => K::step_toward(d.sim, t_end, lp.last_h),
    };
    result?;
    d.steps += 1;
    let prev = &mut lp.prev;
    let mut end = d.node(v_each_step)?;
    let mut landed = None;
    if dense_needed {
        let dense = d.interpolant(prev, &mut end)?;
        let mut upto = end.node.t;
        if has_events {
            let (found, stop) = d.crossings(&dense, &prev.node, &end.node, &mut lp.g_prev)?;
            if let Some(k) = stop {
                upto = found[k].t;
                landed = Some((found[k].clone(), end.node.t));
            }
            d.sol.events.extend(found);
        }
        d.keep_saved(&dense, prev.node.t, upto);
    }
    if let Some((record, t_step_end)) = landed {
        // Redo the step from its start so that it ends on the event (the
        // copy stays: what follows can still fail).
        if let Some(before) = before {
            d.sim.clone_from(before);
        }
        K::land(d.sim, record.t)?;
        d.sol.stats.redone_steps += 1;
        end = d.node(true)?;
        // An event at the step's start (to the clock's resolution) lands on
        // the node the step began from: no new node, and its row (if kept)
        // exists already.
        let at_start = end.step == prev.step;
        for i in 0..d.plan.events.len() {
            lp.g_prev[i] = if i == record.event {
                // The side the crossing left g on: the node at t* can
                // differ from the dense output by the local error, and
                // must not count as a second crossing.
                d.g(i, record.t, &record.q, &record.v)?
            } else {
                let n = &end.node;
                d.g(i, n.t, n.q.as_ref(), n.v.as_ref())?
            };
        }
        match d.plan.events[record.event].action {
            Action::Stop if at_start => {
                d.keep_last_good(&mut end);
                d.sol.status = Status::Stopped { event: record.event, t: record.t };
                return Ok(true);
            }
            Action::Stop => {
                finish_node(d, &mut end, true)?;
                d.sol.status = Status::Stopped { event: record.event, t: record.t };
                return Ok(true);
            }
            _ => {
                if t_step_end > record.t {
                    lp.rejoin = Some(t_step_end);
                }
                if at_start {
                    return Ok(false);
                }
            }
        }
    }
    let last = end.node.t >= t_end;
    finish_node(d, &mut end, last)?;
    lp.last_h = Some(end.node.t - prev.node.t);
    *prev = end;
    Ok(false)
}

/// Node rows, observer and energy watch after a step.
fn finish_node<K: Solvable>(
    d: &mut Driver<'_, '_, K>,
    end: &mut Carried<K::Vector>,
    last: bool,
) -> Result<(), SolveError> {
    if d.plan.every > 0 && (last || d.steps.is_multiple_of(d.plan.every as u64)) {
        d.keep_node(end)?;
    }
    d.observe(end, false)?;
    if d.sol.energy_watch.is_some() {
        d.velocity(end)?;
        let e = d.energy(end.node.t, &end.node.q, &end.node.v);
        if let Some(w) = &mut d.sol.energy_watch {
            w.observe(end.node.t, e);
        }
    }
    Ok(())
}

#[cfg(feature = "progress")]
const PROGRESS_UNITS: u64 = 10_000;

#[cfg(feature = "progress")]
fn progress_bar(span: f64) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new(PROGRESS_UNITS);
    let style = indicatif::ProgressStyle::with_template(
        "{bar:40} {percent:>3}% of t ∈ [t0, t0 + {msg}] ({elapsed}, {eta} left)",
    )
    .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar());
    bar.set_style(style);
    bar.set_message(format!("{span}"));
    bar
}

/// Why a solution could not be written or read.
///
/// Rows are counted from 0, the first row after the CSV header (the index
/// of the row in the solution's columns); header columns are counted from 0.
#[cfg(feature = "serde")]
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum TableError {
    /// From the CSV reader or writer (input or output, and text that is not
    /// UTF-8).
    #[error("csv: {0}")]
    Csv(#[from] csv::Error),
    /// From the JSON reader or writer: malformed JSON, a missing field, a
    /// column `q`, `p` or `v` whose rows differ in length, or a value that
    /// is neither a number nor one of the texts of non-finite values (the
    /// message gives the line and column).
    #[error("json: {0}")]
    Json(#[from] serde_json::Error),
    /// Columns of different lengths: `step`, `q` and `p` have one row per
    /// time in `t`, `v` has one too or none (a solution without
    /// velocities), and `energy` has one per row of `v`.
    #[error("column `{column}` has {rows} rows, `{reference}` has {expected}")]
    Length {
        /// The column whose length is wrong (`"step"`, `"q"`, `"p"`, `"v"` or `"energy"`).
        column: &'static str,
        /// Its length.
        rows: usize,
        /// The column it is compared with (`"t"` or, for `energy`, `"v"`).
        reference: &'static str,
        /// The length of that column.
        expected: usize,
    },
    /// Columns `q`, `p` and `v` whose rows differ in width (possible for a
    /// solution built by hand: the fields are public).
    #[error("column `{column}` has rows of {width} values, `q` has rows of {expected}")]
    Width {
        /// The column whose width is wrong (`"p"` or `"v"`).
        column: &'static str,
        /// Its width.
        width: usize,
        /// The width of `q`.
        expected: usize,
    },
    /// A CSV table whose number of columns fits neither layout of a
    /// solution of `N` coordinates: `2 + 2N` columns without velocities
    /// (`t, step, q…, p…`), `3 + 3N` with them (`t, step, q…, p…, v…, energy`).
    #[error("csv: {found} columns fit no solution, which has 2 + 2N without velocities and 3 + 3N with them")]
    Columns {
        /// The number of columns of the header.
        found: usize,
    },
    /// A CSV header whose name at `column` is not the one
    /// [`write_csv`](Solution::write_csv) writes there for the table's
    /// number of coordinates.
    #[error("csv: header column {column} is `{found}`, expected `{expected}`")]
    Header {
        /// The index of the column.
        column: usize,
        /// The name found.
        found: String,
        /// The name expected.
        expected: String,
    },
    /// A CSV row with a number of fields other than the header's.
    #[error("csv: row {row} has {fields} fields, the header has {expected}")]
    Fields {
        /// The index of the row.
        row: usize,
        /// Its number of fields.
        fields: usize,
        /// The number of columns of the header.
        expected: usize,
    },
    /// A CSV field that is not a value of its column: a number (or the text
    /// of a non-finite value) for the values, a node index or nothing for
    /// `step`.
    #[error("csv: row {row}, column `{column}`: `{text}` is not {expected}")]
    Value {
        /// The index of the row.
        row: usize,
        /// The name of the column.
        column: String,
        /// The field.
        text: String,
        /// What the column holds.
        expected: &'static str,
    },
}

#[cfg(feature = "serde")]
impl Solution {
    /// The CSV header of `n` coordinates: `t, step, q0 …, p0 …` and, with
    /// velocities, `v0 …, energy`.
    fn header(n: usize, velocities: bool) -> Vec<String> {
        let mut h = vec!["t".to_string(), "step".to_string()];
        let names: &[&str] = if velocities { &["q", "p", "v"] } else { &["q", "p"] };
        for name in names {
            h.extend((0..n).map(|i| format!("{name}{i}")));
        }
        if velocities {
            h.push("energy".to_string());
        }
        h
    }

    /// Checks that the columns have the lengths of one table (see
    /// [`TableError::Length`]) and that the rows of `p` and `v` are as wide
    /// as those of `q` ([`TableError::Width`]); `true` when the table has
    /// velocities.
    fn check_columns(&self) -> Result<bool, TableError> {
        let rows = self.t.len();
        let length = |column, len, reference, expected| {
            if len == expected { Ok(()) } else { Err(TableError::Length { column, rows: len, reference, expected }) }
        };
        length("step", self.step.len(), "t", rows)?;
        length("q", self.q.len(), "t", rows)?;
        length("p", self.p.len(), "t", rows)?;
        let velocities = !self.v.is_empty();
        if velocities {
            length("v", self.v.len(), "t", rows)?;
        }
        length("energy", self.energy.len(), "v", self.v.len())?;
        let expected = self.q.width();
        for (column, rows) in [("p", &self.p), ("v", &self.v)] {
            if !rows.is_empty() && rows.width() != expected && !self.q.is_empty() {
                return Err(TableError::Width { column, width: rows.width(), expected });
            }
        }
        Ok(velocities)
    }

    /// Writes the rows as CSV: the header `t,step,q0,…,p0,…` and, for a
    /// solution with velocities, `v0,…,energy`; one line per row, an empty
    /// `step` for an interpolated row. Finite numbers are written by the
    /// `csv` crate in their shortest form that reads back to the same `f64`
    /// (`-0.0` and subnormals included); non-finite ones as `inf`, `-inf`,
    /// `NaN` (the quiet NaN `f64::NAN`), `-NaN` (the same with the sign bit
    /// set) and, for any other NaN, `NaN:0x` and the 16 hexadecimal digits
    /// of its bits, so that [`read_csv`](Self::read_csv) gets every value
    /// back bit for bit. Events, statistics and status are not part of the
    /// table (see [`write_json`](Self::write_json)).
    ///
    /// A solution whose columns differ in length or width (possible for one
    /// built by hand: the fields are public) is refused with
    /// [`TableError::Length`] or [`TableError::Width`] before anything is
    /// written.
    pub fn write_csv<W: std::io::Write>(&self, w: W) -> Result<(), TableError> {
        use crate::serde_arrays::{Float, Seq};
        let velocities = self.check_columns()?;
        let mut out = csv::Writer::from_writer(w);
        out.write_record(Self::header(self.width(), velocities))?;
        for i in 0..self.len() {
            let (t, step, q, p) = (Float(self.t[i]), self.step[i], Seq(&self.q[i]), Seq(&self.p[i]));
            if velocities {
                out.serialize((t, step, q, p, Seq(&self.v[i]), Float(self.energy[i])))?;
            } else {
                out.serialize((t, step, q, p))?;
            }
        }
        out.flush().map_err(csv::Error::from)?;
        Ok(())
    }

    /// Reads a table written by [`write_csv`](Self::write_csv) (status
    /// `Finished`, no events, zero statistics: the table holds only rows).
    ///
    /// The number of coordinates `N` comes from the header: `2 + 2N`
    /// columns without velocities, `3 + 3N` with them (where both fit, the
    /// table has velocities when its last column is named `energy`; a
    /// number of columns that fits neither is [`TableError::Columns`]). The header must be the one
    /// `write_csv` writes for `N` coordinates ([`TableError::Header`]);
    /// every row must have as many fields as the header
    /// ([`TableError::Fields`]: no ragged rows); every value must be a
    /// finite number or one of the texts `write_csv` writes for non-finite
    /// values, and a `step` a node index or empty ([`TableError::Value`],
    /// with the row and the column).
    pub fn read_csv<R: std::io::Read>(r: R) -> Result<Self, TableError> {
        let mut input = csv::ReaderBuilder::new().flexible(true).from_reader(r);
        let header = input.headers()?.clone();
        let found = header.len();
        let with = found >= 3 && (found - 3).is_multiple_of(3);
        let without = found >= 2 && (found - 2).is_multiple_of(2);
        // Where both layouts fit (6, 12, … columns) the last name decides.
        let velocities = match (with, without) {
            (true, true) => header.iter().next_back() == Some("energy"),
            (with, false) => with,
            (false, true) => false,
        };
        if !(with || without) {
            return Err(TableError::Columns { found });
        }
        let n = if velocities { (found - 3) / 3 } else { (found - 2) / 2 };
        let names = Self::header(n, velocities);
        for (column, (found, expected)) in header.iter().zip(&names).enumerate() {
            if found != expected {
                return Err(TableError::Header { column, found: found.to_string(), expected: expected.clone() });
            }
        }
        let mut sol = Self::empty(n);
        let (mut q, mut p, mut v) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        for (row, record) in input.records().enumerate() {
            let record = record?;
            if record.len() != names.len() {
                return Err(TableError::Fields { row, fields: record.len(), expected: names.len() });
            }
            let wrong = |column: usize, expected| TableError::Value {
                row,
                column: names[column].clone(),
                text: record[column].to_string(),
                expected,
            };
            let value =
                |column: usize| crate::serde_arrays::parse(&record[column]).ok_or_else(|| wrong(column, "a number"));
            let values = |first: usize, x: &mut [f64]| -> Result<(), TableError> {
                for (i, x) in x.iter_mut().enumerate() {
                    *x = value(first + i)?;
                }
                Ok(())
            };
            let t = value(0)?;
            let step = match &record[1] {
                "" => None,
                text => Some(text.parse::<u64>().map_err(|_| wrong(1, "a node index or empty"))?),
            };
            values(2, &mut q)?;
            values(2 + n, &mut p)?;
            let energy = if velocities {
                values(2 + 2 * n, &mut v)?;
                Some(value(2 + 3 * n)?)
            } else {
                None
            };
            sol.push(step, t, &q, &p, energy.map(|e| (&v[..], e)));
        }
        Ok(sol)
    }

    /// Writes the whole solution (rows, events, statistics, status) as JSON.
    /// Finite numbers are written in their shortest form that reads back to
    /// the same `f64`; non-finite ones (JSON has no literal for them) as the
    /// strings `"inf"`, `"-inf"`, `"NaN"` (the quiet NaN `f64::NAN`),
    /// `"-NaN"` (the same with the sign bit set) and, for any other NaN,
    /// `"NaN:0x"` and the 16 hexadecimal digits of its bits, so that
    /// [`read_json`](Self::read_json) gets every value back bit for bit. The
    /// same holds for the solution's `Serialize` in any human-readable serde
    /// format; binary formats carry the `f64` itself.
    ///
    /// A solution whose columns differ in length or width (possible for one
    /// built by hand: the fields are public) is refused with
    /// [`TableError::Length`] or [`TableError::Width`] before anything is
    /// written.
    pub fn write_json<W: std::io::Write>(&self, w: W) -> Result<(), TableError> {
        self.check_columns()?;
        Ok(serde_json::to_writer(w, self)?)
    }

    /// Reads a solution written by [`write_json`](Self::write_json); the
    /// typed [`error`](Self::error) of a failed run comes back as `None`
    /// (its message is in the status).
    ///
    /// Values must be numbers or the strings `write_json` writes for
    /// non-finite values, and the rows of each of `q`, `p` and `v` must
    /// have one length ([`TableError::Json`]: no ragged rows); the columns
    /// must have the lengths of one table ([`TableError::Length`]), and `p`
    /// and `v` rows as wide as `q`'s ([`TableError::Width`]). The number of
    /// coordinates is the width of the rows read.
    pub fn read_json<R: std::io::Read>(r: R) -> Result<Self, TableError> {
        let sol: Self = serde_json::from_reader(r)?;
        sol.check_columns()?;
        Ok(sol)
    }
}
