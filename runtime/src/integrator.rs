//! The variational integrator: one type for every discrete Lagrangian, step
//! policy and real type (docs/theory.md §3, position–momentum form).
//!
//! ```text
//! given (t_k, q_k, p_k):   solve  p_k + ∂A/∂q_k (x_k, X) = 0,  ∂A/∂X_interior = 0   for the step's nodes X,
//!                          t_{k+1} = t_k + h_k,   p_{k+1} = ∂A/∂q_{k+1} (x_k, X)
//! ```
//!
//! The integrator owns what every method shares: the builder and its checks,
//! the state `(t_k, q_k, p_k)` with the Kahan compensation of `q` and `p`,
//! the clock, the step policy (fixed steps, or energy-preserving steps with
//! the step size as one more unknown), [`Stats`], and `run`/`run_until`. A
//! discrete Lagrangian brings how one step is solved ([`Method`]): the
//! one-point rules in `one_point.rs` (one hyper-dual sweep of the action, or
//! of the macro's gradient code on dual lanes, per Newton iteration), the Galerkin rules in `galerkin/stepper.rs` (a block of
//! `sN` unknowns). The state is only replaced once a step has converged and
//! every published value is finite, so a failed step leaves the integrator as
//! it was.

use crate::error::Error;
use crate::newton::{NewtonFailure, NewtonOptions, NewtonReport};
use crate::real::{Real, all_finite, kahan, max_abs};
use crate::state::State;
use crate::symplectic::TangentMap;
use crate::system::{Lagrangian, generalized_force};

mod composition;
mod dynamic;
mod method;
mod one_point;
mod sparse;
mod tape_step;
mod variable_step;

pub use composition::{Composition, CompositionMemory};
pub(crate) use dynamic::RunTimeGalerkin;
pub(crate) use dynamic::Sliced;
pub use dynamic::{DynIntegrator, DynIntegratorBuilder, DynMethod};
pub(crate) use method::sealed::Sealed;
pub use method::{F64Readouts, Method};
pub use one_point::OnePointMemory;
pub use sparse::Derivatives;
pub(crate) use sparse::velocity as reverse_mode_velocity;
pub(crate) use tape_step::{Mass as ConstantMass, SparseWork, TapeModel, velocity_derivatives};
pub(crate) use tape_step::{energy as tape_energy, legendre as tape_legendre};
pub(crate) use tape_step::{momentum as tape_momentum, velocity as tape_velocity};
pub use variable_step::{EnergyFallback, StepBounds};
pub(crate) use variable_step::{EnergySearch, Probe, Taken, root_band};

/// Counters of the work an integrator has done.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Stats {
    /// Steps taken successfully.
    pub steps: u64,
    /// Newton iterations (residual evaluations) over all successful steps.
    pub newton_iterations: u64,
    /// Steps that failed and were not applied.
    pub failed_steps: u64,
    /// Energy-preserving steps taken by [`EnergyFallback::LeastSquares`]
    /// because no step size satisfied the energy equation.
    pub energy_fallbacks: u64,
    /// Energy-preserving steps with an accuracy bound
    /// ([`StepBounds::with_accuracy`]) whose energy equation had no root at
    /// or below the bound: taken at the step of least energy mismatch below
    /// it, whatever the [`EnergyFallback`]; the discrete energy (or the
    /// balance of a damped system) changed by the mismatch there.
    pub accuracy_capped_steps: u64,
    /// The largest relative energy mismatch `|g|/|E|` of those steps.
    pub largest_capped_energy_defect: f64,
    /// The report of the last successful Newton solve.
    pub last: NewtonReport,
    /// For a system declared discontinuous (`Lagrangian::DISCONTINUOUS`):
    /// the largest relative change of the discrete energy over one step,
    /// `|E_{k+1} − E_k| / |E_k|`, and the time `t_{k+1}` where it happened.
    /// A smooth `L` changes it by `O(h³)` per step; a jump of the potential
    /// by `ΔV` shows as `ΔV/|E|`. Zero for systems not declared discontinuous
    /// (the check costs one evaluation of the energy per step).
    pub largest_energy_jump: f64,
    /// The time at which [`largest_energy_jump`](Self::largest_energy_jump) happened.
    pub largest_energy_jump_at: f64,
}

/// Configuration of an integrator before it is given its initial state.
///
/// Made by [`Integrator::new`]; [`start`](Self::start) checks everything and
/// returns the running [`Integrator`].
#[derive(Clone, Debug)]
pub struct IntegratorBuilder<S, M, T = f64> {
    system: S,
    method: M,
    h: T,
    newton: NewtonOptions,
    policy: StepPolicy,
    fallback: EnergyFallback,
    derivatives: Derivatives,
    summation: Summation,
}

