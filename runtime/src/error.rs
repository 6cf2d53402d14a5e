//! The error type of the runtime: every failure is a value, never a panic.

use crate::newton::NewtonFailure;
use crate::real::Real;
use crate::state::{PhasePoint, State};

/// What went wrong, with the state the integrator was left in and the
/// diagnostics of the failed solve: the one error type of stepping, for
/// every driver and every system size.
///
/// A failed step leaves the integrator exactly as it was before the step, so
/// `state` is also the state a retry starts from (for example after
/// [`Integrator::set_step_size`](crate::Integrator::set_step_size)). The
/// state is a [`PhasePoint`], sized at run time, so that the errors of
/// systems with different numbers of coordinates (and of the run-time-sized
/// drivers) are one type and `?` gathers them into one `Result`;
/// `State::try_from(state)` gives the const-size [`State`] back. `T` is the
/// real type of that state (`f64` but for a
/// [`GalerkinIntegrator`](crate::GalerkinIntegrator) run in extended precision);
/// diagnostics such as step sizes and residual norms are always `f64`.
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
/// use lagrangian_runtime::{Error, Integrator, Midpoint, State};
///
/// let mut sim = Integrator::new(Oscillator, Midpoint, 0.1).start(0.0, [1.0], [0.0])?;
/// sim.run(10, |_| {})?;
/// match sim.run_until(f64::NAN, |_| {}) {
///     Err(Error::InvalidTarget { state, .. }) => {
///         let state: State<1> = state.try_into()?;
///         assert_eq!(state, *sim.state());
///     }
///     other => panic!("{other:?}"),
/// }
/// # Ok::<(), Error>(())
/// ```
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum Error<T: Real = f64> {
    /// Newton's method reached its iteration cap, or its corrections grew twice in a row.
    #[error(
        "newton did not converge in the step from t = {} (step {}, h = {h:e}): {iterations} iterations, residual norm {residual_norm:e}, last correction {correction_norm:e}",
        .state.t, .state.step
    )]
    NewtonDidNotConverge {
        /// The state the step started from (and the integrator still holds).
        state: PhasePoint<T>,
        /// The step size that was tried.
        h: f64,
        /// Newton iterations spent.
        iterations: usize,
        /// `‖R‖∞` at the last iterate.
        residual_norm: f64,
        /// `‖Δ‖∞` of the last correction.
        correction_norm: f64,
    },
    /// The Newton Jacobian `∂²A/∂q_k∂q_{k+1}` (the discrete Legendre transform)
    /// is singular or too ill-conditioned to invert.
    #[error(
        "singular or ill-conditioned jacobian in the step from t = {} (step {}, h = {h:e}) at iteration {iterations}: reciprocal condition number {rcond:e}",
        .state.t, .state.step
    )]
    SingularJacobian {
        /// The state the step started from (and the integrator still holds).
        state: PhasePoint<T>,
        /// The step size that was tried.
        h: f64,
        /// The Newton iteration at which it happened.
        iterations: usize,
        /// Estimated reciprocal condition number in the 1-norm (0 if exactly singular).
        rcond: f64,
    },
    /// A NaN or an infinity appeared.
    #[error(
        "non-finite {quantity} in the step from t = {} (step {}, h = {h:e}) at iteration {iterations}",
        .state.t, .state.step
    )]
    NonFinite {
        /// The state the step started from (and the integrator still holds).
        state: PhasePoint<T>,
        /// The step size that was tried.
        h: f64,
        /// The Newton iteration at which it happened (0: after convergence).
        iterations: usize,
        /// Which value: `residual`, `jacobian`, `correction`, `position` or `momentum`.
        quantity: &'static str,
    },
    /// The step was refused: for variable steps, the energy equation has no
    /// acceptable root (`h ≤ 0`, outside `[h_min, h_max]`, or changing faster
    /// than the allowed ratio).
    #[error(
        "step rejected from t = {} (step {}, h = {h:e}) after {iterations} iterations: {reason}",
        .state.t, .state.step
    )]
    StepRejected {
        /// The state the step started from (and the integrator still holds).
        state: PhasePoint<T>,
        /// The last step size tried.
        h: f64,
        /// Newton iterations spent.
        iterations: usize,
        /// Why.
        reason: &'static str,
    },
    /// Variable steps: no step size in the admissible bracket satisfies the
    /// energy equation (docs/theory.md §9). The energy equation fixes `h` only
    /// through the `O(h²)` energy error of the discrete Lagrangian, and where
    /// the factor that sets the step density changes sign (Luo, Guo, Li & Wu §IV) its
    /// root disappears. Retry with a smaller `h`, wider bounds, a fixed step,
    /// or [`EnergyFallback::LeastSquares`](crate::EnergyFallback::LeastSquares).
    #[error(
        "no step size in [{h_lo:e}, {h_hi:e}] solves the energy equation from t = {} (step {}): the least relative energy mismatch is {mismatch:e}, at h = {h_best:e} ({iterations} newton iterations){}",
        .state.t, .state.step, root_test_text(.root_test)
    )]
    NoEnergyStep {
        /// The state the step started from (and the integrator still holds).
        state: PhasePoint<T>,
        /// The smallest admissible step.
        h_lo: f64,
        /// The largest admissible step.
        h_hi: f64,
        /// The admissible step with the least energy mismatch.
        h_best: f64,
        /// `|E_{k+1} − E_k| / |E_k|` at `h_best`.
        mismatch: f64,
        /// Newton iterations spent on the DEL solves of the search.
        iterations: usize,
        /// The local root test at the state, for the midpoint and trapezoid
        /// rules (`None` otherwise): `(x, low, high)` with
        /// `x = a₂(z_k) / (a₃ h_{k−1})`, where `Ê(h) ≈ H + a₂h² + a₃h³` is the
        /// energy of a step of size `h` from the node (`a₃` by a difference of
        /// `a₂` across the last step). The local model of the energy equation
        /// has an admissible root iff `x ≥ high` or `x ≤ low`; `low < x < high`
        /// means the leading energy-error coefficient is about to change sign
        /// along the orbit. Derived in the theory notes on energy steps.
        root_test: Option<(f64, f64, f64)>,
    },
    /// A step size that is zero, negative or not finite.
    #[error("invalid step size h = {h}: it must be finite and positive")]
    InvalidStepSize {
        /// The rejected step size.
        h: f64,
    },
    /// Initial data (`q0`, `v0`) or a state (`q`, `p`) whose length is not
    /// the system's number of coordinates.
    #[error("`{what}` has {found} entries, but the system has {expected} coordinates")]
    WrongLength {
        /// Which argument: `q0`, `v0`, `q` or `p`.
        what: &'static str,
        /// The number of coordinates of the system.
        expected: usize,
        /// The length given.
        found: usize,
    },
    /// Variable-step bounds that are not finite, not positive, `h_min > h_max`,
    /// a ratio that is not finite and above 1, or an accuracy outside `(0, 1)`.
    #[error(
        "invalid step bounds h_min = {h_min}, h_max = {h_max}, max_ratio = {max_ratio}: need 0 < h_min ≤ h_max, both finite, 1 < max_ratio < ∞ and an accuracy, if any, in (0, 1)"
    )]
    InvalidStepBounds {
        /// The rejected lower bound.
        h_min: f64,
        /// The rejected upper bound.
        h_max: f64,
        /// The rejected ratio.
        max_ratio: f64,
    },
    /// Initial data that cannot start an integration.
    #[error("invalid initial data: {reason}")]
    InvalidInitialData {
        /// What is wrong with it.
        reason: &'static str,
    },
    /// Newton settings that cannot work: a tolerance that is not finite and
    /// positive (or `atol` negative), no iteration allowed, or a condition
    /// threshold outside `[0, 1)`.
    #[error("invalid newton options: {reason}")]
    InvalidNewtonOptions {
        /// What is wrong with them.
        reason: &'static str,
    },
    /// A target time behind the current time, or not finite.
    #[error("invalid target time {target}: the integrator is at t = {}", .state.t)]
    InvalidTarget {
        /// The rejected target time.
        target: f64,
        /// The current state.
        state: PhasePoint<T>,
    },
    /// A discrete Lagrangian that cannot define a step: a Galerkin method of
    /// degree 0, or with a quadrature that is invalid or too weak for its degree.
    #[error("invalid discrete lagrangian: {reason}")]
    InvalidMethod {
        /// What is wrong with it.
        reason: &'static str,
    },
    /// The system uses a feature the runtime does not integrate yet.
    #[error("not supported yet: {what}")]
    Unsupported {
        /// What is missing.
        what: &'static str,
    },
    /// Time-transformed steps: the step density `g = dt/ds` is not finite
    /// and positive at the state or inside the step from it.
    #[error("the step density g = {value} is not finite and positive (step from t = {})", .state.t)]
    InvalidDensity {
        /// The physical state the integrator holds.
        state: PhasePoint<T>,
        /// The offending value of `g`.
        value: f64,
    },
    /// Time-transformed steps: a step in `s` advanced time by less than the
    /// floor (or not at all): the monitor makes the steps collapse.
    #[error("the step from t = {} advanced time by {dt:e}, below the floor {floor:e}", .state.t)]
    TimeStepCollapsed {
        /// The physical state the integrator holds.
        state: PhasePoint<T>,
        /// The time the refused step advanced.
        dt: f64,
        /// The smallest time step allowed.
        floor: f64,
    },
    /// Time-transformed steps: the search for the partial step in `s` that
    /// ends on the target time did not converge.
    #[error("no step in s found that lands on t = {target}: the closest reached {reached}")]
    Landing {
        /// The target.
        target: f64,
        /// The closest time reached.
        reached: f64,
    },
    /// The explicit time-transformed splitting: the system is not of the
    /// form `½ vᵀMv − V(t, q)` with a constant, regular `M` that it needs.
    #[error("not separable: {reason}")]
    NotSeparable {
        /// The requirement that is not met.
        reason: &'static str,
    },
    /// The explicit time-transformed splitting: an argument of `f'` was not
    /// finite and positive inside a step: the shift `c` is too small for the
    /// energy reached (a time-dependent `V` can raise it), or the state is
    /// not finite.
    #[error("the argument {which:?} of f' is {value}, not finite and positive (step from t = {})", .state.t)]
    TimeFunctionArgument {
        /// The physical state the integrator holds.
        state: PhasePoint<T>,
        /// Which argument.
        which: Argument,
        /// Its value.
        value: f64,
    },
    /// A time-transformed step lost the orbit: the rate `dt/ds` it took
    /// left the step density by more than a factor 2 against the rate at
    /// its start. On the exact flow the rate equals the density (on the
    /// level set of the transformed Hamiltonian that the start puts the
    /// orbit on), so such a step has an energy error as large as the energy
    /// scale itself: `σ` is far too large for this part of the orbit, the
    /// step's Newton solve converged to a spurious root, or the orbit runs
    /// into a singularity that the time transformation does not regularise
    /// (a collision with `α < 1` on Kepler).
    ///
    /// The explicit splitting compares its drift's rate `f'(T + p_t + c)`
    /// with its kick's `f'(c − V)`; the implicit driver compares `t'/g`,
    /// which is `1 + c·u` with `u = p_t + E` and `c` the penalty.
    #[error(
        "the step from t = {} lost the orbit: its rate dt/ds against the step density's changed by a factor {factor:e} (1 on the exact flow, at most 2 allowed): the step σ is too large here, the step converged to a spurious root, or the orbit meets a singularity that the time transformation does not regularise",
        .state.t
    )]
    OrbitLost {
        /// The physical state the integrator holds.
        state: PhasePoint<T>,
        /// The ratio of the rates at the failing point divided by that at
        /// the start (outside `[1/2, 2]`, or NaN).
        factor: f64,
    },
    /// A setting of the driver that cannot work (a penalty, a time-step
    /// floor, a shift of a time transformation).
    #[error("invalid setting: {reason}")]
    InvalidSetting {
        /// What is wrong with it.
        reason: &'static str,
    },
    /// A tolerance of a tolerance-driven solve ([`Auto`](crate::auto::Auto))
    /// that is NaN, not positive, or not below 1 (relative), or an absolute
    /// tolerance that is negative or not finite.
    #[error("invalid tolerance {value}: {reason}")]
    InvalidTolerance {
        /// The rejected value.
        value: f64,
        /// What is wrong with it.
        reason: &'static str,
    },
    /// A span of a tolerance-driven solve that is empty, reversed or not finite.
    #[error("invalid span from t0 = {t0} to t_end = {t_end}: it must be finite with t_end > t0")]
    InvalidSpan {
        /// The start.
        t0: f64,
        /// The end.
        t_end: f64,
    },
    /// The tolerance asked for lies below what `f64` arithmetic reaches on
    /// this problem: the round-off accumulated over the steps the tolerance
    /// needs is larger than the tolerance itself.
    #[error(
        "tolerance {requested:e} is below what f64 reaches on this problem (round-off floor about {floor:e} over the span): run in extended precision (`DoubleDouble`) or relax the tolerance"
    )]
    ToleranceUnreachable {
        /// The absolute error asked for (`rtol · scale + atol`).
        requested: f64,
        /// The estimated round-off floor of the global error in `f64`.
        floor: f64,
    },
    /// The pilot's error estimate grows exponentially (a positive Lyapunov
    /// exponent) so fast that no method in `f64` meets the tolerance over the
    /// span: an answer would be confident and wrong.
    #[error(
        "chaotic: no method meets the tolerance over this span (the pilot's error grows like exp({rate:.3} t); the round-off alone grows to {floor:e} by t = {t_end}, against {requested:e} asked for): shorten the span or relax the tolerance"
    )]
    Chaotic {
        /// The absolute error asked for.
        requested: f64,
        /// The round-off alone, amplified to the end of the span.
        floor: f64,
        /// The measured growth rate of the error (per unit time).
        rate: f64,
        /// The end of the span.
        t_end: f64,
    },
    /// Every candidate method of a tolerance-driven solve failed in its
    /// pilot; one line per candidate says which failed where.
    #[error("no candidate method completed its pilot: {}", .failures.join("; "))]
    NoMethod {
        /// `method: error` for each candidate tried, in order.
        failures: Vec<String>,
    },
    /// The velocity for a momentum could not be found (inverse Legendre transform).
    #[error("no velocity found for the momentum at t = {} (step {}): {iterations} newton iterations, residual norm {residual_norm:e}", .state.t, .state.step)]
    InverseLegendre {
        /// The state whose velocity was sought.
        state: PhasePoint<T>,
        /// Newton iterations spent.
        iterations: usize,
        /// `‖∂L/∂v − p‖∞` at the last iterate.
        residual_norm: f64,
    },
    /// Holonomic constraints: the initial data lie off the constraint
    /// manifold `g(q) = 0` or off its tangent space `G(q) v = 0` by more
    /// than `tolerance` (relative: the distance `|g_i| / ‖∇g_i‖` against
    /// `max(‖q‖∞, 1)`, and `|G_i v| / ‖∇g_i‖` against `‖v‖∞`). Project them
    /// first with [`Constrained::project`](crate::Constrained::project).
    #[error(
        "initial data inconsistent with the constraints: relative distance {position:e} from g(q) = 0 and {velocity:e} from G(q) v = 0 (tolerance {tolerance:e}); project them with `Constrained::project`"
    )]
    InconsistentConstraints {
        /// The relative distance from the constraint manifold.
        position: f64,
        /// The relative size of the velocity component normal to it.
        velocity: f64,
        /// The tolerance both must meet.
        tolerance: f64,
    },
    /// Holonomic constraints: the constraint Jacobian `G(q) = ∂g/∂q` has
    /// lower rank than the number of constraints (redundant constraints, or a
    /// singular configuration such as the dead point of a four-bar linkage),
    /// at the initial data or inside a step.
    #[error(
        "rank-deficient constraint jacobian at t = {} (step {}): reciprocal condition number {rcond:e} of the constraint block (redundant constraints or a singular configuration)",
        .state.t, .state.step
    )]
    SingularConstraints {
        /// The state the integrator holds (the initial data at the start).
        state: PhasePoint<T>,
        /// The reciprocal condition number of `G Gᵀ` (at the start) or of
        /// the step's Schur complement `G(q_{k+1}) A⁻¹ G(q_k)ᵀ`.
        rcond: f64,
    },
    /// Holonomic constraints: `g(q)` or its Jacobian is NaN or infinite.
    #[error("non-finite constraint value at t = {} (step {})", .state.t, .state.step)]
    NonFiniteConstraints {
        /// The state the integrator holds (the initial data at the start).
        state: PhasePoint<T>,
    },
    /// The loss of an adjoint gradient, or its derivative, is NaN or
    /// infinite at a node ([`Problem::gradient`](crate::Problem::gradient)).
    #[error("the loss or its gradient is not finite at t = {} (step {})", .state.t, .state.step)]
    NonFiniteLoss {
        /// The node.
        state: PhasePoint<T>,
    },
    /// Sensitivities or an adjoint gradient through a step that is not a
    /// differentiable function of its inputs: an energy-preserving step
    /// whose size minimises the energy mismatch (a least-squares fallback,
    /// an accuracy cap) instead of solving the energy equation.
    #[error("the step from t = {} (step {}) is not differentiable: {reason}", .state.t, .state.step)]
    NotDifferentiable {
        /// The node the step starts from.
        state: PhasePoint<T>,
        /// Why.
        reason: &'static str,
    },
}

