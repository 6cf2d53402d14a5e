//! The Galerkin variational integrator: fixed steps, forces, and the state
//! and checks shared with its energy-preserving steps.
//!
//! ```text
//! given (t_k, q_k, p_k), unknowns D_m = Q_m − q_k, m = 1 … s  (s − 1 interior nodes and q_{k+1} − q_k):
//!     p_k + ∂A/∂Q_0 + F^0 = 0              N equations  (the DEL, docs/theory.md §3)
//!     ∂A/∂Q_m + F^m = 0,  m = 1 … s − 1    (s − 1)N equations  (Chen, Guo & Wu (finite elements) (2.38))
//! then q_{k+1} = q_k + D_s,  p_{k+1} = ∂A/∂Q_s + F^s = p_k + h Σ_j b_j (∂L/∂q + F)(c_j)
//! ```
//!
//! `F^m = h Σ_j b_j ℓ_m(c_j) F(t_j, q(c_j), q̇(c_j))` is the discrete force on
//! node `m` of the generalised force `F = Q − ∂R/∂v` (docs/theory.md §6): the
//! virtual work `∫ F·δq dt` of the interpolated variation `δq = Σ_m ℓ_m δQ_m`
//! by the step's own quadrature, so the discrete Lagrange–d'Alembert
//! principle keeps the method's order 2s. Without forces `F^m = 0`.
//!
//! One Newton block of size `sN`: the residual and the Jacobian
//! `∂²A/∂Q_ρ∂Q_n` (rows `ρ = 0 … s−1`, columns `n = 1 … s`) are assembled by
//! the chain rule from the gradient and Hessian of `L` at the quadrature
//! points ([`Galerkin`](super::Galerkin)), and the correction comes from a
//! statically sized LU with partial pivoting; nothing is allocated while
//! stepping. The first guess extrapolates the previous step's polynomial to
//! the new interval (error `O(h^{s+1})`); the first step starts from the
//! straight line `q_0 + τ h v_0`. The iteration is simplified Newton (the
//! Jacobian of the first guess kept for the whole step); if that fails, full
//! Newton from the same guess, then from a straight line, and only then a
//! typed error. Iteration counts include every attempt.
//!
//! Positions are summed with Kahan's compensation: the integrator holds
//! `q_k` and the rounding error `e_k` of the sum `q_0 + Σ D_s`, and evaluates
//! the step polynomial at `q_k + (e_k + Σ_m ℓ_m D_m)`, so the round-off of
//! the positions grows like `h · ε` per step instead of `ε`.
//!
//! Energy-preserving variable steps are in `energy.rs` (the step size as one
//! more unknown of the step).

use core::cell::Cell;

use crate::error::Error;
use crate::integrator::{EnergyFallback, IMPLAUSIBLE_GROWTH, Stats, StepBounds, implausible_growth, kahan, non_finite};
use crate::mechanics::DiscreteMechanics;
use crate::newton::{self, Breakdown, Linearization, NewtonFailure, NewtonOptions, NewtonReport, Unknown};
use crate::real::{Real, all_finite, max_abs};
use crate::state::State;
use crate::symplectic::TangentMap;
use crate::system::{Lagrangian, generalized_force};
use nalgebra::SMatrix;

use super::linalg::{BlockMatrix, BlockVector, Lu, LuFailure};
use super::method::{Galerkin, PointDerivatives, gradient_at, point_gradient};

/// Configuration of a [`GalerkinIntegrator`] before it is given its initial state.
#[derive(Clone, Debug)]
pub struct GalerkinBuilder<Sys, const S: usize, const R: usize, T = f64> {
    system: Sys,
    method: Galerkin<S, R, T>,
    h: T,
    newton: NewtonOptions,
    policy: Option<StepBounds>,
    fallback: EnergyFallback,
}

impl<Sys, const S: usize, const R: usize, T: Real> GalerkinBuilder<Sys, S, R, T> {
    /// Energy-preserving variable steps within `bounds` (Chen, Guo & Wu (finite elements) §3: the
    /// step size as an unknown fixed by the discrete energy equation),
    /// starting from the guess `h` given to [`GalerkinIntegrator::new`]. For
    /// autonomous systems without forces; see [`galerkin`](super) for what
    /// is conserved and what is not supported yet.
    pub fn energy_preserving(mut self, bounds: StepBounds) -> Self {
        self.policy = Some(bounds);
        self
    }

    /// What energy-preserving steps do where no admissible step size solves
    /// the energy equation (default [`EnergyFallback::Fail`]; with
    /// [`EnergyFallback::LeastSquares`] the step of least energy mismatch is
    /// taken, its energy conserved from then on, and the step counted in
    /// [`Stats::energy_fallbacks`]).
    pub fn energy_fallback(mut self, fallback: EnergyFallback) -> Self {
        self.fallback = fallback;
        self
    }

    /// Replaces the Newton settings.
    pub fn newton(mut self, options: NewtonOptions) -> Self {
        self.newton = options;
        self
    }