/// How a step's increments are added to the state `(q_k, p_k)`.
///
/// Rounding `q_k + Δq` to `f64` at every step loses the low bits of the
/// increment; over many steps of a system whose coordinates are large
/// against their increments (a moving centre of mass, coordinates far from
/// the origin) those losses add up to a drift of the energy and the momenta
/// that the method itself does not make. Compensated summation (Kahan; see
/// Hairer, Lubich & Wanner, *Geometric Numerical Integration*, §VIII.5)
/// carries each rounding error into the next sum, so the state stays the
/// exact sum of the increments to within one rounding.
///
/// A free particle far from the origin, whose exact position after `n`
/// steps is `q_0 + n h v`:
///
/// ```
/// # use lagrangian_runtime::{Integrator, Lagrangian, Scalar, Summation, Trapezoid};
/// struct Free;
/// impl Lagrangian<1> for Free {
///     const AUTONOMOUS: bool = true;
///     const CYCLIC: [bool; 1] = [true];
///     fn lagrangian<D: Scalar>(&self, _t: D, _q: [D; 1], v: [D; 1]) -> D {
///         v[0] * v[0] * 0.5
///     }
/// }
///
/// let error = |summation| -> Result<f64, Box<dyn std::error::Error>> {
///     let mut sim = Integrator::new(Free, Trapezoid, 0.01).summation(summation).start(0.0, [1e4], [0.3])?;
///     sim.run(100_000, |_| {})?;
///     Ok((sim.state().q[0] - (1e4 + 1e5 * (0.3 * 0.01))).abs())
/// };
/// // Compensated: within one rounding of the exact sum (0.0 here); plain:
/// // 1e5 roundings to ulp(1e4) ≈ 1.8e-12, all one way (6.1e-8).
/// assert!(error(Summation::Compensated)? <= 2e-12);
/// assert!(error(Summation::Plain)? > 1e-9);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Summation {
    /// `q_{k+1} = q_k + Δq` and `p_{k+1} = p_k + Δp` as Kahan sums whose
    /// compensations the integrator keeps (the default).
    #[default]
    Compensated,
    /// `q_{k+1} = q_k + Δq` and `p_{k+1} = p_k + Δp` rounded once, as a
    /// hand-written integrator does: a few operations fewer per coordinate
    /// and step (on the explicit paths, the sub-steps of a composition
    /// update `q` and `p` in place). Round-off then accumulates in the
    /// state: choose it for speed where coordinates stay of the size of
    /// their increments' sums, not for long runs of drifting or offset
    /// systems (`runtime/tests/compensated.rs` shows the difference).
    Plain,
}

impl Summation {
    /// `true` for [`Summation::Plain`].
    #[inline(always)]
    pub(crate) fn is_plain(self) -> bool {
        matches!(self, Summation::Plain)
    }
}

/// How the integrator chooses its step sizes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StepPolicy {
    /// Every step has the configured size `h` (docs/theory.md §3, fixed step).
    Fixed,
    /// Energy-preserving variable steps (Lee; Kane, Marsden & Ortiz; Chen,
    /// Guo & Wu): each `h_k` is an unknown of the step, fixed by the discrete
    /// energy equation `E_{k+1} = E_k` (for a time-dependent `L` and the
    /// one-point rules, the energy-evolution equation of de León & Martín de
    /// Diego). The configured `h` is the first guess.
    EnergyPreserving(StepBounds),
}

impl<S, M: Method<T>, T: Real> IntegratorBuilder<S, M, T> {
    /// Energy-preserving variable steps within `bounds`, starting from the
    /// guess `h` given to [`Integrator::new`].
    pub fn energy_preserving(mut self, bounds: StepBounds) -> Self {
        self.policy = StepPolicy::EnergyPreserving(bounds);
        self
    }

    /// What energy-preserving steps do where no admissible step size
    /// satisfies the energy equation (default: [`EnergyFallback::Fail`]; with
    /// [`EnergyFallback::LeastSquares`] the step of least energy mismatch is
    /// taken and counted in [`Stats::energy_fallbacks`]).
    pub fn energy_fallback(mut self, fallback: EnergyFallback) -> Self {
        self.fallback = fallback;
        self
    }

    /// Replaces the Newton settings.
    pub fn newton(mut self, options: NewtonOptions) -> Self {
        self.newton = options;
        self
    }

    /// How the derivatives of a step are computed and its Newton systems
    /// solved ([`Derivatives`]); [`Derivatives::Automatic`] by default, which
    /// takes reverse mode (a tape, banded or dense solves on the heap) for
    /// systems larger than [`Derivatives::FORWARD_MAX_N`], and from
    /// [`Derivatives::REVERSE_MIN_N`] coordinates for Newton steps reverse
    /// mode supports.
    pub fn derivatives(mut self, derivatives: Derivatives) -> Self {
        self.derivatives = derivatives;
        self
    }

    /// How increments are added to the state ([`Summation`]):
    /// [`Summation::Compensated`] by default.
    pub fn summation(mut self, summation: Summation) -> Self {
        self.summation = summation;
        self
    }