/// Matches `$error` against every variant that carries the state a failed
/// step started from, binding it to `$state` (by reference, as `$error` is
/// borrowed): the one list of those variants.
macro_rules! carried_state {
    ($error:expr, $state:ident => $some:expr, $none:expr) => {
        match $error {
            Error::NewtonDidNotConverge { state: $state, .. }
            | Error::SingularJacobian { state: $state, .. }
            | Error::NonFinite { state: $state, .. }
            | Error::StepRejected { state: $state, .. }
            | Error::NoEnergyStep { state: $state, .. }
            | Error::InvalidTarget { state: $state, .. }
            | Error::InvalidDensity { state: $state, .. }
            | Error::TimeStepCollapsed { state: $state, .. }
            | Error::TimeFunctionArgument { state: $state, .. }
            | Error::OrbitLost { state: $state, .. }
            | Error::InverseLegendre { state: $state, .. }
            | Error::SingularConstraints { state: $state, .. }
            | Error::NonFiniteConstraints { state: $state }
            | Error::NonFiniteLoss { state: $state }
            | Error::NotDifferentiable { state: $state, .. } => $some,
            _ => $none,
        }
    };
}

impl<T: Real> Error<T> {
    /// The state the error carries: the state the failed step started from
    /// (and the integrator still holds), or the node where the failure was
    /// found; `None` for the errors of a setting or of the input.
    pub fn state(&self) -> Option<&PhasePoint<T>> {
        carried_state!(self, state => Some(state), None)
    }