    /// Starts at `(t0, q0, v0)` with `p0 = ∂L/∂v(t0, q0, v0)`.
    ///
    /// Fails with [`Error::InvalidMethod`] for an unusable discrete
    /// Lagrangian (`s = 0`, an invalid or too weak quadrature), and otherwise
    /// like [`IntegratorBuilder::start`](crate::IntegratorBuilder::start).
    pub fn start<const N: usize>(
        self,
        t0: T,
        q0: [T; N],
        v0: [T; N],
    ) -> Result<GalerkinIntegrator<Sys, N, S, R, T>, Error<N, T>>
    where
        Sys: Lagrangian<N>,
    {
        self.method.check().map_err(|reason| Error::InvalidMethod { reason })?;
        Error::<N, T>::check_setup(self.h.to_f64(), &self.newton)?;
        if let Some(b) = self.policy {
            if !b.valid() {
                return Err(Error::InvalidStepBounds { h_min: b.h_min, h_max: b.h_max, max_ratio: b.max_ratio });
            }
            if !(b.h_min..=b.h_max).contains(&self.h.to_f64()) {
                return Err(Error::InvalidStepSize { h: self.h.to_f64() });
            }
            if Sys::HAS_FORCE || Sys::HAS_DISSIPATION {
                return Err(Error::Unsupported {
                    what: "energy-preserving steps for a system with `force` or `dissipation`: its energy is not \
                           conserved, so the energy equation that fixes the step sizes does not hold; use fixed steps",
                });
            }
            if !Sys::AUTONOMOUS {
                return Err(Error::Unsupported {
                    what: "energy-preserving galerkin steps for a time-dependent lagrangian; use fixed steps, \
                           or the energy-preserving midpoint and trapezoid rules",
                });
            }
        }
        if !t0.is_finite() || !all_finite(&q0) || !all_finite(&v0) {
            return Err(Error::InvalidInitialData { reason: "t0, q0 and v0 must be finite" });
        }
        if !all_finite(&generalized_force(&self.system, t0, q0, v0)) {
            return Err(Error::InvalidInitialData {
                reason: "the force `force − ∂(dissipation)/∂v` is not finite at the initial data",
            });
        }
        let point = PointDerivatives::at(&self.system, t0, q0, v0);
        let p0 = point.v;
        if !all_finite(&p0) || !self.system.lagrangian(t0, q0, v0).is_finite() {
            return Err(Error::InvalidInitialData {
                reason: "the lagrangian or its momentum is not finite at the initial data",
            });
        }
        // Regularity is a yes-or-no question: asked of the Hessian rounded to f64.
        let hessian = SMatrix::<f64, N, N>::from_fn(|i, k| point.vv[i][k].to_f64());
        if !hessian.iter().all(|x| x.is_finite()) || hessian.try_inverse().is_none() {
            return Err(Error::InvalidInitialData {
                reason: "∂²L/∂v² is singular at the initial data: the legendre transform is not regular",
            });
        }
        Ok(GalerkinIntegrator {
            system: self.system,
            method: self.method,
            h: self.h,
            newton: self.newton,
            state: State { step: 0, t: t0, q: q0, p: p0 },
            carry: [T::zero(); N],
            p_carry: [T::zero(); N],
            last: None,
            v0,
            clock: (t0, 0),
            stats: Stats::default(),
            policy: self.policy,
            fallback: self.fallback,
            energy: T::zero(),
            time_error: T::zero(),
        })
    }
}

/// The last step taken: where it started and its node increments.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct LastStep<const N: usize, const S: usize, T> {
    t0: T,
    h: T,
    q0: [T; N],
    carry: [T; N],
    d: [[T; N]; S],
}

/// A fixed-step variational integrator built on the Galerkin discrete
/// Lagrangian [`Galerkin<S, R>`](Galerkin), for a system with `N` degrees of
/// freedom.
///
/// ```
/// use lagrangian_runtime::galerkin::{Galerkin, GalerkinIntegrator};
/// use lagrangian_runtime::{Lagrangian, Scalar};
///
/// struct Oscillator;
/// impl Lagrangian<1> for Oscillator {
///     const AUTONOMOUS: bool = true;
///     const CYCLIC: [bool; 1] = [false];
///     fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 1], v: [D; 1]) -> D {
///         (v[0] * v[0] - q[0] * q[0]) * 0.5
///     }
/// }
///
/// // Degree 4, 4 Gauss points: order 8. Ten steps per period are plenty.
/// let mut sim = GalerkinIntegrator::new(Oscillator, Galerkin::<4, 4>::gauss(), 0.2 * std::f64::consts::PI)
///     .start(0.0, [1.0], [0.0])?;
/// sim.run(10, |_| {})?;
/// assert!((sim.state().q[0] - 1.0).abs() < 1e-8);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Extended precision
///
/// The whole run can be made in another [`Real`] type: the quadrature, the
/// basis, the Newton block and the state are then computed in it, and the
/// same Lagrangian is evaluated on num-dual's hyper-duals over it. With
/// [`DoubleDouble`](crate::DoubleDouble) (about 32 digits), order 16 shows
/// errors `f64` cannot hold; tighten Newton's `rtol` to the type's precision.
///
/// ```
/// # use lagrangian_runtime::galerkin::{Galerkin, GalerkinIntegrator};
/// # use lagrangian_runtime::{Lagrangian, Scalar};
/// # struct Oscillator;
/// # impl Lagrangian<1> for Oscillator {
/// #     const AUTONOMOUS: bool = true;
/// #     const CYCLIC: [bool; 1] = [false];
/// #     fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 1], v: [D; 1]) -> D {
/// #         (v[0] * v[0] - q[0] * q[0]) * 0.5
/// #     }
/// # }
/// use lagrangian_runtime::{DoubleDouble, NewtonOptions};
///
/// // Degree 8, order 16: one period in 40 steps, back to q = 1 within 1e-28.
/// let h = DoubleDouble::TAU / 40.0;
/// let (zero, one) = (DoubleDouble::from(0.0), DoubleDouble::from(1.0));
/// let mut sim = GalerkinIntegrator::new(Oscillator, Galerkin::<8, 8, DoubleDouble>::gauss(), h)
///     .newton(NewtonOptions { rtol: 1e-30, ..NewtonOptions::default() })
///     .start(zero, [one], [zero])?;
/// sim.run(40, |_| {})?;
/// assert!((sim.state().q[0] - one).abs() < DoubleDouble::from(1e-28));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Clone, Debug)]
pub struct GalerkinIntegrator<Sys, const N: usize, const S: usize, const R: usize, T = f64> {
    pub(super) system: Sys,
    pub(super) method: Galerkin<S, R, T>,
    pub(super) h: T,
    pub(super) newton: NewtonOptions,
    pub(super) state: State<N, T>,
    /// Kahan compensation: the position is `state.q + carry`.
    pub(super) carry: [T; N],
    /// Kahan compensation of the momentum: it is `state.p + p_carry`.
    pub(super) p_carry: [T; N],
    pub(super) last: Option<LastStep<N, S, T>>,
    pub(super) v0: [T; N],
    /// `(t, step)` that `t_k = t + (k − step) h` is measured from.
    pub(super) clock: (T, u64),
    pub(super) stats: Stats,
    /// Energy-preserving steps within these bounds, or fixed steps (`None`).
    pub(super) policy: Option<StepBounds>,
    /// What energy-preserving steps do where no admissible step size solves
    /// the energy equation.
    pub(super) fallback: EnergyFallback,
    /// The discrete energy the energy-preserving steps conserve.
    pub(super) energy: T,
    /// Kahan compensation of `t_k` under energy-preserving steps.
    pub(super) time_error: T,
}