    /// Starts at `(t0, q0, v0)` with `p0 = ∂L/∂v(t0, q0, v0)`.
    ///
    /// Fails with [`Error::InvalidMethod`] for an unusable discrete
    /// Lagrangian (a Galerkin rule with `s = 0` or a too weak quadrature),
    /// with [`Error::InvalidStepSize`] for a step that is not finite and
    /// positive (or outside the step bounds), with
    /// [`Error::InvalidStepBounds`] for unusable bounds, with
    /// [`Error::InvalidInitialData`] for non-finite data or where
    /// `∂²L/∂v²` is singular (the Legendre transform is not regular and the
    /// one-step map does not exist) or the generalised force is not finite
    /// there, and with [`Error::Unsupported`] for a combination the method
    /// does not support: energy-preserving Galerkin steps (and one-point
    /// steps in a real type other than `f64`, which run as Galerkin steps)
    /// for a time-dependent `L` or a system with `force` or `dissipation`.
    /// For a forced system, the one-point rules' variable steps in `f64` are
    /// fixed by the discrete energy balance `E_{k+1} − E_k = W_k`
    /// ([`forcing`](crate::forcing)).
    pub fn start<const N: usize>(self, t0: T, q0: [T; N], v0: [T; N]) -> Result<Integrator<S, M, N, T>, Error<T>>
    where
        S: Lagrangian<N>,
    {
        self.method.check().map_err(|reason| Error::InvalidMethod { reason })?;
        Error::<T>::check_setup(N, self.h.to_f64(), &self.newton)?;
        if let StepPolicy::EnergyPreserving(b) = self.policy {
            if !b.valid() {
                return Err(Error::InvalidStepBounds { h_min: b.h_min, h_max: b.h_max, max_ratio: b.max_ratio });
            }
            if !(b.h_min..=b.h_max).contains(&self.h.to_f64()) {
                return Err(Error::InvalidStepSize { h: self.h.to_f64() });
            }
        }
        if S::CONSTRAINTS != M::CONSTRAINTS {
            return Err(Error::Unsupported { what: CONSTRAINT_COUNT_MISMATCH });
        }
        if matches!(self.policy, StepPolicy::EnergyPreserving(_)) && !S::ENERGY_STEPS {
            return Err(Error::Unsupported { what: NO_ENERGY_STEPS });
        }
        self.method.supports::<S, N>(&self.policy)?;
        self.derivatives.check::<N, T>()?;
        // `Automatic` is resolved here, once: reverse mode above
        // `FORWARD_MAX_N`, and from `REVERSE_MIN_N` where the method's step
        // would run Newton in reverse mode with everything it needs.
        let derivatives = match self.derivatives {
            Derivatives::Automatic if N > Derivatives::FORWARD_MAX_N => Derivatives::Reverse,
            Derivatives::Automatic if self.method.prefers_reverse::<S, N>(&self.policy) => Derivatives::Reverse,
            Derivatives::Automatic => Derivatives::Forward,
            chosen => chosen,
        };
        self.method.supports_derivatives::<S, N>(derivatives == Derivatives::Reverse, &self.policy)?;
        if !t0.is_finite() || !all_finite(&q0) || !all_finite(&v0) {
            return Err(Error::InvalidInitialData { reason: "t0, q0 and v0 must be finite" });
        }
        if !all_finite(&generalized_force(&self.system, t0, q0, v0)) {
            return Err(Error::InvalidInitialData {
                reason: "the force `force − ∂(dissipation)/∂v` is not finite at the initial data",
            });
        }
        let mut memory = self.method.memory();
        let (p0, energy) = self.method.start_memory(&self.system, t0, q0, v0, &mut memory)?;
        let zero = T::zero();
        Ok(Integrator {
            memory,
            system: self.system,
            method: self.method,
            h: self.h,
            newton: self.newton,
            state: State { step: 0, t: t0, q: q0, p: p0 },
            carry: [zero; N],
            p_carry: [zero; N],
            policy: self.policy,
            fallback: self.fallback,
            energy,
            energy_carry: zero,
            time_error: zero,
            watched_energy: None,
            v0,
            clock: Clock { t: t0, step: 0 },
            stats: Stats::default(),
            derivatives,
            summation: self.summation,
        })
    }
}

/// Why an integrator refuses energy-preserving steps of a system that
/// cannot take them with any method (`Lagrangian::ENERGY_STEPS`).
pub(crate) const NO_ENERGY_STEPS: &str = "energy-preserving steps of a time-transformed system: its steps have a fixed `σ`, and the physical time step follows from the step density";

/// Why an integrator refuses a system whose number of holonomic
/// constraints differs from the method's.
const CONSTRAINT_COUNT_MISMATCH: &str = "a system whose number of holonomic constraints (`Lagrangian::CONSTRAINTS`) differs from the method's: a constrained system runs under `Constrained::<_, M>` with its own `M`: `new(rule)` for a one-point rule (midpoint, trapezoid, α-β), `galerkin(rule)` for a Galerkin rule, `composition(composition)` for a composition of RATTLE steps; double-double runs with constraints are not supported yet";

