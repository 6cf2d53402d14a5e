//! The fixed-step variational integrator (docs/theory.md §3, position–momentum form).
//!
//! ```text
//! given (t_k, q_k, p_k):   solve  p_k + ∂A/∂q_k (x_k, x_{k+1}) = 0   for q_{k+1},   t_{k+1} = t_k + h
//!                          then   p_{k+1} = ∂A/∂q_{k+1} (x_k, x_{k+1})
//! ```
//!
//! Each Newton iteration is one hyper-dual sweep of the action; the state is
//! only replaced once a step has converged, so a failed step leaves the
//! integrator as it was.

use nalgebra::SVector;

use crate::derivatives::{self, Segment};
use crate::discrete::DiscreteLagrangian;
use crate::error::Error;
use crate::forcing::{self, DiscreteForces, EnergyBalance};
use crate::mechanics::DiscreteMechanics;
use crate::newton::{self, NewtonFailure, NewtonOptions, NewtonReport};
use crate::real::{all_finite, max_abs};
use crate::state::State;
use crate::symplectic::{self, TangentMap};
use crate::system::Lagrangian;

mod variable_step;

pub use variable_step::{EnergyFallback, StepBounds};

/// Counters of the work an integrator has done.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Stats {
    /// Steps taken successfully.
    pub steps: u64,
    /// Newton iterations (residual-and-Jacobian evaluations) over all successful steps.
    pub newton_iterations: u64,
    /// Steps that failed and were not applied.
    pub failed_steps: u64,
    /// Energy-preserving steps taken by [`EnergyFallback::LeastSquares`]
    /// because no step size satisfied the energy equation.
    pub energy_fallbacks: u64,
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
pub struct IntegratorBuilder<S, M> {
    system: S,
    method: M,
    h: f64,
    newton: NewtonOptions,
    policy: StepPolicy,
    fallback: EnergyFallback,
}

/// How the integrator chooses its step sizes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum StepPolicy {
    /// Every step has the configured size `h` (docs/theory.md §3, fixed step).
    Fixed,
    /// Energy-preserving variable steps (Lee; Kane, Marsden & Ortiz; paper
    /// 001 §3, 003 §3.2): each `h_k` is an unknown of the step, fixed by the
    /// discrete energy equation `E_{k+1} = E_k` (for a time-dependent `L`, the
    /// energy-evolution equation of de León & Martín de Diego). The configured `h` is the
    /// first guess.
    EnergyPreserving(StepBounds),
}

impl<S, M: DiscreteLagrangian> IntegratorBuilder<S, M> {
    /// Energy-preserving variable steps within `bounds`, starting from the
    /// guess `h` given to [`Integrator::new`].
    pub fn energy_preserving(mut self, bounds: StepBounds) -> Self {
        self.policy = StepPolicy::EnergyPreserving(bounds);
        self
    }