    /// The error of a step from `state` with size `h` whose Newton solve failed.
    pub(crate) fn from_newton(failure: NewtonFailure, state: impl Into<PhasePoint<T>>, h: f64) -> Self {
        let state = state.into();
        match failure {
            NewtonFailure::NotConverged(r) => Error::NewtonDidNotConverge {
                state,
                h,
                iterations: r.iterations,
                residual_norm: r.residual_norm,
                correction_norm: r.correction_norm,
            },
            NewtonFailure::Singular { iterations, rcond } => Error::SingularJacobian { state, h, iterations, rcond },
            NewtonFailure::NonFinite { iterations, quantity } => Error::NonFinite { state, h, iterations, quantity },
            NewtonFailure::Rejected { iterations, reason } => Error::StepRejected { state, h, iterations, reason },
        }
    }

    /// The same error, reported at `at` instead of the state it carries (a
    /// composition's sub-step fails at an intermediate state; the caller's
    /// state is the one kept).
    pub(crate) fn at_state(self, at: impl Into<PhasePoint<T>>) -> Self {
        self.map_state(|_| at.into())
    }

    /// The same error with its state mapped by `f`: a time-transformed
    /// driver reports the failure of its step in `s`, whose state is the
    /// extended `(q, t)`, at the physical state.
    pub(crate) fn map_state(mut self, f: impl FnOnce(PhasePoint<T>) -> PhasePoint<T>) -> Self {
        carried_state!(&mut self, state => {
            let empty = PhasePoint { step: state.step, t: T::ZERO, q: Vec::new(), p: Vec::new() };
            *state = f(core::mem::replace(state, empty));
        }, ());
        self
    }