/// [`kahan`] or, under [`Summation::Plain`], `a + b` with a zero
/// compensation (the compensation `c` of a plain state is zero).
#[inline(always)]
pub(crate) fn add_increment<T: crate::real::Real, const N: usize>(
    summation: Summation,
    a: &[T; N],
    c: &[T; N],
    b: &[T; N],
) -> ([T; N], [T; N]) {
    match summation {
        Summation::Compensated => kahan(a, c, b),
        Summation::Plain => (core::array::from_fn(|i| a[i] + b[i]), [T::zero(); N]),
    }
}

/// `true` when the increment `dq` of a converged step is more than `10⁶`
/// times both the predicted one and the last one (scaled to the same step),
/// and larger than the position `q` itself: Newton found a root, but not one a
/// trajectory reaches. Smooth motion changes its increment by a factor
/// `e^{λh}` per step; a growth of `10⁶` in one step is an unresolved (or, for
/// explicit discrete Lagrangians, unstable) step size, or a spurious root of
/// the DEL far away. Motion that starts from an increment of exactly zero (a
/// first-order α-β step from rest) has no scale to compare with and passes.
pub(crate) fn implausible_growth(dq: &[f64], predicted: &[f64], last: &[f64], q: &[f64]) -> bool {
    let scale = max_abs(predicted).max(max_abs(last));
    scale > 0.0 && max_abs(dq) > 1e6 * scale.max(1e-6 * max_abs(q))
}

/// The increment of a step of size `h` predicted by quadratic extrapolation
/// of the positions: the secant velocities `dq/h` of the last two steps
/// (`(h, dq)` each), placed at their midpoints, extrapolated linearly to the
/// midpoint of the new step; `v0·h` before the first step. Written to `out`.
#[inline(always)]
pub(crate) fn predict_into(
    h: f64,
    last: Option<(f64, &[f64])>,
    earlier: Option<(f64, &[f64])>,
    v0: &[f64],
    out: &mut [f64],
) {
    match (last, earlier) {
        // Equal steps (every fixed-step run): the same extrapolation as
        // `2 Δq_{k−1} − Δq_{k−2}`, without the divisions, whose latency
        // sits on the path to Newton's first residual.
        (Some((h_last, dq_last)), Some((h_earlier, dq_earlier))) if h_last == h && h_earlier == h => {
            for (i, x) in out.iter_mut().enumerate() {
                *x = 2.0 * dq_last[i] - dq_earlier[i];
            }
        }
        (Some((h_last, dq_last)), Some((h_earlier, dq_earlier))) => {
            let s = (h_last + h) / (h_last + h_earlier);
            for (i, x) in out.iter_mut().enumerate() {
                let v = dq_last[i] / h_last;
                let v_earlier = dq_earlier[i] / h_earlier;
                *x = h * (v + (v - v_earlier) * s);
            }
        }
        (Some((h_last, dq_last)), None) => {
            for (x, d) in out.iter_mut().zip(dq_last) {
                *x = d * (h / h_last);
            }
        }
        _ => {
            for (x, v) in out.iter_mut().zip(v0) {
                *x = v * h;
            }
        }
    }
}

/// Why a step rejected by [`implausible_growth`] is refused.
pub(crate) const IMPLAUSIBLE_GROWTH: &str = "the solution's increment is over 1e6 times the predicted and the last one: \
                                            a root far from the trajectory (an unstable or unresolved step size)";

/// Which of the values a step publishes is not finite, if any.
pub(crate) fn non_finite<T: crate::real::Real>(t: T, q: &[T], p: &[T]) -> Option<&'static str> {
    first_non_finite(all_finite(q), all_finite(p), t.is_finite())
}

/// [`non_finite`] from finiteness a loop has already found.
#[inline]
pub(crate) fn first_non_finite(q_finite: bool, p_finite: bool, t_finite: bool) -> Option<&'static str> {
    if !q_finite {
        Some("position")
    } else if !p_finite {
        Some("momentum")
    } else if !t_finite {
        Some("time")
    } else {
        None
    }
}

/// The landing rule of `run_until` for a fixed step `h`: `true` when the
/// next node, at `t_next`, would reach `t_end` or come within `10⁻⁹ h` of
/// it, so that the next step is the shortened one that ends on `t_end` (a
/// node a rounding short of the target would otherwise leave a step of a
/// few ulps).
#[inline]
pub(crate) fn fixed_step_lands<T: Real>(t_next: T, h: T, t_end: T) -> bool {
    t_next >= t_end - h * 1e-9
}

