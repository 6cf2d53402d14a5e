//! One stepper for every [`Scheme`]: an enum over the drivers, each a
//! const-generic fast path, matched once per call.
//!
//! The enum lives in one box per stepper (no virtual call): a step of the
//! pendulum's midpoint rule through [`Stepper`] is the integrator's own step
//! behind one pointer and one `match` on the variant. Copies of a stepper
//! go through a function of their own per kind of driver, so that no frame
//! holds room for every kind at once.

use super::composed::{Composed, ConstSubSteps, SubSteps};
use super::extend::Extended;
use super::scheme::Scheme;
use super::support::Policy;
use crate::dense::{DenseStep, GalerkinPolynomial, Hermite, Node};
use crate::dim::{Dim, Dimension};
use crate::discrete::{AlphaBeta, Midpoint, Trapezoid};
use crate::error::Error;
use crate::galerkin::Galerkin;
use crate::integrator::{Clock, Composition, F64Readouts, Integrator, Stats};
use crate::mechanics::DiscreteMechanics;
use crate::solution::{Plan, Solution, SolveError, Stepping};
use crate::state::State;
use crate::system::Lagrangian;
use crate::time_transform::{ExplicitAdaptive, SplittingStats};

/// The driver behind a [`Stepper`].
// The variants differ by their Galerkin tables (the collocation tables grow
// with `R²`) and kept sub-steps; a stepper boxes the whole enum once, so
// boxing each variant as well would buy only a second indirection per step.
#[allow(clippy::large_enum_variant)]
pub enum Driver<S: Lagrangian<N> + Clone, const N: usize>
where
    Dim<N>: Extended<N>,
{
    Midpoint(Integrator<S, Midpoint, N>),
    Trapezoid(Integrator<S, Trapezoid, N>),
    AlphaBeta(Integrator<S, AlphaBeta, N>),
    Gauss2(Integrator<S, Galerkin<2, 2>, N>),
    Gauss3(Integrator<S, Galerkin<3, 3>, N>),
    Gauss4(Integrator<S, Galerkin<4, 4>, N>),
    Gauss5(Integrator<S, Galerkin<5, 5>, N>),
    Gauss6(Integrator<S, Galerkin<6, 6>, N>),
    Gauss7(Integrator<S, Galerkin<7, 7>, N>),
    Gauss8(Integrator<S, Galerkin<8, 8>, N>),
    Lobatto2(Integrator<S, Galerkin<2, 3>, N>),
    Lobatto3(Integrator<S, Galerkin<3, 4>, N>),
    Lobatto4(Integrator<S, Galerkin<4, 5>, N>),
    Composition(Integrator<S, Composition, N>),
    Composed(Composed<DriverBox<S, N>>),
    Transformed(<Dim<N> as Extended<N>>::Transformed<S>),
    Splitting(ExplicitAdaptive<S, f64, N>),
}

/// Runs `$body` with `$d` bound to the driver of whichever variant `$x` is;
/// with `$d, $variant =>`, also binds `$variant` to that variant's
/// constructor (a function from its driver to a [`Driver`]); with
/// `($x, $y), $a, $b => $body, else $other`, runs `$body` with both drivers
/// bound when `$x` and `$y` are the same variant and `$other` when not.
macro_rules! each {
    ($($form:tt)*) => {
        each_of!(($($form)*) Midpoint Trapezoid AlphaBeta Gauss2 Gauss3 Gauss4 Gauss5 Gauss6 Gauss7 Gauss8 Lobatto2 Lobatto3 Lobatto4
            Composition Composed Transformed Splitting)
    };
}

/// [`each!`] over the list of variants it names (the one list of them).
macro_rules! each_of {
    (($x:expr, $d:ident => $body:expr) $($v:ident)*) => {
        match $x {
            $(Driver::$v($d) => $body,)*
        }
    };
    (($x:expr, $d:ident, $variant:ident => $body:expr) $($v:ident)*) => {
        match $x {
            $(Driver::$v($d) => {
                let $variant = Driver::$v;
                $body
            })*
        }
    };
    ((($x:expr, $y:expr), $a:ident, $b:ident => $body:expr, else $other:expr) $($v:ident)*) => {
        match ($x, $y) {
            $((Driver::$v($a), Driver::$v($b)) => $body,)*
            _ => $other,
        }
    };
}