impl<Sys, const S: usize, const R: usize, T: Real> GalerkinIntegrator<Sys, 0, S, R, T> {
    /// Configures an integrator for `system` with the Galerkin discrete
    /// Lagrangian `method` and step `h`; continue with [`GalerkinBuilder::start`].
    ///
    /// The real type `T` of the method is the type of the whole run: `f64`,
    /// or [`DoubleDouble`](crate::DoubleDouble) for about 32 digits.
    #[allow(clippy::new_ret_no_self)]
    pub fn new(system: Sys, method: Galerkin<S, R, T>, h: T) -> GalerkinBuilder<Sys, S, R, T> {
        GalerkinBuilder {
            system,
            method,
            h,
            newton: NewtonOptions::default(),
            policy: None,
            fallback: EnergyFallback::Fail,
        }
    }
}

/// The unknown of a step: the node increments `D_1 … D_s`.
#[derive(Clone, Copy, Debug)]
pub(super) struct Nodes<const N: usize, const S: usize, T>(pub(super) BlockVector<N, S, T>);

impl<const N: usize, const S: usize, T: Real> Unknown for Nodes<N, S, T> {
    const EPSILON: f64 = T::EPSILON;

    #[inline]
    fn update(&mut self, dx: &Self) {
        for (x, d) in self.0.as_flattened_mut().iter_mut().zip(dx.0.as_flattened()) {
            *x += *d;
        }
    }

    #[inline]
    fn error_ratio(&self, dx: &Self, rtol: f64, atol: f64) -> f64 {
        max_abs(dx.0.as_flattened()) / (rtol * max_abs(self.0.as_flattened()) + atol)
    }
}

impl<Sys: Lagrangian<N>, const N: usize, const S: usize, const R: usize, T: Real> GalerkinIntegrator<Sys, N, S, R, T> {
    /// The current state `(k, t_k, q_k, p_k)`.
    pub fn state(&self) -> &State<N, T> {
        &self.state
    }

    /// The system being integrated.
    pub fn system(&self) -> &Sys {
        &self.system
    }

    /// The discrete Lagrangian in use.
    pub fn method(&self) -> &Galerkin<S, R, T> {
        &self.method
    }

    /// The current step size.
    pub fn step_size(&self) -> T {
        self.h
    }

    /// Work counters (Newton iterations per step: `newton_iterations / steps`).
    pub fn stats(&self) -> &Stats {
        &self.stats
    }

    /// The Newton settings in use.
    pub fn newton_options(&self) -> &NewtonOptions {
        &self.newton
    }

    /// The node values `Q_1 … Q_s` of the last step's polynomial (`Q_s = q_k`),
    /// or `None` before the first step.
    pub fn last_nodes(&self) -> Option<[[T; N]; S]> {
        let last = self.last?;
        Some(last.d.map(|d| core::array::from_fn(|i| last.q0[i] + (last.carry[i] + d[i]))))
    }

    /// Changes the step size for the following steps.
    pub fn set_step_size(&mut self, h: T) -> Result<(), Error<N, T>> {
        if !h.is_finite() || self.policy.is_some_and(|b| !(b.h_min..=b.h_max).contains(&h.to_f64())) {
            return Err(Error::InvalidStepSize { h: h.to_f64() });
        }
        Error::<N, T>::check_step(h.to_f64())?;
        self.clock = (self.state.t, self.state.step);
        self.h = h;
        Ok(())
    }

    /// Takes one step of size [`step_size`](Self::step_size).
    ///
    /// On failure nothing changes and the error carries the state and the
    /// Newton diagnostics.
    #[inline]
    pub fn step(&mut self) -> Result<&State<N, T>, Error<N, T>> {
        if let Some(bounds) = self.policy {
            return self.energy_step(bounds);
        }
        let t1 = self.clock.0 + self.h * (self.state.step + 1 - self.clock.1) as f64;
        self.step_by(self.h, t1)
    }