/// Where `t_k = t + (k − step)·h` is measured from; reset whenever `h` changes,
/// so that times stay exact multiples of `h` instead of accumulating round-off.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Clock<T> {
    pub(crate) t: T,
    pub(crate) step: u64,
}

impl<T: Real> Clock<T> {
    /// The time of node `k` on this clock.
    #[inline(always)]
    pub(crate) fn at(&self, k: u64, h: T) -> T {
        // Through `i64`: one instruction on x86-64 where `u64 → f64` takes
        // several, and the same number below 2⁶³ steps since the reset.
        self.t + h * (k - self.step) as i64 as f64
    }
}

/// A variational integrator for a system `S` with `N` degrees of freedom, a
/// discrete Lagrangian `M` and real type `T` (`f64`, or
/// [`DoubleDouble`](crate::DoubleDouble) for about 32 digits).
///
/// Every discrete Lagrangian runs through this one type: the one-point rules
/// ([`Midpoint`](crate::Midpoint), [`Trapezoid`](crate::Trapezoid),
/// [`AlphaBeta`](crate::AlphaBeta)) and the [`Galerkin`](crate::Galerkin)
/// rules of any order, with fixed or energy-preserving steps, with or
/// without forces.
///
/// ```
/// use lagrangian_runtime::{Integrator, Lagrangian, Midpoint, Scalar};
///
/// /// A harmonic oscillator, implemented by hand (`#[lagrangian]` writes this for you).
/// struct Oscillator;
/// impl Lagrangian<1> for Oscillator {
///     const AUTONOMOUS: bool = true;
///     const CYCLIC: [bool; 1] = [false];
///     fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 1], v: [D; 1]) -> D {
///         (v[0] * v[0] - q[0] * q[0]) * 0.5
///     }
/// }
///
/// let mut sim = Integrator::new(Oscillator, Midpoint, 0.01).start(0.0, [1.0], [0.0])?;
/// sim.run(628, |_| {})?;
/// assert!((sim.state().t - 6.28).abs() < 1e-12);
/// assert!((sim.state().q[0] - 6.28f64.cos()).abs() < 1e-4);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Extended precision
///
/// The whole run can be made in another [`Real`] type: give the step (and
/// the initial data) in it. The Newton block and the state are then computed
/// in it, and the same Lagrangian is evaluated on num-dual's hyper-duals over
/// it; tighten Newton's `rtol` to the type's precision.
///
/// ```
/// # use lagrangian_runtime::{Integrator, Lagrangian, Midpoint, Scalar};
/// # struct Oscillator;
/// # impl Lagrangian<1> for Oscillator {
/// #     const AUTONOMOUS: bool = true;
/// #     const CYCLIC: [bool; 1] = [false];
/// #     fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 1], v: [D; 1]) -> D {
/// #         (v[0] * v[0] - q[0] * q[0]) * 0.5
/// #     }
/// # }
/// use lagrangian_runtime::num_dual::DualNum;
/// use lagrangian_runtime::{DoubleDouble, NewtonOptions};
///
/// let dd = DoubleDouble::from;
/// let mut sim = Integrator::new(Oscillator, Midpoint, dd(0.01))
///     .newton(NewtonOptions { rtol: 1e-30, ..NewtonOptions::default() })
///     .start(dd(0.0), [dd(1.0)], [dd(0.0)])?;
/// sim.run(100, |_| {})?;
/// // The midpoint rule's phase error, (ωh)²/24 per unit time, far above round-off.
/// let exact = dd(1.0).cos();
/// assert!((sim.state().q[0] - exact).abs() < dd(1e-5));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug)]
pub struct Integrator<S, M: Method<T>, const N: usize, T: Real = f64> {
    pub(crate) system: S,
    pub(crate) method: M,
    pub(crate) h: T,
    pub(crate) newton: NewtonOptions,
    pub(crate) state: State<N, T>,
    /// Kahan compensation of the position: it is `state.q + carry`. Zero in
    /// reverse mode, whose steps keep it on the heap (swapped, not copied:
    /// `SparseWork::carries`).
    pub(crate) carry: [T; N],
    /// Kahan compensation of the momentum: it is `state.p + p_carry` (zero
    /// in reverse mode, like `carry`).
    pub(crate) p_carry: [T; N],
    pub(crate) policy: StepPolicy,
    pub(crate) fallback: EnergyFallback,
    /// `E_k`, the target of energy-preserving steps (fixed steps compute the
    /// discrete energy on demand).
    pub(crate) energy: T,
    /// Kahan compensation of the energy target `energy`.
    pub(crate) energy_carry: T,
    /// Kahan compensation of `t_k` under variable steps.
    pub(crate) time_error: T,
    /// The discrete energy of the last step, kept by the energy-jump watch of
    /// a system declared discontinuous (`None` before the first step).
    pub(crate) watched_energy: Option<T>,
    /// What the method keeps of its last steps.
    pub(crate) memory: M::Memory<N>,
    pub(crate) v0: [T; N],
    pub(crate) clock: Clock<T>,
    pub(crate) stats: Stats,
    /// Forward or reverse mode, as resolved at `start` (never `Automatic`).
    pub(crate) derivatives: Derivatives,
    /// How increments are added to the state; under [`Summation::Plain`]
    /// `carry` and `p_carry` (and reverse mode's carries) stay zero.
    pub(crate) summation: Summation,
}