    /// What energy-preserving steps do where no admissible step size
    /// satisfies the energy equation (default: [`EnergyFallback::Fail`]).
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
    /// Fails with [`Error::InvalidStepSize`] for a step that is not finite and
    /// positive, with [`Error::InvalidInitialData`] for non-finite data or
    /// where `∂²L/∂v²` is singular (the Legendre transform is not regular and
    /// the one-step map does not exist) or the generalised force is not
    /// finite there, and with [`Error::Unsupported`] for a system with `force`
    /// or `dissipation` under [`StepPolicy::EnergyPreserving`] (its energy is
    /// not conserved; see [`forcing`](crate::forcing) for the fixed-step
    /// Lagrange–d'Alembert integrator and its energy balance).
    pub fn start<const N: usize>(self, t0: f64, q0: [f64; N], v0: [f64; N]) -> Result<Integrator<S, M, N>, Error<N>>
    where
        S: Lagrangian<N>,
    {
        Error::<N>::check_setup(self.h, &self.newton)?;
        if let StepPolicy::EnergyPreserving(b) = self.policy {
            if !b.valid() {
                return Err(Error::InvalidStepBounds { h_min: b.h_min, h_max: b.h_max, max_ratio: b.max_ratio });
            }
            if !(b.h_min..=b.h_max).contains(&self.h) {
                return Err(Error::InvalidStepSize { h: self.h });
            }
        }
        if forcing::is_forced::<S, N>() && matches!(self.policy, StepPolicy::EnergyPreserving(_)) {
            return Err(Error::Unsupported {
                what: "energy-preserving steps for a system with `force` or `dissipation`: its energy is not \
                       conserved, so the energy equation that fixes the step sizes does not hold; use fixed steps",
            });
        }
        if !t0.is_finite() || !all_finite(&q0) || !all_finite(&v0) {
            return Err(Error::InvalidInitialData { reason: "t0, q0 and v0 must be finite" });
        }
        if !all_finite(&forcing::generalized_force(&self.system, t0, q0, v0)) {
            return Err(Error::InvalidInitialData {
                reason: "the force `force − ∂(dissipation)/∂v` is not finite at the initial data",
            });
        }
        let p0 = self.system.momentum(t0, q0, v0);
        if !all_finite(&p0) || !self.system.lagrangian_value(t0, q0, v0).is_finite() {
            return Err(Error::InvalidInitialData {
                reason: "the lagrangian or its momentum is not finite at the initial data",
            });
        }
        let hessian = self.system.velocity_hessian(t0, q0, v0);
        if !hessian.iter().all(|x| x.is_finite()) || hessian.try_inverse().is_none() {
            return Err(Error::InvalidInitialData {
                reason: "∂²L/∂v² is singular at the initial data: the legendre transform is not regular",
            });
        }
        let energy = self.system.energy(t0, q0, v0);
        if !energy.is_finite() {
            return Err(Error::InvalidInitialData { reason: "the energy is not finite at the initial data" });
        }
        Ok(Integrator {
            policy: self.policy,
            fallback: self.fallback,
            energy,
            time_error: 0.0,
            energy_carry: 0.0,
            watched_energy: None,
            system: self.system,
            method: self.method,
            h: self.h,
            newton: self.newton,
            state: State { step: 0, t: t0, q: q0, p: p0 },
            carry: Compensation::default(),
            previous: None,
            earlier: None,
            v0,
            clock: Clock { t: t0, step: 0 },
            stats: Stats::default(),
        })
    }
}

/// The rounding errors of the Kahan sums of `q_k` and `p_k`: the exact sums
/// are `q_k + q` and `p_k + p`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Compensation<const N: usize> {
    pub(crate) q: [f64; N],
    pub(crate) p: [f64; N],
}

impl<const N: usize> Default for Compensation<N> {
    fn default() -> Self {
        Self { q: [0.0; N], p: [0.0; N] }
    }
}

/// `a + (c + b)` summed with Kahan's compensation `c`: `(sum, new compensation)`.
#[inline(always)]
pub(crate) fn kahan<T: crate::real::Real, const N: usize>(a: &[T; N], c: &[T; N], b: &[T; N]) -> ([T; N], [T; N]) {
    let mut sum = [T::zero(); N];
    let mut carry = [T::zero(); N];
    for i in 0..N {
        let u = c[i] + b[i];
        sum[i] = a[i] + u;
        carry[i] = u - (sum[i] - a[i]);
    }
    (sum, carry)
}

/// `true` when the increment `dq` of a converged step is more than `10⁶`
/// times both the predicted one and the last one (scaled to the same step),
/// and larger than the position `q` itself: Newton found a root, but not one a
/// trajectory reaches. Smooth motion changes its increment by a factor
/// `e^{λh}` per step; a growth of `10⁶` in one step is an unresolved (or, for
/// explicit discrete Lagrangians, unstable) step size, or a spurious root of
/// the DEL far away. Motion that starts from an increment of exactly zero (a
/// first-order α-β step from rest) has no scale to compare with and passes.
pub(crate) fn implausible_growth<const N: usize>(
    dq: &[f64; N],
    predicted: &[f64; N],
    last: &[f64; N],
    q: &[f64; N],
) -> bool {
    let scale = max_abs(predicted).max(max_abs(last));
    scale > 0.0 && max_abs(dq) > 1e6 * scale.max(1e-6 * max_abs(q))
}

/// Why a step rejected by [`implausible_growth`] is refused.
pub(crate) const IMPLAUSIBLE_GROWTH: &str = "the solution's increment is over 1e6 times the predicted and the last one: \
                                            a root far from the trajectory (an unstable or unresolved step size)";