    /// Takes `n` steps, calling `observe` after each.
    pub fn run(&mut self, n: usize, mut observe: impl FnMut(&Self)) -> Result<(), Error<N, T>> {
        for _ in 0..n {
            self.step()?;
            observe(self);
        }
        Ok(())
    }

    /// Steps until `t_end` and stops there exactly, like
    /// [`Integrator::run_until`](crate::Integrator::run_until): the last step
    /// is shortened to land on `t_end` (or stretched by at most `10⁻⁹ h`);
    /// a target equal to the current time is a no-op.
    pub fn run_until(&mut self, t_end: T, mut observe: impl FnMut(&Self)) -> Result<(), Error<N, T>> {
        if !t_end.is_finite() || t_end < self.state.t {
            return Err(Error::InvalidTarget { target: t_end.to_f64(), state: self.state });
        }
        loop {
            if t_end - self.state.t <= T::zero() {
                return Ok(());
            }
            let last = match (self.policy, self.last) {
                (Some(b), Some(last)) => (t_end - self.state.t).to_f64() <= b.bracket(last.h.to_f64()).1,
                (Some(_), None) => t_end - self.state.t <= self.h,
                (None, _) => {
                    let next = self.clock.0 + self.h * (self.state.step + 1 - self.clock.1) as f64;
                    next >= t_end - self.h * 1e-9
                }
            };
            if last {
                let h = self.h;
                self.step_by(t_end - self.state.t, t_end)?;
                self.clock = (self.state.t, self.state.step);
                if self.policy.is_some() {
                    // A fixed landing step: conserve its energy from here on,
                    // and keep the solved step as the next guess.
                    self.reread_energy();
                    self.h = h;
                }
                observe(self);
                return Ok(());
            }
            self.step()?;
            observe(self);
        }
    }

    /// The first guess for the increments of a step of size `h`.
    #[inline]
    pub(super) fn predict(&self, h: T) -> BlockVector<N, S, T> {
        let g = &self.method;
        match &self.last {
            Some(last) if last.h == h => core::array::from_fn(|m| {
                core::array::from_fn(|i| (0..S).map(|n| g.extrapolate[m][n] * last.d[n][i]).sum())
            }),
            Some(last) => {
                // Extrapolate the last polynomial, in its own variable τ ∈ [0, 1],
                // to the control nodes of the new step, 1 + τ_m h/h_last.
                let rho = h / last.h;
                let mut out = [[T::zero(); N]; S];
                for m in 0..S {
                    let tau = T::one() + g.control[m] * rho;
                    for n in 0..S {
                        let w = g.basis(n + 1, tau) - if n + 1 == S { 1.0 } else { 0.0 };
                        for i in 0..N {
                            out[m][i] += w * last.d[n][i];
                        }
                    }
                }
                out
            }
            None => g.control.map(|tau| self.v0.map(|v| v * tau * h)),
        }
    }

    /// One step of size `h` stamped with end time `t1`.
    #[inline]
    pub(super) fn step_by(&mut self, h: T, t1: T) -> Result<&State<N, T>, Error<N, T>> {
        let State { t: t0, q: q0, p: p0, .. } = self.state;
        let e = self.carry;
        let (system, g, min_rcond) = (&self.system, &self.method, self.newton.min_rcond);
        let pc = self.p_carry;
        // Simplified Newton first: the Jacobian is assembled and factored at
        // the first guess only, and later iterations cost the gradient of L at
        // the quadrature points and one triangular solve (N instead of
        // N(2N + 1) hyper-dual evaluations per point, no assembly, no LU). With
        // the extrapolated guess it converges in about as many iterations as
        // full Newton. If it fails: full Newton from the same guess, then from
        // the straight line at the last secant velocity (v0 at the first step).
        // The condition estimate is made on the first iteration of each solve.
        let first = Cell::new(true);
        let frozen: Cell<Option<Lu<N, S, T>>> = Cell::new(None);
        let simplified = Cell::new(true);
        let last_correction: Cell<Option<f64>> = Cell::new(None);
        let linearize = |x: &Nodes<N, S, T>| {
            let check = if first.replace(false) { min_rcond } else { 0.0 };
            let reuse = if simplified.get() { frozen.get() } else { None };
            let (lin, lu) = linearize(system, g, t0, h, (&q0, &e), (&p0, &pc), &x.0, check, reuse.as_ref())?;
            if simplified.get() {
                frozen.set(Some(lu));
                // A frozen Jacobian that contracts slowly (a large step, a poor
                // guess) is refreshed at the next iterate.
                let size = max_abs(lin.correction.0.as_flattened());
                if last_correction.replace(Some(size)).is_some_and(|last| size > 0.05 * last) {
                    frozen.set(None);
                }
            }
            Ok(lin)
        };
        let attempt = |guess: BlockVector<N, S, T>, simplify: bool| {
            first.set(true);
            frozen.set(None);
            last_correction.set(None);
            simplified.set(simplify);
            newton::solve(Nodes(guess), &self.newton, &linearize)
        };
        let predicted = self.predict(h);
        let mut spent = 0;
        // (Degree 1 has a single block: full Newton is cheaper there, measured
        // 148 against 222 ns per pendulum step.)
        let mut solved = attempt(predicted, S >= 2);
        for (guess, simplify) in [(None, false), (Some(()), false)] {
            let Err(failure) = &solved else { break };
            spent += failure.iterations();
            let guess = match guess {
                None => predicted,
                Some(()) => {
                    let v = match &self.last {
                        Some(last) => last.d[S - 1].map(|x| x / last.h),
                        None => self.v0,
                    };
                    g.control.map(|tau| v.map(|v| v * tau * h))
                }
            };
            solved = attempt(guess, simplify);
        }
        // Every attempt counts in the iterations reported.
        let solved = match solved {
            Ok((x, mut report)) => {
                report.iterations += spent;
                Ok((x, report))
            }
            Err(failure) => Err(with_iterations(failure, spent)),
        };
        let (d, report) = match solved {
            Ok((x, report)) => (x.0, report),
            Err(failure) => return Err(self.fail(h, failure)),
        };
        if let Some(last) = &self.last {
            let f = |x: &[T; N]| x.map(|v| v.to_f64());
            let rho = (h / last.h).to_f64();
            let reached = f(&last.d[S - 1]).map(|x| x * rho);
            if implausible_growth(&f(&d[S - 1]), &f(&predicted[S - 1]), &reached, &f(&q0)) {
                let reason = IMPLAUSIBLE_GROWTH;
                return Err(self.fail(h, NewtonFailure::Rejected { iterations: report.iterations, reason }));
            }
        }
        self.commit(h, t1, d, report)
    }