impl<S: Clone, M: Method<T> + Clone, const N: usize, T: Real> Clone for Integrator<S, M, N, T> {
    fn clone(&self) -> Self {
        let Self {
            system,
            method,
            h,
            newton,
            state,
            carry,
            p_carry,
            policy,
            fallback,
            energy,
            energy_carry,
            time_error,
            watched_energy,
            memory,
            v0,
            clock,
            stats,
            derivatives,
            summation,
        } = self;
        Self {
            system: system.clone(),
            method: method.clone(),
            h: *h,
            newton: *newton,
            state: *state,
            carry: *carry,
            p_carry: *p_carry,
            policy: *policy,
            fallback: *fallback,
            energy: *energy,
            energy_carry: *energy_carry,
            time_error: *time_error,
            watched_energy: *watched_energy,
            memory: memory.clone(),
            v0: *v0,
            clock: *clock,
            stats: *stats,
            derivatives: *derivatives,
            summation: *summation,
        }
    }

    /// Field by field, the method's memory through its own `clone_from`:
    /// `solve` copies the integrator before every step, and a memory that
    /// keeps storage on the heap (a Galerkin rule's factored Newton block)
    /// copies into the storage it has instead of allocating.
    fn clone_from(&mut self, source: &Self) {
        let Self {
            system,
            method,
            h,
            newton,
            state,
            carry,
            p_carry,
            policy,
            fallback,
            energy,
            energy_carry,
            time_error,
            watched_energy,
            memory,
            v0,
            clock,
            stats,
            derivatives,
            summation,
        } = self;
        system.clone_from(&source.system);
        method.clone_from(&source.method);
        memory.clone_from(&source.memory);
        (*h, *newton, *state, *carry, *p_carry) = (source.h, source.newton, source.state, source.carry, source.p_carry);
        (*policy, *fallback, *energy, *energy_carry) =
            (source.policy, source.fallback, source.energy, source.energy_carry);
        (*time_error, *watched_energy, *v0, *clock) =
            (source.time_error, source.watched_energy, source.v0, source.clock);
        (*stats, *derivatives, *summation) = (source.stats, source.derivatives, source.summation);
    }
}

impl<S, M: Method<T>, T: Real> Integrator<S, M, 0, T> {
    /// Configures an integrator for `system` with the discrete Lagrangian
    /// `method` and step `h`; continue with [`IntegratorBuilder::start`].
    ///
    /// The type of `h` is the real type of the whole run: `f64`, or
    /// [`DoubleDouble`](crate::DoubleDouble) for about 32 digits (a
    /// [`Galerkin`](crate::Galerkin) rule carries its own type, which `h`
    /// must match).
    #[allow(clippy::new_ret_no_self)]
    pub fn new(system: S, method: M, h: T) -> IntegratorBuilder<S, M, T> {
        IntegratorBuilder {
            system,
            method,
            h,
            newton: NewtonOptions::default(),
            policy: StepPolicy::Fixed,
            fallback: EnergyFallback::Fail,
            derivatives: Derivatives::Automatic,
            summation: Summation::Compensated,
        }
    }
}

impl<S: Lagrangian<N>, M: Method<T>, const N: usize, T: Real> Integrator<S, M, N, T> {
    /// The current state `(k, t_k, q_k, p_k)`.
    pub fn state(&self) -> &State<N, T> {
        &self.state
    }

    /// The system being integrated.
    pub fn system(&self) -> &S {
        &self.system
    }

    /// The discrete Lagrangian in use.
    pub fn method(&self) -> &M {
        &self.method
    }

    /// The current step size (under energy-preserving steps, the last step
    /// taken, which is the next guess).
    pub fn step_size(&self) -> T {
        self.h
    }

    /// The size of the last step taken; `None` before the first.
    pub fn last_step_size(&self) -> Option<T> {
        M::last_step_size(&self.memory)
    }

    /// Work counters (Newton iterations per step: `newton_iterations / steps`).
    pub fn stats(&self) -> &Stats {
        &self.stats
    }

    /// How increments are added to the state ([`IntegratorBuilder::summation`]).
    pub fn summation(&self) -> Summation {
        self.summation
    }

    /// The Newton settings in use.
    pub fn newton_options(&self) -> &NewtonOptions {
        &self.newton
    }

    /// The step policy in use.
    pub fn policy(&self) -> StepPolicy {
        self.policy
    }