    /// `Ok` for a usable configuration of a system with `n` coordinates: a
    /// finite, positive step size, valid Newton options and at least one
    /// degree of freedom.
    pub(crate) fn check_setup(n: usize, h: f64, newton: &crate::newton::NewtonOptions) -> Result<(), Self> {
        if n == 0 {
            return Err(Error::InvalidInitialData { reason: "the system has no degrees of freedom (N = 0)" });
        }
        newton.validate().map_err(|reason| Error::InvalidNewtonOptions { reason })?;
        Self::check_step(h)
    }

    /// `Ok` for a finite, positive step size.
    pub(crate) fn check_step(h: f64) -> Result<(), Self> {
        if h.is_finite() && h > 0.0 { Ok(()) } else { Err(Error::InvalidStepSize { h }) }
    }

    /// `Ok` for the initial data `(t0, q0, v0)` of a run-time-sized system
    /// with `n` coordinates: at least one, `q0` and `v0` of that length, all
    /// finite.
    pub(crate) fn check_run_time_data(n: usize, t0: f64, q0: &[f64], v0: &[f64]) -> Result<(), Self> {
        if n == 0 {
            return Err(Error::InvalidInitialData { reason: "the system has no degrees of freedom (dimension 0)" });
        }
        for (what, x) in [("q0", q0), ("v0", v0)] {
            if x.len() != n {
                return Err(Error::WrongLength { what, expected: n, found: x.len() });
            }
        }
        if !t0.is_finite() || !crate::real::all_finite(q0) || !crate::real::all_finite(v0) {
            return Err(Error::InvalidInitialData { reason: "t0, q0 and v0 must be finite" });
        }
        Ok(())
    }
}