    /// Applies a step of size `h` (end time `t1`) whose block system is
    /// solved by the increments `d`: the momentum update, the Kahan sums and
    /// the checks of every published value. On failure nothing changes.
    #[inline]
    pub(super) fn commit(
        &mut self,
        h: T,
        t1: T,
        d: BlockVector<N, S, T>,
        report: NewtonReport,
    ) -> Result<&State<N, T>, Error<N, T>> {
        let State { step, t: t0, q: q0, p: p0 } = self.state;
        let e = self.carry;
        let (system, g) = (&self.system, &self.method);
        // p_{k+1} = ∂A/∂Q_s at the solution, which the q_k row and the
        // interior rows turn into the momentum balance
        //     p_{k+1} = p_k + ∂A/∂q_k|_D = p_k + h Σ_j b_j ∂L/∂q(c_j)
        // (the update of the equivalent partitioned Runge–Kutta method). Taken
        // in this form, the momentum of a cyclic coordinate is conserved
        // exactly (its ∂L/∂q is zero) instead of up to the round-off of the
        // interior rows, and summed with Kahan's compensation like q, the
        // rounding of p grows like ε|Δp| = O(εh) per step instead of ε|p|.
        let mut dp = [T::zero(); N];
        let mut lagrangian_finite = true;
        for j in 0..R {
            let (t, q, v) = g.point(t0, h, (&q0, &e), &d, j);
            let (l, mut lq, _) = point_gradient(system, t, q, v);
            if Sys::HAS_FORCE || Sys::HAS_DISSIPATION {
                // p_{k+1} − p_k = h Σ_j b_j (∂L/∂q + F)(c_j): the forces on all
                // s + 1 nodes sum to h Σ_j b_j F_j (the basis sums to one).
                let f = generalized_force(system, t, q, v);
                for i in 0..N {
                    lq[i] += f[i];
                }
            }
            // The derivatives can be finite where L is not (L = ln(1 − q)
            // past q = 1 has a finite derivative on the wrong branch): the
            // step is only valid where the action itself is.
            lagrangian_finite &= l.is_finite();
            let w = g.quadrature().weights()[j] * h;
            for i in 0..N {
                dp[i] += w * lq[i];
            }
        }
        let (p1, p_carry) = kahan(&p0, &self.p_carry, &dp);
        // q_{k+1} = (q_k + e_k) + D_s, Kahan-summed.
        let (q1, carry) = kahan(&q0, &e, &d[S - 1]);
        // L at the end node too, which Gauss points do not reach.
        if lagrangian_finite {
            let mut v1 = [T::zero(); N];
            for n in 0..S {
                for i in 0..N {
                    v1[i] += g.end_d[n] * d[n][i];
                }
            }
            for x in &mut v1 {
                *x /= h;
            }
            lagrangian_finite = system.lagrangian(t1, q1, v1).is_finite();
        }
        let quantity = if lagrangian_finite { non_finite(t1, &q1, &p1) } else { Some("lagrangian") };
        if let Some(quantity) = quantity {
            self.stats.failed_steps += 1;
            return Err(Error::NonFinite { state: self.state, h: h.to_f64(), iterations: report.iterations, quantity });
        }
        self.last = Some(LastStep { t0, h, q0, carry: e, d });
        self.carry = carry;
        self.p_carry = p_carry;
        self.state = State { step: step + 1, t: t1, q: q1, p: p1 };
        self.stats.steps += 1;
        self.stats.newton_iterations += report.iterations as u64;
        self.stats.last = report;
        Ok(&self.state)
    }

    /// The size of the last step, `None` before the first.
    pub(super) fn last_step_size(&self) -> Option<T> {
        self.last.map(|l| l.h)
    }

    /// `(t0, h, q0, carry, d)` of the last step.
    #[allow(clippy::type_complexity)]
    pub(super) fn last_step_parts(&self) -> Option<(T, T, [T; N], [T; N], BlockVector<N, S, T>)> {
        self.last.map(|l| (l.t0, l.h, l.q0, l.carry, l.d))
    }