    /// Changes the step size for the following steps (for example to retry a
    /// failed step with a smaller one). The integrator stays variational: the
    /// DEL equations hold with the step sizes actually taken.
    ///
    /// Under energy-preserving steps `h` is the next guess and must lie in
    /// `[h_min, h_max]`.
    pub fn set_step_size(&mut self, h: T) -> Result<(), Error<T>> {
        Error::<T>::check_step(h.to_f64())?;
        if let StepPolicy::EnergyPreserving(b) = self.policy
            && !(b.h_min..=b.h_max).contains(&h.to_f64())
        {
            return Err(Error::InvalidStepSize { h: h.to_f64() });
        }
        self.clock = Clock { t: self.state.t, step: self.state.step };
        self.h = h;
        Ok(())
    }

    /// Takes one step: of size [`step_size`](Self::step_size) under fixed
    /// steps, of the size the energy equation fixes under energy-preserving
    /// steps.
    ///
    /// On failure nothing changes: the state, the step size and the predictor
    /// are those from before the call, and the error carries the state and
    /// the Newton diagnostics.
    #[inline]
    pub fn step(&mut self) -> Result<&State<N, T>, Error<T>> {
        match self.policy {
            StepPolicy::EnergyPreserving(bounds) => M::energy_step(self, bounds)?,
            StepPolicy::Fixed => {
                let t1 = self.clock.at(self.state.step + 1, self.h);
                M::fixed_step(self, self.h, t1)?;
            }
        }
        Ok(&self.state)
    }

    /// Takes `n` steps, calling `observe` after each with the integrator.
    ///
    /// Stops at the first failure, with the integrator at the last good state.
    pub fn run(&mut self, n: usize, mut observe: impl FnMut(&Self)) -> Result<(), Error<T>> {
        for _ in 0..n {
            self.step()?;
            observe(self);
        }
        Ok(())
    }

    /// Steps until `t_end`, calling `observe` after each step, and stops at
    /// `t_end` exactly: the last step is shortened to land on it (a step
    /// that would end within `10⁻⁹ h` of it is stretched by that much
    /// instead), and the step size is then restored. A target equal to the
    /// current time is a no-op.
    ///
    /// Under energy-preserving steps every step, the last included, is at
    /// most the largest admissible step `min(h_max, max_ratio·h_{k−1})`; the
    /// last one is a fixed step of the remaining length (the energy equation
    /// is not imposed on it, and its discrete energy is conserved from then
    /// on) and may be shorter than `h_min`.
    pub fn run_until(&mut self, t_end: T, mut observe: impl FnMut(&Self)) -> Result<(), Error<T>> {
        if !t_end.is_finite() || t_end < self.state.t {
            return Err(Error::InvalidTarget { target: t_end.to_f64(), state: self.state.into() });
        }
        loop {
            let remaining = t_end - self.state.t;
            if remaining <= T::zero() {
                return Ok(());
            }
            let last = match self.policy {
                StepPolicy::Fixed => fixed_step_lands(self.clock.at(self.state.step + 1, self.h), self.h, t_end),
                StepPolicy::EnergyPreserving(b) => match M::last_step_size(&self.memory) {
                    Some(h_prev) => remaining.to_f64() <= b.bracket(h_prev.to_f64()).1,
                    None => remaining <= self.h,
                },
            };
            if last {
                let h = self.h;
                // An accuracy bound caps the energy steps below the bracket:
                // the landing keeps under the last step, in equal pieces.
                let pieces = match (self.policy, M::last_step_size(&self.memory)) {
                    (StepPolicy::EnergyPreserving(StepBounds { accuracy: Some(_), .. }), Some(h_prev)) => {
                        (remaining.to_f64() / h_prev.to_f64()).ceil().max(1.0)
                    }
                    _ => 1.0,
                };
                let t_start = self.state.t;
                for i in 1..pieces as usize {
                    let t1 = t_start + remaining * (i as f64 / pieces);
                    M::fixed_step(self, t1 - self.state.t, t1)?;
                    observe(self);
                }
                M::fixed_step(self, t_end - self.state.t, t_end)?;
                self.clock = Clock { t: self.state.t, step: self.state.step };
                if let StepPolicy::EnergyPreserving(_) = self.policy {
                    // A fixed landing step: conserve its energy from here on,
                    // and keep the solved step as the next guess.
                    M::reread_energy(self);
                    self.time_error = T::zero();
                    self.h = h;
                }
                observe(self);
                return Ok(());
            }
            self.step()?;
            observe(self);
        }
    }

    /// The discrete energy `E_k = −∂A(x_{k−1}, x_k)/∂t_k` of the last step
    /// (docs/theory.md §3); at `k = 0`, the continuous energy of the initial
    /// data.
    ///
    /// Under energy-preserving steps it is read off the last step like for
    /// fixed steps, so it shows what the steps achieve, not the target they
    /// were solved for.
    pub fn discrete_energy(&self) -> T {
        M::discrete_energy(self)
    }