/// Which of the values a step publishes is not finite, if any.
pub(crate) fn non_finite<T: crate::real::Real, const N: usize>(t: T, q: &[T; N], p: &[T; N]) -> Option<&'static str> {
    if !all_finite(q) {
        Some("position")
    } else if !all_finite(p) {
        Some("momentum")
    } else if !t.is_finite() {
        Some("time")
    } else {
        None
    }
}

/// Where `t_k = t + (k − step)·h` is measured from; reset whenever `h` changes,
/// so that times stay exact multiples of `h` instead of accumulating round-off.
#[derive(Clone, Copy, Debug)]
struct Clock {
    t: f64,
    step: u64,
}

/// A fixed-step variational integrator for a system `S` with `N` degrees of
/// freedom and a discrete Lagrangian `M`.
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
#[derive(Clone, Debug)]
pub struct Integrator<S, M, const N: usize> {
    system: S,
    method: M,
    h: f64,
    newton: NewtonOptions,
    state: State<N>,
    /// Kahan compensation of `q_k` and `p_k`.
    carry: Compensation<N>,
    policy: StepPolicy,
    fallback: EnergyFallback,
    /// `E_k`, kept up to date by variable steps (fixed steps compute it on demand).
    energy: f64,
    /// Kahan compensation of `t_k` under variable steps.
    time_error: f64,
    /// Kahan compensation of the energy target `energy`.
    energy_carry: f64,
    /// The discrete energy of the last step, kept by the energy-jump watch of
    /// a system declared discontinuous (`None` before the first step).
    watched_energy: Option<f64>,
    /// The last step, from node `k − 1` to node `k`; `None` at the start.
    previous: Option<Segment<N>>,
    /// `(h, dq)` of the step before that, for the predictor.
    earlier: Option<(f64, [f64; N])>,
    v0: [f64; N],
    clock: Clock,
    stats: Stats,
}

impl<S, M: DiscreteLagrangian> Integrator<S, M, 0> {
    /// Configures an integrator for `system` with the discrete Lagrangian
    /// `method` and step `h`; continue with [`IntegratorBuilder::start`].
    #[allow(clippy::new_ret_no_self)]
    pub fn new(system: S, method: M, h: f64) -> IntegratorBuilder<S, M> {
        IntegratorBuilder {
            system,
            method,
            h,
            newton: NewtonOptions::default(),
            policy: StepPolicy::Fixed,
            fallback: EnergyFallback::Fail,
        }
    }
}