    /// The discrete energy `E_k = Σ_j b_j E_L(c_j)` of the last step (minus
    /// `∂A/∂h` at fixed nodes, for an autonomous `L`): under
    /// energy-preserving steps, the quantity conserved. `None` before the
    /// first step and for a time-dependent `L`.
    pub fn discrete_energy(&self) -> Option<T> {
        if !Sys::AUTONOMOUS {
            return None;
        }
        let (t0, h, q0, carry, d) = self.last_step_parts()?;
        Some(super::energy::step_energy(&self.system, &self.method, t0, h, (&q0, &carry), &d))
    }

    /// The step policy: `Some(bounds)` for energy-preserving steps.
    pub fn policy(&self) -> Option<StepBounds> {
        self.policy
    }

    pub(super) fn fail(&mut self, h: T, failure: NewtonFailure) -> Error<N, T> {
        self.stats.failed_steps += 1;
        Error::from_newton(failure, self.state, h.to_f64())
    }
}

/// Readouts that solve in `f64` (the inverse Legendre transform, the tangent map).
impl<Sys: Lagrangian<N>, const N: usize, const S: usize, const R: usize> GalerkinIntegrator<Sys, N, S, R> {
    /// The velocity `v_k` whose momentum `∂L/∂v(t_k, q_k, v_k)` is `p_k`.
    pub fn velocity(&self) -> Result<[f64; N], Error<N>> {
        let State { t, q, p, .. } = self.state;
        let guess = match &self.last {
            // The velocity at the end of the last step's polynomial.
            Some(last) => core::array::from_fn(|i| {
                (0..S).map(|n| self.method.basis_derivative(n + 1, 1.0) * last.d[n][i]).sum::<f64>() / last.h
            }),
            None => self.v0,
        };
        self.system.velocity(t, q, p, guess).map_err(|f| Error::InverseLegendre {
            state: self.state,
            iterations: f.iterations,
            residual_norm: f.residual_norm,
        })
    }

    /// The energy `E_L(t_k, q_k, v_k)` at the velocity of the current momentum.
    pub fn energy(&self) -> Result<f64, Error<N>> {
        let v = self.velocity()?;
        Ok(self.system.energy(self.state.t, self.state.q, v))
    }

    /// The discrete momentum map `J_k = p_k·ξ(q_k)` of a symmetry at the current node.
    pub fn momentum_map(&self, symmetry: &(impl crate::noether::Generator<N> + ?Sized)) -> f64 {
        crate::noether::momentum_map(symmetry, &self.state.q, &self.state.p)
    }

    /// The forcing impulse `Σ_m F^m·ξ(Q_m)` of the last step over its nodes
    /// `Q_0 = q_{k−1}, …, Q_s = q_k`, with `F^m = h Σ_j b_j ℓ_m(c_j) F(c_j)` the
    /// discrete force on node `m`; `None` before the first step.
    ///
    /// For a symmetry of `L` (`ξ` with `∂L/∂q·ξ + ∂L/∂v·ξ'(q)v = 0` along the
    /// step) the step action is invariant, the interior equations
    /// `∂A/∂Q_m + F^m = 0` hold, and so `J_k − J_{k−1}` equals this impulse
    /// (the discrete Noether theorem with forcing, through the basis).
    pub fn forcing_impulse(&self, symmetry: &(impl crate::noether::Generator<N> + ?Sized)) -> Option<f64> {
        let last = self.last?;
        let g = &self.method;
        let mut fnode = [[0.0; N]; S];
        let mut f_end = [0.0; N];
        for j in 0..R {
            let (t, q, v) = g.point(last.t0, last.h, (&last.q0, &last.carry), &last.d, j);
            let f = generalized_force(&self.system, t, q, v);
            let w = g.quadrature().weights()[j] * last.h;
            for i in 0..N {
                for m in 0..S {
                    fnode[m][i] += w * (g.row[j][m] * f[i]);
                }
                f_end[i] += w * (g.col[j][S - 1] * f[i]);
            }
        }
        let node = |m: usize| -> [f64; N] {
            core::array::from_fn(|i| last.q0[i] + (last.carry[i] + if m == 0 { 0.0 } else { last.d[m - 1][i] }))
        };
        let dot = |a: &[f64; N], b: &[f64; N]| (0..N).map(|i| a[i] * b[i]).sum::<f64>();
        let mut impulse = dot(&f_end, &symmetry.generator(&node(S)));
        for m in 0..S {
            impulse += dot(&fnode[m], &symmetry.generator(&node(m)));
        }
        Some(impulse)
    }

    /// The tangent map `∂(q_k, p_k)/∂(q_{k−1}, p_{k−1})` of the last step
    /// (docs/theory.md §8), or `None` before the first step or where the Newton
    /// block is singular.
    ///
    /// By the implicit function theorem on the block system, with the
    /// interior nodes as functions of `(q_k, p_k)`; the Hessian comes from
    /// [`Galerkin::node_hessian`]. Allocates; a diagnostic, not for the
    /// stepping loop.
    ///
    /// Also `None` for a system with forces, whose step map is not symplectic.
    pub fn last_tangent_map(&self) -> Option<TangentMap<N>> {
        if Sys::HAS_FORCE || Sys::HAS_DISSIPATION {
            return None;
        }
        let last = self.last?;
        let q0 = core::array::from_fn(|i| last.q0[i] + last.carry[i]);
        tangent_map(&self.system, &self.method, last.t0, last.h, q0, &last.d)
    }
}