    /// Counts a failed step and turns its Newton failure into the error.
    pub(crate) fn fail(&mut self, h: T, failure: NewtonFailure) -> Error<T> {
        self.stats.failed_steps += 1;
        Error::from_newton(failure, self.state, h.to_f64())
    }
}

/// Readouts that solve in `f64` (the inverse Legendre transform, the tangent map).
impl<S: Lagrangian<N>, M: F64Readouts, const N: usize> Integrator<S, M, N> {
    /// The velocity `v_k` whose momentum `∂L/∂v(t_k, q_k, v_k)` is `p_k`.
    pub fn velocity(&self) -> Result<[f64; N], Error> {
        use crate::mechanics::DiscreteMechanics;
        let State { t, q, p, .. } = self.state;
        if const { sparse::too_large_for_forward(N) } || self.derivatives.reverse::<N>() {
            if S::SEPARABILITY.has_constant_mass()
                && let Some(v) = M::constant_mass_velocity(self)
            {
                return Ok(v);
            }
            return sparse::velocity(&self.system, t, &q, &p, &M::velocity_guess(self)).map_err(
                |(iterations, residual_norm)| Error::InverseLegendre {
                    state: self.state.into(),
                    iterations,
                    residual_norm,
                },
            );
        }
        self.system.velocity(t, q, p, M::velocity_guess(self)).map_err(|f| Error::InverseLegendre {
            state: self.state.into(),
            iterations: f.iterations,
            residual_norm: f.residual_norm,
        })
    }

    /// The continuous energy `E_L(t_k, q_k, v_k)` at the velocity of the current momentum.
    pub fn energy(&self) -> Result<f64, Error> {
        use crate::mechanics::DiscreteMechanics;
        let v = self.velocity()?;
        if const { sparse::too_large_for_forward(N) } || self.derivatives.reverse::<N>() {
            return Ok(sparse::energy(&self.system, self.state.t, &self.state.q, &v));
        }
        Ok(self.system.energy(self.state.t, self.state.q, v))
    }

    /// The tangent map `∂(q_k, p_k)/∂(q_{k−1}, p_{k−1})` of the last step
    /// (docs/theory.md §8), or `None` before the first step or where the
    /// step's Newton block is singular. Allocates for Galerkin rules: a
    /// diagnostic, not for the stepping loop.
    ///
    /// Also `None` for a system with forces: its step map is not symplectic,
    /// and the tangent map would need the derivatives of the discrete forces;
    /// and above [`Derivatives::FORWARD_MAX_N`] coordinates, where the steps
    /// have no dense `2N × 2N` Jacobian. Boxed: its `4N²` entries inline
    /// would not fit a thread's stack at large `N` (2 MiB at `N = 256`).
    pub fn last_tangent_map(&self) -> Option<Box<TangentMap<N>>> {
        if const { sparse::too_large_for_forward(N) } || S::HAS_FORCE || S::HAS_DISSIPATION {
            return None;
        }
        M::tangent_map(self).map(Box::new)
    }

    /// The discrete momentum map `J_k = p_k·ξ(q_k)` of a symmetry at the current node (docs/theory.md §7).
    pub fn momentum_map(&self, symmetry: &(impl crate::noether::Generator<N> + ?Sized)) -> f64 {
        crate::noether::momentum_map(symmetry, &self.state.q, &self.state.p)
    }

    /// The forcing impulse of the last step on a symmetry, which
    /// `J_{k+1} − J_k` equals for a symmetry of the action (see
    /// [`noether`](crate::noether)): `F_k^−·ξ(q_k) + F_k^+·ξ(q_{k+1})` for
    /// the one-point rules, `Σ_m F^m·ξ(Q_m)` over the nodes of a Galerkin
    /// step. `None` before the first step.
    pub fn forcing_impulse(&self, symmetry: &(impl crate::noether::Generator<N> + ?Sized)) -> Option<f64> {
        M::forcing_impulse(self, symmetry)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_published_value_is_checked() {
        assert_eq!(non_finite(1.0, &[1.0], &[1.0]), None);
        assert_eq!(non_finite(f64::INFINITY, &[1.0], &[1.0]), Some("time"));
        assert_eq!(non_finite(1.0, &[f64::NAN], &[1.0]), Some("position"));
        assert_eq!(non_finite(1.0, &[1.0], &[f64::NEG_INFINITY]), Some("momentum"));
    }

    #[test]
    fn growth_by_a_million_is_implausible() {
        assert!(!implausible_growth(&[1e5], &[1.0], &[0.5], &[1.0]));
        assert!(implausible_growth(&[2e6], &[1.0], &[0.5], &[1.0]));
        // Not beyond the position itself.
        assert!(!implausible_growth(&[2e6], &[1.0], &[0.5], &[1e7]));
        // No scale to compare with.
        assert!(!implausible_growth(&[1.0], &[0.0], &[0.0], &[1.0]));
    }
}