/// `wrap(d)` built on the heap (a driver is large: 300 kB at `N = 1000`),
/// as a function for `Result::map`.
pub(super) fn boxed<S: Lagrangian<N> + Clone, T, const N: usize>(
    wrap: fn(T) -> Driver<S, N>,
) -> impl FnOnce(T) -> Box<Driver<S, N>>
where
    Dim<N>: Extended<N>,
{
    move |d| Box::new(wrap(d))
}

/// A copy of `d` wrapped by `wrap` on the heap, made by a function of its
/// own for each kind of driver: a frame that copies any kind holds room for
/// every kind at once (1 MB at `N = 1000`), this one for its own only.
#[inline(never)]
fn boxed_copy<S: Lagrangian<N> + Clone, T: Clone, const N: usize>(
    d: &T,
    wrap: fn(T) -> Driver<S, N>,
) -> Box<Driver<S, N>>
where
    Dim<N>: Extended<N>,
{
    boxed(wrap)(d.clone())
}

/// `a` made a copy of `b` in place (a function of its own for each kind of
/// driver, as [`boxed_copy`]).
#[inline(never)]
fn copy_into<T: Clone>(a: &mut T, b: &T) {
    a.clone_from(b);
}

/// One step of one kind of driver, in a function of its own: the driver's
/// whole step is inlined into it, as into a loop over a driver named
/// directly, where inlining every kind into the one `match` of
/// [`Stepper::step`] would exhaust the inliner's budget and leave parts of
/// the step out of line.
#[inline(never)]
pub(super) fn step_of<D: Stepping<N>, const N: usize>(d: &mut D) -> Result<(), Error> {
    d.step()
}

/// The interpolant of one step of a [`Stepper`]: the cubic Hermite, or a
/// Galerkin step's own polynomial.
#[derive(Clone, Debug)]
pub enum Interpolant<const N: usize> {
    /// The cubic Hermite through both nodes.
    Hermite(Hermite<N>),
    /// The step polynomial of degree 2.
    Galerkin2(GalerkinPolynomial<N, 2>),
    /// The step polynomial of degree 3.
    Galerkin3(GalerkinPolynomial<N, 3>),
    /// The step polynomial of degree 4.
    Galerkin4(GalerkinPolynomial<N, 4>),
    /// The step polynomial of degree 5.
    Galerkin5(GalerkinPolynomial<N, 5>),
    /// The step polynomial of degree 6.
    Galerkin6(GalerkinPolynomial<N, 6>),
    /// The step polynomial of degree 7.
    Galerkin7(GalerkinPolynomial<N, 7>),
    /// The step polynomial of degree 8.
    Galerkin8(GalerkinPolynomial<N, 8>),
}

impl<const N: usize> DenseStep<N> for Interpolant<N> {
    fn t0(&self) -> f64 {
        match self {
            Self::Hermite(p) => p.t0(),
            Self::Galerkin2(p) => p.t0(),
            Self::Galerkin3(p) => p.t0(),
            Self::Galerkin4(p) => p.t0(),
            Self::Galerkin5(p) => p.t0(),
            Self::Galerkin6(p) => p.t0(),
            Self::Galerkin7(p) => p.t0(),
            Self::Galerkin8(p) => p.t0(),
        }
    }

    fn t1(&self) -> f64 {
        match self {
            Self::Hermite(p) => p.t1(),
            Self::Galerkin2(p) => p.t1(),
            Self::Galerkin3(p) => p.t1(),
            Self::Galerkin4(p) => p.t1(),
            Self::Galerkin5(p) => p.t1(),
            Self::Galerkin6(p) => p.t1(),
            Self::Galerkin7(p) => p.t1(),
            Self::Galerkin8(p) => p.t1(),
        }
    }