/// The tangent map of the Galerkin step from `(t0, q0)` with node increments `d`.
///
/// ```text
/// F(X; q_k, p_k) = (p_k + ∂A/∂Q_0, ∂A/∂Q_1, …, ∂A/∂Q_{s−1}) = 0,   X = (Q_1, …, Q_s)
/// dX = −J⁻¹ (H_{·0} dq_k + E dp_k),   J = H_{ρ n} (ρ = 0…s−1, n = 1…s),   E = (I, 0, …, 0)ᵀ
/// dq_{k+1} = dQ_s,   dp_{k+1} = H_{s0} dq_k + Σ_n H_{sn} dQ_n
/// ```
pub fn tangent_map<Sys, const N: usize, const S: usize, const R: usize>(
    system: &Sys,
    method: &Galerkin<S, R>,
    t0: f64,
    h: f64,
    q0: [f64; N],
    d: &[[f64; N]; S],
) -> Option<TangentMap<N>>
where
    Sys: Lagrangian<N> + ?Sized,
{
    use nalgebra::{DMatrix, SMatrix};
    let hess = method.node_hessian(system, t0, h, q0, d);
    let sn = S * N;
    let j = hess.view((0, N), (sn, sn)).into_owned();
    // Right-hand sides: columns for dq_k (N) then dp_k (N).
    let mut rhs = DMatrix::zeros(sn, 2 * N);
    rhs.view_mut((0, 0), (sn, N)).copy_from(&hess.view((0, 0), (sn, N)));
    for i in 0..N {
        rhs[(i, N + i)] = 1.0;
    }
    let dx = -j.lu().solve(&rhs)?;
    let dq1 = dx.view((sn - N, 0), (N, 2 * N)).into_owned();
    let mut dp1 = hess.view((sn, N), (N, sn)) * &dx;
    let h_s0 = hess.view((sn, 0), (N, N)).into_owned();
    let mut top = dp1.view_mut((0, 0), (N, N));
    top += &h_s0;
    let block = |m: &DMatrix<f64>, c: usize| SMatrix::<f64, N, N>::from_fn(|a, b| m[(a, c + b)]);
    let out = TangentMap { dq_dq: block(&dq1, 0), dq_dp: block(&dq1, N), dp_dq: block(&dp1, 0), dp_dp: block(&dp1, N) };
    out.matrix().iter().all(|x| x.is_finite()).then_some(out)
}