/// A failure found inside a step before it is known whether the step
/// fails: a trial of the energy-step search, or a first Newton attempt that
/// a second one may repair. It is the [`Error`] without its state (a
/// [`PhasePoint`] without coordinates, whose empty vectors allocate
/// nothing), so a step that recovers from it allocates nothing; the step
/// that gives up places it at the state it started from with [`at`](Self::at).
#[derive(Debug)]
pub(crate) struct Unplaced<T: Real = f64>(Error<T>);

impl<T: Real> Unplaced<T> {
    /// The error `build` makes of a state still to be placed.
    pub(crate) fn new(build: impl FnOnce(PhasePoint<T>) -> Error<T>) -> Self {
        Self(build(PhasePoint { step: 0, t: T::ZERO, q: Vec::new(), p: Vec::new() }))
    }

    /// The failure of a Newton solve of a step of size `h`.
    pub(crate) fn newton(failure: NewtonFailure, h: f64) -> Self {
        Self::new(|state| Error::from_newton(failure, state, h))
    }

    /// The error, placed at `state`: the state the failed step started from.
    pub(crate) fn at(self, state: impl Into<PhasePoint<T>>) -> Error<T> {
        self.0.at_state(state)
    }
}

/// The const-size state of a [`PhasePoint`] with `N` coordinates;
/// [`Error::WrongLength`] (naming `q` or `p`) for one of another length.
impl<const N: usize, T: Real> TryFrom<PhasePoint<T>> for State<N, T> {
    type Error = Error<T>;

    fn try_from(PhasePoint { step, t, q, p }: PhasePoint<T>) -> Result<Self, Error<T>> {
        let sized = |what, x: Vec<T>| {
            let found = x.len();
            <[T; N]>::try_from(x).map_err(|_| Error::WrongLength { what, expected: N, found })
        };
        Ok(State { step, t, q: sized("q", q)?, p: sized("p", p)? })
    }
}

/// Which argument of `f'` failed the positivity check in the explicit
/// time-transformed splitting ([`Error::TimeFunctionArgument`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Argument {
    /// `T(p) + p_t + c`, in a drift.
    Kinetic,
    /// `c − V(t, q)`, in a kick.
    Potential,
}

/// The root test of [`Error::NoEnergyStep`] as text for its message.
fn root_test_text(test: &Option<(f64, f64, f64)>) -> String {
    match test {
        Some((x, low, high)) => format!(
            "; root test x = {x:.3} ({}: a root needs x ≤ {low:.3} or x ≥ {high:.3})",
            if *x > *low && *x < *high { "inside the band without a root" } else { "outside the band" }
        ),
        None => String::new(),
    }
}