impl<S: Lagrangian<N>, M: DiscreteLagrangian, const N: usize> Integrator<S, M, N> {
    /// The current state `(k, t_k, q_k, p_k)`.
    pub fn state(&self) -> &State<N> {
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

    /// The current step size.
    pub fn step_size(&self) -> f64 {
        self.h
    }

    /// Work counters.
    pub fn stats(&self) -> &Stats {
        &self.stats
    }

    /// The Newton settings in use.
    pub fn newton_options(&self) -> &NewtonOptions {
        &self.newton
    }

    /// Changes the step size for the following steps (for example to retry a
    /// failed step with a smaller one). The integrator stays variational: the
    /// DEL equations hold with the step sizes actually taken.
    ///
    /// Under energy-preserving steps `h` is the next guess and must lie in
    /// `[h_min, h_max]`.
    pub fn set_step_size(&mut self, h: f64) -> Result<(), Error<N>> {
        Error::<N>::check_step(h)?;
        if let StepPolicy::EnergyPreserving(b) = self.policy
            && !(b.h_min..=b.h_max).contains(&h)
        {
            return Err(Error::InvalidStepSize { h });
        }
        self.clock = Clock { t: self.state.t, step: self.state.step };
        self.h = h;
        Ok(())
    }

    /// Takes one step of size [`step_size`](Self::step_size).
    ///
    /// On failure nothing changes: the state, the step size and the predictor
    /// are those from before the call.
    #[inline]
    pub fn step(&mut self) -> Result<&State<N>, Error<N>> {
        if let StepPolicy::EnergyPreserving(bounds) = self.policy {
            if self.previous.is_some() {
                return self.energy_step(bounds);
            }
            // The first step has the given h0 (Luo, Guo, Li & Wu §V starts from τ0):
            // E_L(q0, v0) is not the discrete energy of any step, and
            // demanding E_1 = E_L(q0, v0) has no root but h → 0. The energy
            // conserved from then on is the discrete E_1, within O(h0²) of E_L.
            let h = self.h;
            self.step_by(h, self.state.t + h)?;
            self.reread_energy();
            return Ok(&self.state);
        }
        let t1 = self.clock.t + (self.state.step + 1 - self.clock.step) as f64 * self.h;
        self.step_by(self.h, t1)
    }

    /// The step policy in use.
    pub fn policy(&self) -> StepPolicy {
        self.policy
    }

    /// One step of size `h`, whose end node is stamped with time `t1`
    /// (`t_k + h` up to the round-off the clock avoids accumulating).
    #[inline]
    fn step_by(&mut self, h: f64, t1: f64) -> Result<&State<N>, Error<N>> {
        let State { step, t: t0, q: q0, .. } = self.state;
        let (dq, report) = self.solve_del(h)?;
        let seg = Segment { t0, h, q0, dq };
        let (q1, p1, carry) = self.advance(&seg);
        if let Some(quantity) = non_finite(t1, &q1, &p1) {
            self.stats.failed_steps += 1;
            return Err(Error::NonFinite { state: self.state, h, iterations: report.iterations, quantity });
        }
        self.carry = carry;
        if S::DISCONTINUOUS {
            self.watch_energy(&seg, t1);
        }
        self.earlier = self.previous.map(|last| (last.h, last.dq));
        self.previous = Some(seg);
        self.state = State { step: step + 1, t: t1, q: q1, p: p1 };
        self.stats.steps += 1;
        self.stats.newton_iterations += report.iterations as u64;
        self.stats.last = report;
        Ok(&self.state)
    }

    /// `(q_{k+1}, p_{k+1})` after the solved step `seg`, each the Kahan sum of
    /// the node's value and the step's increment: `q_{k+1} = q_k + Δq`,
    /// `p_{k+1} = p_k + Δp` with `Δp = ∂A/∂q_k + ∂A/∂q_{k+1} + F_k^− + F_k^+`
    /// taken at fixed increment. Summed this way the rounding of the nodes
    /// does not accumulate (it is carried into the next sum), so a moving
    /// centre of mass or large coordinates do not bias the energy or the
    /// momenta. Returns the new compensation too; changes nothing.
    #[inline]
    fn advance(&self, seg: &Segment<N>) -> ([f64; N], [f64; N], Compensation<N>) {
        let dp = forcing::momentum_change(&self.system, &self.method, seg);
        let (q1, q) = kahan(&self.state.q, &self.carry.q, &seg.dq);
        let (p1, p) = kahan(&self.state.p, &self.carry.p, &dp);
        (q1, p1, Compensation { q, p })
    }

    /// Records the relative change of the discrete energy across the node
    /// between the last step and `seg` (see [`Stats::largest_energy_jump`]).
    pub(super) fn watch_energy(&mut self, seg: &Segment<N>, t1: f64) {
        let after = -derivatives::end_time_derivative(&self.system, &self.method, seg);
        // The last step's energy was this function's `after` one step ago.
        let before = self.watched_energy.unwrap_or_else(|| self.system.energy(self.state.t, self.state.q, self.v0));
        self.watched_energy = Some(after);
        let jump = (after - before).abs() / before.abs().max(f64::MIN_POSITIVE);
        if jump.is_finite() && jump > self.stats.largest_energy_jump {
            self.stats.largest_energy_jump = jump;
            self.stats.largest_energy_jump_at = t1;
        }
    }

    /// Solves the DEL `p_k + ∂A/∂q_k = 0` for the increment `dq = q_{k+1} − q_k`
    /// of a step of size `h` (see `Segment` for why the increment).
    #[inline]
    fn solve_del(&mut self, h: f64) -> Result<([f64; N], NewtonReport), Error<N>> {
        let State { t: t0, q: q0, p: p0, .. } = self.state;
        let predictor = self.predict(h);
        let (system, method, min_rcond) = (&self.system, &self.method, self.newton.min_rcond);
        let pc = self.carry.p;
        let eval = |x: &SVector<f64, N>| {
            let seg = Segment { t0, h, q0, dq: (*x).into() };
            // Lagrange–d'Alembert: F_k^− joins ∂A/∂q_k, ∂F_k^−/∂q_{k+1} the Jacobian.
            let d = forcing::with_forces(system, method, &seg, derivatives::step_derivatives(system, method, &seg));
            // The momentum carries its compensation: p_k is p0 + pc.
            let r = SVector::from_fn(|i, _| (p0[i] + d.d_q0[i]) + pc[i]);
            let scale = max_abs(&p0).max(max_abs(&d.d_q0));
            Ok(newton::square_correction(r, d.d2_q0_q1, min_rcond)?.cancelling(scale))
        };
        match newton::solve(SVector::from(predictor), &self.newton, eval) {
            Ok((dq, report)) => {
                let dq: [f64; N] = dq.into();
                if let Some(last) = &self.previous
                    && implausible_growth(&dq, &predictor, &last.dq.map(|x| x * (h / last.h)), &q0)
                {
                    let reason = IMPLAUSIBLE_GROWTH;
                    return Err(self.fail(h, NewtonFailure::Rejected { iterations: report.iterations, reason }));
                }
                Ok((dq, report))
            }
            Err(failure) => Err(self.fail(h, failure)),
        }
    }

    /// The increment predicted by quadratic extrapolation of the positions:
    /// the secant velocities `dq/h` of the last two steps, placed at their
    /// midpoints, extrapolated linearly to the midpoint of the new step. Its
    /// error is `O(h³)`, so Newton usually converges in two iterations.
    #[inline]
    fn predict(&self, h: f64) -> [f64; N] {
        match (&self.previous, &self.earlier) {
            (Some(last), Some((h_earlier, dq_earlier))) => {
                let s = (last.h + h) / (last.h + h_earlier);
                core::array::from_fn(|i| {
                    let v = last.dq[i] / last.h;
                    let v_earlier = dq_earlier[i] / h_earlier;
                    h * (v + (v - v_earlier) * s)
                })
            }
            (Some(last), None) => last.dq.map(|x| x * (h / last.h)),
            _ => self.v0.map(|v| v * h),
        }
    }

    fn fail(&mut self, h: f64, failure: NewtonFailure) -> Error<N> {
        self.stats.failed_steps += 1;
        Error::from_newton(failure, self.state, h)
    }

    /// Takes `n` steps, calling `observe` after each with the integrator.
    ///
    /// Stops at the first failure, with the integrator at the last good state.
    pub fn run(&mut self, n: usize, mut observe: impl FnMut(&Self)) -> Result<(), Error<N>> {
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
    /// is not imposed on it) and may be shorter than `h_min`.
    pub fn run_until(&mut self, t_end: f64, mut observe: impl FnMut(&Self)) -> Result<(), Error<N>> {
        if !t_end.is_finite() || t_end < self.state.t {
            return Err(Error::InvalidTarget { target: t_end, state: self.state });
        }
        loop {
            let remaining = t_end - self.state.t;
            if remaining <= 0.0 {
                return Ok(());
            }
            let last = match self.policy {
                StepPolicy::Fixed => {
                    let next = self.clock.t + (self.state.step + 1 - self.clock.step) as f64 * self.h;
                    next >= t_end - 1e-9 * self.h
                }
                StepPolicy::EnergyPreserving(b) => {
                    let h_prev = self.previous.map_or(self.h, |last| last.h);
                    let reach = if self.previous.is_some() { b.bracket(h_prev).1 } else { self.h };
                    remaining <= reach
                }
            };
            if last {
                self.final_step(t_end)?;
                observe(self);
                return Ok(());
            }
            self.step()?;
            observe(self);
        }
    }

    /// Sets `E_k = −∂A/∂t_k` from the last step (after a step of given size).
    fn reread_energy(&mut self) {
        self.energy_carry = 0.0;
        if let Some(last) = &self.previous {
            self.energy = -derivatives::end_time_derivative(&self.system, &self.method, last);
        }
    }

    /// A step of the size that lands on `t_end`; for energy-preserving steps
    /// it is a fixed step (the energy equation is not imposed on it) after
    /// which the discrete energy is re-read, so `E_k` stays consistent.
    fn final_step(&mut self, t_end: f64) -> Result<(), Error<N>> {
        let h = self.h;
        self.step_by(t_end - self.state.t, t_end)?;
        match self.policy {
            StepPolicy::Fixed => self.clock = Clock { t: self.state.t, step: self.state.step },
            StepPolicy::EnergyPreserving(_) => {
                self.reread_energy();
                self.time_error = 0.0;
                // Keep the solved step as the next guess, not the shortened one.
                self.h = h;
            }
        }
        Ok(())
    }

    /// The discrete energy `E_k = −∂A(x_{k−1}, x_k)/∂t_k` (docs/theory.md §3); at
    /// `k = 0`, the continuous energy of the initial data.
    ///
    /// Under energy-preserving steps it is read off the last step like for
    /// fixed steps, so it shows what the steps achieve, not the target they
    /// were solved for.
    pub fn discrete_energy(&self) -> f64 {
        match &self.previous {
            Some(seg) => -derivatives::end_time_derivative(&self.system, &self.method, seg),
            None => self.system.energy(self.state.t, self.state.q, self.v0),
        }
    }

    /// The velocity `v_k` whose momentum `∂L/∂v(t_k, q_k, v_k)` is `p_k`.
    pub fn velocity(&self) -> Result<[f64; N], Error<N>> {
        let State { t, q, p, .. } = self.state;
        let guess = match &self.previous {
            Some(last) => last.dq.map(|x| x / last.h),
            None => self.v0,
        };
        self.system.velocity(t, q, p, guess).map_err(|f| Error::InverseLegendre {
            state: self.state,
            iterations: f.iterations,
            residual_norm: f.residual_norm,
        })
    }

    /// The continuous energy `E_L(t_k, q_k, v_k)` at the velocity of the current momentum.
    pub fn energy(&self) -> Result<f64, Error<N>> {
        let v = self.velocity()?;
        Ok(self.system.energy(self.state.t, self.state.q, v))
    }

    /// The tangent map `∂(q_k, p_k)/∂(q_{k−1}, p_{k−1})` of the last step
    /// (docs/theory.md §8), or `None` before the first step or where `∂²A/∂q_k∂q_{k+1}`
    /// is singular.
    ///
    /// Also `None` for a system with forces: its step map is not symplectic,
    /// and the tangent map would need the derivatives of the discrete forces.
    pub fn last_tangent_map(&self) -> Option<TangentMap<N>> {
        if forcing::is_forced::<S, N>() {
            return None;
        }
        symplectic::tangent_map(&self.system, &self.method, self.previous.as_ref()?)
    }

    /// The last step as a segment `(t_k, h, q_k, dq)`: its increment `dq` is
    /// the one Newton solved for, free of the rounding of `q_{k+1} = q_k + dq`
    /// (which, when every step rounds the same way, adds up over long runs).
    /// `None` before the first step.
    pub fn last_step(&self) -> Option<&Segment<N>> {
        self.previous.as_ref()
    }

    /// The discrete forces `(F_k^−, F_k^+)` of the last step (docs/theory.md §6), or
    /// `None` before the first step; zero for a system without forces.
    pub fn last_forces(&self) -> Option<DiscreteForces<N>> {
        Some(forcing::discrete_forces(&self.system, &self.method, self.previous.as_ref()?))
    }

    /// The energy balance `E_{k+1} − E_k − W_k` across node `k`, the node
    /// between the last two steps (see [`forcing`](crate::forcing) for `W_k`
    /// and when the balance is exact), or `None` before the second step.
    ///
    /// The step before the last is rebuilt from the last one and its stored
    /// increment, so its start point carries the round-off of one subtraction.
    pub fn energy_balance(&self) -> Option<EnergyBalance> {
        let ahead = self.previous.as_ref()?;
        let (h, dq) = self.earlier?;
        let behind = Segment { t0: ahead.t0 - h, h, q0: core::array::from_fn(|i| ahead.q0[i] - dq[i]), dq };
        Some(forcing::energy_balance(&self.system, &self.method, &behind, ahead))
    }

    /// The discrete momentum map `J_k = p_k·ξ(q_k)` of a symmetry at the current node (docs/theory.md §7).
    pub fn momentum_map(&self, symmetry: &(impl crate::noether::Generator<N> + ?Sized)) -> f64 {
        crate::noether::momentum_map(symmetry, &self.state.q, &self.state.p)
    }

    /// The forcing impulse `F_k^−·ξ(q_k) + F_k^+·ξ(q_{k+1})` of the last step,
    /// which `J_{k+1} − J_k` equals for a symmetry of the action (see
    /// [`noether`](crate::noether)); `None` before the first step.
    pub fn forcing_impulse(&self, symmetry: &(impl crate::noether::Generator<N> + ?Sized)) -> Option<f64> {
        Some(crate::noether::forcing_impulse(&self.system, &self.method, self.previous.as_ref()?, symmetry))
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