/// Residual and Newton correction of the block system at the increments `d`.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(super) fn linearize<Sys, T, const N: usize, const S: usize, const R: usize>(
    system: &Sys,
    g: &Galerkin<S, R, T>,
    t0: T,
    h: T,
    base: (&[T; N], &[T; N]),
    (p0, pc): (&[T; N], &[T; N]),
    d: &BlockVector<N, S, T>,
    min_rcond: f64,
    frozen: Option<&Lu<N, S, T>>,
) -> Result<(Linearization<Nodes<N, S, T>>, Lu<N, S, T>), Breakdown>
where
    Sys: Lagrangian<N> + ?Sized,
    T: Real,
{
    let zero = T::zero();
    let inv_h = h.recip();
    let mut r: BlockVector<N, S, T> = [[zero; N]; S];
    // Size of the terms that cancel in each block row.
    let mut scale = [0.0; S];
    scale[0] = max_abs(p0);
    let mut jac: BlockMatrix<N, S, T> = [[[[zero; N]; S]; N]; S];
    let mut direct = [zero; N];
    let mut grad: BlockVector<N, S, T> = [[zero; N]; S];
    // Discrete forces on the nodes Q_0 … Q_{s−1} (the last node's, F^s, only
    // enters p_{k+1}).
    let mut fnode: BlockVector<N, S, T> = [[zero; N]; S];
    let forced = Sys::HAS_FORCE || Sys::HAS_DISSIPATION;
    for j in 0..R {
        let (t, q, v) = g.point(t0, h, base, d, j);
        // The Hessian only when the Jacobian is to be assembled.
        let (lq, lv, pd) = match frozen {
            Some(_) => {
                let (lq, lv) = gradient_at(system, t, q, v);
                (lq, lv, None)
            }
            None => {
                let pd = PointDerivatives::at(system, t, q, v);
                (pd.q, pd.v, Some(pd))
            }
        };
        let b = g.quadrature().weights()[j];
        let (row, row_d, col, col_d) = (&g.row[j], &g.row_d[j], &g.col[j], &g.col_d[j]);
        // Lagrange–d'Alembert: the virtual work h Σ_j b_j F_j·δq(c_j) puts
        // h b_j ℓ_m(c_j) F_j on node m (Fu, Dai & Tang's discrete forces, through
        // the basis); with the Jacobian, their derivatives in the unknowns.
        let force = forced.then(|| match frozen {
            Some(_) => (generalized_force(system, t, q, v), None),
            None => {
                let (f, dq, dv) = force_derivatives(system, t, q, v);
                (f, Some((dq, dv)))
            }
        });
        if let Some((f, df)) = &force {
            let w = b * h;
            for m in 0..S {
                for i in 0..N {
                    let x = w * (row[m] * f[i]);
                    fnode[m][i] += x;
                    let k = m;
                    scale[k] = f64::max(scale[k], x.abs().to_f64());
                }
            }
            if let Some((dq, dv)) = df {
                for n in 0..S {
                    let (c, cd) = (b * h * col[n], b * col_d[n]);
                    for rho in 0..S {
                        let l = row[rho];
                        for i in 0..N {
                            for k in 0..N {
                                jac[rho][i][n][k] += l * (c * dq[i][k] + cd * dv[i][k]);
                            }
                        }
                    }
                }
            }
        }
        // The weight w = b h is rounded once and shared by every row, and the
        // coefficients of the basis are not premultiplied: all rows are then
        // derivatives of the same action Σ w_j L, whatever the rounding.
        let w = b * h;
        let lv_h: [T; N] = core::array::from_fn(|i| lv[i] / h);
        // ∂A/∂q_k at fixed increments.
        for i in 0..N {
            let x = w * lq[i];
            direct[i] += x;
            scale[0] = f64::max(scale[0], x.to_f64().abs());
        }
        // ∂A/∂D_m for the nodes m = 1 … s.
        for m in 0..S {
            let (c, cd) = (col[m], col_d[m]);
            for i in 0..N {
                let (x, y) = (w * (c * lq[i]), w * (cd * lv_h[i]));
                grad[m][i] += x + y;
                let k = if m + 1 < S { m + 1 } else { 0 };
                scale[k] = f64::max(scale[k], (x.abs() + y.abs()).to_f64());
            }
        }
        let Some(pd) = pd else { continue };
        for n in 0..S {
            // The column block n of this point's contribution, before the row basis.
            let (c, cd) = (b * col[n], b * col_d[n]);
            let mut yq = [[zero; N]; N];
            let mut yv = [[zero; N]; N];
            for i in 0..N {
                for k in 0..N {
                    yq[i][k] = h * c * pd.qq[i][k] + cd * pd.qv[i][k];
                    yv[i][k] = c * pd.qv[k][i] + cd * inv_h * pd.vv[i][k];
                }
            }
            for rho in 0..S {
                let (l, ld) = (row[rho], row_d[rho]);
                for i in 0..N {
                    for k in 0..N {
                        jac[rho][i][n][k] += l * yq[i][k] + ld * yv[i][k];
                    }
                }
            }
        }
    }
    // Rows: p_k + ∂A/∂Q_0 = p_k + ∂A/∂q_k|_D − Σ_m ∂A/∂D_m, then ∂A/∂D_m for
    // the interior nodes. Formed this way, the q_k row is the derivative of
    // exactly the action the other rows differentiate (see `Galerkin::new`).
    for i in 0..N {
        // (p_k − ∂A/∂D_s) + (compensation + ∂A/∂q_k|_D − Σ_interior ∂A/∂D_m)
        let mut x = pc[i] + direct[i];
        for gm in &grad[..S - 1] {
            x -= gm[i];
        }
        r[0][i] = (p0[i] - grad[S - 1][i]) + (x + fnode[0][i]);
    }
    for m in 1..S {
        for i in 0..N {
            r[m][i] = grad[m - 1][i] + fnode[m][i];
        }
    }
    if !all_finite(r.as_flattened()) {
        return Err(Breakdown::NonFinite("residual"));
    }
    let lu = match frozen {
        Some(lu) => *lu,
        None => Lu::factor(&jac).map_err(|f| match f {
            LuFailure::Singular => Breakdown::Singular(0.0),
            LuFailure::NonFinite => Breakdown::NonFinite("jacobian"),
        })?,
    };
    if min_rcond > 0.0 {
        let rc = lu.rcond();
        if rc.is_nan() || rc < min_rcond {
            return Err(Breakdown::Singular(rc));
        }
    }
    let x = lu.solve(&r);
    let correction = Nodes(x.map(|b| b.map(|v| -v)));
    let mut residual_ratio: f64 = 0.0;
    for rho in 0..S {
        residual_ratio = residual_ratio.max(max_abs(&r[rho]) / scale[rho]);
    }
    Ok((Linearization { correction, residual_norm: max_abs(r.as_flattened()), residual_ratio }, lu))
}

/// The failure with `spent` earlier iterations added to its count.
pub(super) fn with_iterations(failure: NewtonFailure, spent: usize) -> NewtonFailure {
    match failure {
        NewtonFailure::NotConverged(mut r) => {
            r.iterations += spent;
            NewtonFailure::NotConverged(r)
        }
        NewtonFailure::Singular { iterations, rcond } => {
            NewtonFailure::Singular { iterations: iterations + spent, rcond }
        }
        NewtonFailure::NonFinite { iterations, quantity } => {
            NewtonFailure::NonFinite { iterations: iterations + spent, quantity }
        }
        NewtonFailure::Rejected { iterations, reason } => {
            NewtonFailure::Rejected { iterations: iterations + spent, reason }
        }
    }
}

/// The generalised force `F = Q − ∂R/∂v` at one point and its Jacobians
/// `(∂F_i/∂q_k, ∂F_i/∂v_k)`: `2N` evaluations on duals over `T`.
#[inline]
#[allow(clippy::type_complexity)]
fn force_derivatives<Sys, T, const N: usize>(
    system: &Sys,
    t: T,
    q: [T; N],
    v: [T; N],
) -> ([T; N], [[T; N]; N], [[T; N]; N])
where
    Sys: Lagrangian<N> + ?Sized,
    T: Real,
{
    use num_dual::Dual;
    let z = T::zero();
    let (mut f, mut dq, mut dv) = ([z; N], [[z; N]; N], [[z; N]; N]);
    for k in 0..2 * N {
        let mut qd = q.map(Dual::from_re);
        let mut vd = v.map(Dual::from_re);
        if k < N {
            qd[k].eps = T::one();
        } else {
            vd[k - N].eps = T::one();
        }
        let y = generalized_force(system, Dual::from_re(t), qd, vd);
        for i in 0..N {
            f[i] = y[i].re;
            if k < N {
                dq[i][k] = y[i].eps;
            } else {
                dv[i][k - N] = y[i].eps;
            }
        }
    }
    (f, dq, dv)
}