    fn eval(&self, t: f64) -> ([f64; N], [f64; N]) {
        match self {
            Self::Hermite(p) => p.eval(t),
            Self::Galerkin2(p) => p.eval(t),
            Self::Galerkin3(p) => p.eval(t),
            Self::Galerkin4(p) => p.eval(t),
            Self::Galerkin5(p) => p.eval(t),
            Self::Galerkin6(p) => p.eval(t),
            Self::Galerkin7(p) => p.eval(t),
            Self::Galerkin8(p) => p.eval(t),
        }
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

/// Whichever driver as the base of a composition ([`Composed`]).
impl<S: Lagrangian<N> + Clone, const N: usize> SubSteps for DriverBox<S, N>
where
    Dim<N>: Extended<N>,
{
    fn sub_step(&mut self, h: f64, t1: f64) -> Result<(), Error> {
        match &mut *self.0 {
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

    fn time(&self) -> f64 {
        each!(&*self.0, d => Stepping::state(d).t)
    }
}

/// The readouts of whichever driver as the base of a composition.
impl<S: Lagrangian<N> + Clone, const N: usize> ConstSubSteps<N> for DriverBox<S, N>
where
    Dim<N>: Extended<N>,
{
    type System = S;

    fn system(&self) -> &S {
        each!(&*self.0, d => Stepping::system(d))
    }

    fn state(&self) -> State<N> {
        each!(&*self.0, d => Stepping::state(d))
    }

    fn velocity(&self) -> Result<[f64; N], Error> {
        each!(&*self.0, d => Stepping::velocity(d))
    }

    fn stats(&self) -> Stats {
        each!(&*self.0, d => Stepping::stats(d))
    }
}

/// A system at a size, with the driver that steps it there: implemented
/// for every [`Lagrangian<N>`] at [`Dim<N>`] (the const-generic drivers)
/// and every [`DynLagrangian`](crate::DynLagrangian) at
/// [`Dyn`](crate::dim::Dyn) (the reverse-mode driver on a tape). It is what
/// lets one [`Stepper`] type serve both sizes; users never implement it.
pub trait Steppable<Z: Dimension> {
    /// The driver behind a [`Stepper`] at this size.
    type Driver: Clone;
}

impl<S: Lagrangian<N> + Clone, const N: usize> Steppable<Dim<N>> for S
where
    Dim<N>: Extended<N>,
{
    type Driver = DriverBox<S, N>;
}

/// The compile-time-sized driver on the heap: a driver of a large system is
/// large (300 kB at `N = 1000`), and `solve` keeps a copy of the stepper
/// from before each step; one pointer to follow per step costs nothing
/// beside a step.
pub struct DriverBox<S: Lagrangian<N> + Clone, const N: usize>(pub(super) Box<Driver<S, N>>)
where
    Dim<N>: Extended<N>;

impl<S: Lagrangian<N> + Clone, const N: usize> core::ops::Deref for DriverBox<S, N>
where
    Dim<N>: Extended<N>,
{
    type Target = Driver<S, N>;
    #[inline(always)]
    fn deref(&self) -> &Driver<S, N> {
        &self.0
    }
}

impl<S: Lagrangian<N> + Clone, const N: usize> core::ops::DerefMut for DriverBox<S, N>
where
    Dim<N>: Extended<N>,
{
    #[inline(always)]
    fn deref_mut(&mut self) -> &mut Driver<S, N> {
        &mut self.0
    }
}

impl<S: Lagrangian<N> + Clone, const N: usize> Clone for DriverBox<S, N>
where
    Dim<N>: Extended<N>,
{
    fn clone(&self) -> Self {
        Self(each!(&*self.0, d, variant => boxed_copy(d, variant)))
    }

    /// In place when both drivers are of one kind: no allocation.
    fn clone_from(&mut self, source: &Self) {
        each!((&mut *self.0, &*source.0), a, b => copy_into(a, b), else *self = source.clone());
    }
}

impl<S: Lagrangian<N> + Clone, const N: usize> core::fmt::Debug for DriverBox<S, N>
where
    Dim<N>: Extended<N>,
{
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Driver").field("state", &each!(&*self.0, d => Stepping::state(d))).finish()
    }
}

/// A running integration of a [`Problem`](super::Problem) with any
/// [`Scheme`]: step by step, to exact targets, or to a [`Solution`] by
/// [`solve`](Self::solve), with one error type, [`Error`]. One type for
/// both sizes, with the same methods and meanings: `Stepper<S, Dim<N>>` of
/// a compile-time-sized system, a [`Stepping<N>`], and `Stepper<S, Dyn>` of
/// a run-time-sized one, a [`RunTimeStepping`](crate::RunTimeStepping).
/// The storage follows the size, as `nalgebra`'s types do: arrays
/// `[f64; N]` on the stack at `Dim<N>` ([`State<N>`] by value), vectors
/// on the heap at `Dyn` ([`PhasePoint`](crate::PhasePoint) by reference).
///
/// `state()` has one meaning for every scheme at both sizes: the node
/// `(k, t_k, q_k, p_k)` in physical time with the physical momenta, `k`
/// counting steps (in `s` for the time-transformed schemes, whose
/// `t_k` is the target exactly after a landing).
///
/// A failed step leaves the stepper as it was (each driver's own
/// guarantee), so a retry starts from the state the error carries.
pub struct Stepper<S: Steppable<Z>, Z: Dimension> {
    pub(super) driver: S::Driver,
    pub(super) scheme: Scheme,
    pub(super) policy: Policy,
}

impl<S: Steppable<Z>, Z: Dimension> Clone for Stepper<S, Z> {
    fn clone(&self) -> Self {
        Self { driver: self.driver.clone(), scheme: self.scheme.clone(), policy: self.policy }
    }

    /// In place where the driver copies in place.
    fn clone_from(&mut self, source: &Self) {
        self.driver.clone_from(&source.driver);
        // A composition's or a time transformation's scheme holds its base in
        // a box: copied only when it differs, `solve`'s refresh of its copy
        // before every step allocates nothing.
        if self.scheme != source.scheme {
            self.scheme.clone_from(&source.scheme);
        }
        self.policy = source.policy;
    }
}

impl<S: Steppable<Z>, Z: Dimension> core::fmt::Debug for Stepper<S, Z>
where
    S::Driver: core::fmt::Debug,
{
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Stepper")
            .field("scheme", &self.scheme)
            .field("policy", &self.policy)
            .field("driver", &self.driver)
            .finish()
    }
}

impl<S: Steppable<Z>, Z: Dimension> Stepper<S, Z> {
    /// The method.
    pub fn scheme(&self) -> &Scheme {
        &self.scheme
    }

    /// The step policy.
    pub fn policy(&self) -> Policy {
        self.policy
    }
}

impl<S: Lagrangian<N> + Clone, const N: usize> Stepper<S, Dim<N>>
where
    Dim<N>: Extended<N>,
{
    /// The state `(k, t_k, q_k, p_k)` at the current node (physical time
    /// and momenta for the time-transformed schemes; `k` counts their steps
    /// in `s`).
    pub fn state(&self) -> State<N> {
        Stepping::state(self)
    }

    /// The momenta `p_k` at the current node.
    pub fn momenta(&self) -> [f64; N] {
        Stepping::state(self).p
    }

    /// The velocity whose momentum is `p_k`.
    pub fn velocity(&self) -> Result<[f64; N], Error> {
        Stepping::velocity(self)
    }

    /// The energy `E_L(t_k, q_k, v_k)` at the current node, with `v_k` the
    /// velocity of `p_k`: one meaning for every scheme.
    pub fn energy(&self) -> Result<f64, Error> {
        let s = Stepping::state(self);
        let v = Stepping::velocity(self)?;
        Ok(Stepping::system(self).energy(s.t, s.q, v))
    }

    /// Work counters (steps; Newton iterations of the implicit schemes).
    pub fn stats(&self) -> Stats {
        Stepping::stats(self)
    }

    /// The system.
    pub fn system(&self) -> &S {
        Stepping::system(self)
    }

    /// The explicit splitting's own counters (gradient evaluations, landing
    /// trials); `None` for the other schemes.
    pub fn splitting_stats(&self) -> Option<SplittingStats> {
        match &*self.driver {
            Driver::Splitting(d) => Some(d.stats()),
            _ => None,
        }
    }

    /// One step; on failure nothing changes.
    #[inline(always)]
    pub fn step(&mut self) -> Result<State<N>, Error> {
        // One match for the step and the state read after it.
        each!(&mut *self.driver, d => {
            step_of(d)?;
            Ok(Stepping::state(d))
        })
    }

    /// `n` steps, calling `observe` after each.
    pub fn run(&mut self, n: usize, mut observe: impl FnMut(&Self)) -> Result<(), Error> {
        for _ in 0..n {
            Stepping::step(self)?;
            observe(self);
        }
        Ok(())
    }

    /// Steps to `t_end` exactly: the last step is shortened (or, for the
    /// time-transformed schemes, a partial step in `s` is solved for) so
    /// that the node's time is `t_end`.
    pub fn run_until(&mut self, t_end: f64) -> Result<(), Error> {
        Stepping::land(self, t_end)
    }

    /// Integrates as `plan` says: [`Stepping::solve`], named here so that
    /// the trait need not be in scope.
    pub fn solve(&mut self, plan: Plan<'_>) -> Result<Solution, SolveError> {
        Stepping::solve(self, plan)
    }
}

impl<S: Lagrangian<N> + Clone, const N: usize> Stepping<N> for Stepper<S, Dim<N>>
where
    Dim<N>: Extended<N>,
{
    type System = S;
    type Native = Interpolant<N>;

    fn system(&self) -> &S {
        each!(&*self.driver, d => Stepping::system(d))
    }

    fn state(&self) -> State<N> {
        each!(&*self.driver, d => Stepping::state(d))
    }

    fn velocity(&self) -> Result<[f64; N], Error> {
        each!(&*self.driver, d => Stepping::velocity(d))
    }

    fn stats(&self) -> Stats {
        each!(&*self.driver, d => Stepping::stats(d))
    }

    #[inline(always)]
    fn step(&mut self) -> Result<(), Error> {
        each!(&mut *self.driver, d => step_of(d))
    }

    fn step_toward(&mut self, t_end: f64, last_h: Option<f64>) -> Result<(), Error> {
        each!(&mut *self.driver, d => Stepping::step_toward(d, t_end, last_h))
    }

    fn land(&mut self, t: f64) -> Result<(), Error> {
        each!(&mut *self.driver, d => Stepping::land(d, t))
    }

    fn native(&self, start: &Node<N>, end: &Node<N>) -> Interpolant<N> {
        match &*self.driver {
            Driver::Gauss2(d) => Interpolant::Galerkin2(Stepping::native(d, start, end)),
            Driver::Gauss3(d) => Interpolant::Galerkin3(Stepping::native(d, start, end)),
            Driver::Gauss4(d) => Interpolant::Galerkin4(Stepping::native(d, start, end)),
            Driver::Gauss5(d) => Interpolant::Galerkin5(Stepping::native(d, start, end)),
            Driver::Gauss6(d) => Interpolant::Galerkin6(Stepping::native(d, start, end)),
            Driver::Gauss7(d) => Interpolant::Galerkin7(Stepping::native(d, start, end)),
            Driver::Gauss8(d) => Interpolant::Galerkin8(Stepping::native(d, start, end)),
            Driver::Lobatto2(d) => Interpolant::Galerkin2(Stepping::native(d, start, end)),
            Driver::Lobatto3(d) => Interpolant::Galerkin3(Stepping::native(d, start, end)),
            Driver::Lobatto4(d) => Interpolant::Galerkin4(Stepping::native(d, start, end)),
            Driver::Midpoint(d) => Interpolant::Hermite(Stepping::native(d, start, end)),
            Driver::Trapezoid(d) => Interpolant::Hermite(Stepping::native(d, start, end)),
            Driver::AlphaBeta(d) => Interpolant::Hermite(Stepping::native(d, start, end)),
            Driver::Composition(d) => Interpolant::Hermite(Stepping::native(d, start, end)),
            Driver::Composed(d) => Interpolant::Hermite(Stepping::native(d, start, end)),
            Driver::Transformed(d) => Interpolant::Hermite(Stepping::native(d, start, end)),
            Driver::Splitting(d) => Interpolant::Hermite(Stepping::native(d, start, end)),
        }
    }
}
