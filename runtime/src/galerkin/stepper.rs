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

use crate::dense::{GalerkinPolynomial, Node};
use crate::error::Error;
use crate::integrator::{
    F64Readouts, IMPLAUSIBLE_GROWTH, Integrator, IntegratorBuilder, Method, StepBounds, StepPolicy, add_increment,
    implausible_growth, non_finite,
};
use crate::newton::{self, Breakdown, Linearization, NewtonFailure, NewtonOptions, NewtonReport, Unknown};
use crate::real::{Real, all_finite, max_abs};
use crate::state::State;
use crate::symplectic::TangentMap;
use crate::system::{Lagrangian, generalized_force};
use nalgebra::SMatrix;

use super::collocation;
use super::forces::NoJacobian;
use super::linalg::{BlockMatrix, BlockVector, Lu, LuFailure};
use super::method::{
    Galerkin, PointDerivatives, StageIteration, gradient_at, point_gradient, value_gradient_at, velocity_derivatives,
};

/// The builder of a Galerkin integrator: [`IntegratorBuilder`] with a
/// [`Galerkin`] rule.
pub type GalerkinBuilder<Sys, const S: usize, const R: usize, T = f64> = IntegratorBuilder<Sys, Galerkin<S, R, T>, T>;

/// The last step taken: where it started and its node increments.
#[doc(hidden)]
#[derive(Debug, PartialEq)]
pub struct LastStep<const N: usize, const S: usize, T> {
    pub(crate) t0: T,
    pub(crate) h: T,
    pub(crate) q0: [T; N],
    pub(crate) carry: [T; N],
    pub(crate) d: [[T; N]; S],
    /// The step size `block` was assembled for, when it holds the factored
    /// Newton block a simplified Newton iteration of this step converged
    /// with: the next step of the same size starts from it instead of
    /// assembling and factoring its own (see `step_nodes`). `None`: `block`
    /// holds nothing to keep.
    pub(crate) jacobian: Option<T>,
    /// The kept block (see `jacobian`); its matrix is on the heap.
    pub(crate) block: Lu<N, S, T>,
    /// Storage for the next step's own block (and for the inverse of the
    /// kept one): allocated at the first step and passed between `block` and
    /// the steps, so that later steps do not allocate.
    pub(crate) spare: Lu<N, S, T>,
    /// When to offer the kept block again after it contracted too slowly.
    pub(crate) kept_policy: KeptPolicy,
    /// The derivative evaluations of `L` over the successful fixed steps so far.
    pub(crate) evaluations: PointEvaluations,
    /// When to try the fixed-point iteration again after it failed to
    /// converge fast enough (`collocation.rs`): the same back-off as the kept block's.
    pub(crate) fixed_point: KeptPolicy,
    /// When to start the fixed-point iteration with the block-diagonal
    /// `∂²L/∂v²` again after a step had to switch to the coupled matrix
    /// (`collocation::solve`): the same back-off, so that a stretch of steps
    /// where the coupling is strong starts coupled.
    pub(crate) coupling: KeptPolicy,
    /// The rows of `M⁻¹` of a system whose mass matrix is proven constant,
    /// for the fixed-point iteration (`collocation::constant_mass_inverse`);
    /// empty until a step computes it.
    pub(crate) mass_inverse: Box<[[T; N]]>,
}

impl<const N: usize, const S: usize, T: Copy> Clone for LastStep<N, S, T> {
    fn clone(&self) -> Self {
        let Self {
            t0,
            h,
            q0,
            carry,
            d,
            jacobian,
            block,
            spare,
            kept_policy,
            evaluations,
            fixed_point,
            coupling,
            mass_inverse,
        } = self;
        Self {
            t0: *t0,
            h: *h,
            q0: *q0,
            carry: *carry,
            d: *d,
            jacobian: *jacobian,
            block: block.clone(),
            spare: spare.clone(),
            kept_policy: *kept_policy,
            evaluations: *evaluations,
            fixed_point: *fixed_point,
            coupling: *coupling,
            mass_inverse: mass_inverse.clone(),
        }
    }

    /// The blocks into the storage they have: a copy of an integrator made
    /// before each step of a `solve` does not allocate.
    fn clone_from(&mut self, source: &Self) {
        let Self {
            t0,
            h,
            q0,
            carry,
            d,
            jacobian,
            block,
            spare,
            kept_policy,
            evaluations,
            fixed_point,
            coupling,
            mass_inverse,
        } = self;
        block.clone_from(&source.block);
        spare.clone_from(&source.spare);
        if mass_inverse.len() == source.mass_inverse.len() {
            mass_inverse.copy_from_slice(&source.mass_inverse);
        } else {
            *mass_inverse = source.mass_inverse.clone();
        }
        (*t0, *h, *q0, *carry, *d, *jacobian) =
            (source.t0, source.h, source.q0, source.carry, source.d, source.jacobian);
        (*kept_policy, *evaluations, *fixed_point, *coupling) =
            (source.kept_policy, source.evaluations, source.fixed_point, source.coupling);
    }
}

/// Evaluations of the derivatives of `L` at quadrature points, summed over
/// the successful fixed steps of a Galerkin integrator
/// ([`Integrator::point_evaluations`]): the work measure of an implicit step
/// that iteration counts alone hide (a simplified iteration costs gradients
/// only, one with a new Jacobian a Hessian at every point).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PointEvaluations {
    /// Gradients `(∂L/∂q, ∂L/∂v)` at one point: `R` per iteration that
    /// reuses a Jacobian, and `R` per step for the momentum update (for a
    /// fixed-point step, at the stage values of the velocities it returns).
    pub gradients: u64,
    /// Gradients with the Hessian of `L` at one point: `R` per iteration
    /// that assembles a new Jacobian.
    pub hessians: u64,
    /// Hessians `∂²L/∂v²` in the velocities only at one point: `R` per step
    /// solved by the fixed-point iteration of a Gauss rule (whose
    /// iterations count `R` gradients each), and per step that Newton
    /// solved and the automatic iteration finishes with the fixed point.
    pub velocity_hessians: u64,
}

/// Back-off for the kept Newton block: where a block one step old contracts
/// too slowly to be kept through a step (large steps, fast dynamics), trying
/// it first wastes iterations before the refresh, step after step. After a
/// refresh the next `skip` steps assemble their own block from the start;
/// each further refresh doubles the pause (1, 3, 7, 15 steps), and a step
/// that keeps the block throughout resets it.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct KeptPolicy {
    /// Steps still to take without offering the kept block.
    skip: u8,
    /// The pause after the next refresh.
    backoff: u8,
}

impl KeptPolicy {
    /// Whether this step may start from the kept block.
    fn offers(self) -> bool {
        self.skip == 0
    }

    /// The policy after a step: `offered` whether the kept block was offered,
    /// `kept` whether it served the whole step.
    fn after(self, offered: bool, skipped: bool, kept: bool) -> Self {
        match (offered, skipped) {
            (true, _) if kept => Self::default(),
            (true, _) => {
                let backoff = (2 * self.backoff + 1).min(15);
                Self { skip: backoff, backoff }
            }
            (false, true) => Self { skip: self.skip - 1, ..self },
            (false, false) => self,
        }
    }
}

/// What a Galerkin rule keeps between steps: the last step, `None` before the first.
pub(crate) type GalerkinMemory<const N: usize, const S: usize, T> = Option<LastStep<N, S, T>>;

/// The [`Integrator`] with a Galerkin rule [`Galerkin<S, R, T>`](Galerkin), for
/// a system with `N` degrees of freedom (a name, not another type).
///
/// ```
/// use lagrangian_runtime::galerkin::Galerkin;
/// use lagrangian_runtime::{Integrator, Lagrangian, Scalar};
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
/// let mut sim = Integrator::new(Oscillator, Galerkin::<4, 4>::gauss(), 0.2 * std::f64::consts::PI)
///     .start(0.0, [1.0], [0.0])?;
/// sim.run(10, |_| {})?;
/// assert!((sim.state().q[0] - 1.0).abs() < 1e-8);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
///
/// # Extended precision
///
/// The rule's real type is the type of the whole run: the quadrature, the
/// basis, the Newton block and the state are computed in it. With
/// [`DoubleDouble`](crate::DoubleDouble) (about 32 digits), order 16 shows
/// errors `f64` cannot hold; tighten Newton's `rtol` to the type's precision.
///
/// ```
/// # use lagrangian_runtime::galerkin::Galerkin;
/// # use lagrangian_runtime::{Integrator, Lagrangian, Scalar};
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
/// let mut sim = Integrator::new(Oscillator, Galerkin::<8, 8, DoubleDouble>::gauss(), h)
///     .newton(NewtonOptions { rtol: 1e-30, ..NewtonOptions::default() })
///     .start(zero, [one], [zero])?;
/// sim.run(40, |_| {})?;
/// assert!((sim.state().q[0] - one).abs() < DoubleDouble::from(1e-28));
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub type GalerkinIntegrator<Sys, const N: usize, const S: usize, const R: usize, T = f64> =
    Integrator<Sys, Galerkin<S, R, T>, N, T>;

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

impl<Sys, const N: usize, const S: usize, const R: usize, T> Integrator<Sys, Galerkin<S, R, T>, N, T>
where
    Sys: Lagrangian<N>,
    T: Real,
{
    /// The node values `Q_1 … Q_s` of the last step's polynomial (`Q_s = q_k`),
    /// or `None` before the first step.
    pub fn last_nodes(&self) -> Option<[[T; N]; S]> {
        let last = self.memory.as_ref()?;
        Some(last.d.map(|d| core::array::from_fn(|i| last.q0[i] + (last.carry[i] + d[i]))))
    }

    /// The derivative evaluations of `L` at quadrature points over the
    /// successful fixed steps so far (zero before the first step, and for
    /// energy-preserving steps, which are not counted).
    pub fn point_evaluations(&self) -> PointEvaluations {
        self.memory.as_ref().map_or_else(PointEvaluations::default, |last| last.evaluations)
    }

    /// Whether a step starts from the last step's Jacobian (see
    /// `step_nodes`): from a block of 4 unknowns. Below, assembling and
    /// factoring the block costs less than the extra iterations a kept one
    /// needs. Measured with the kept block inverted once and borrowed in
    /// place (`--bench galerkin`, h = 0.1, fresh against kept, two runs
    /// each): pendulum s = 4 0.71/0.64 against 0.49/0.55 µs per step (2.0
    /// against 4.4 iterations), s = 5 0.85/0.86 against 0.58/0.57, s = 6
    /// 10 443 against 8 217 instructions; Kepler e = 0.5 s = 2 0.51/0.49
    /// against 0.43/0.45 µs (2.3 against 6.1 iterations). Earlier, with the
    /// block copied through the memory, even `sN = 6` lost (11 541 against
    /// 12 145 instructions).
    const KEEPS_JACOBIAN: bool = S >= 2 && S * N >= 4;

    /// The first guess for the increments of a step of size `h`.
    #[inline]
    pub(super) fn predict_nodes(&self, h: T) -> BlockVector<N, S, T> {
        let g = &self.method;
        match &self.memory {
            Some(last) if last.h == h => {
                let mut out = [[T::zero(); N]; S];
                for (row, weights) in out.iter_mut().zip(&g.extrapolate) {
                    for (&w, dn) in weights.iter().zip(&last.d) {
                        for (x, &y) in row.iter_mut().zip(dn) {
                            *x += w * y;
                        }
                    }
                }
                out
            }
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
    pub(crate) fn step_nodes(&mut self, h: T, t1: T) -> Result<(), Error<T>> {
        let State { t: t0, q: q0, p: p0, .. } = self.state;
        let e = self.carry;
        let predicted = self.predict_nodes(h);
        // Gauss rules try the fixed-point iteration on the stage velocities
        // first (`collocation.rs`: gradients of L only, no Jacobian); a step
        // where it contracts slowly or diverges goes on to Newton below,
        // and the next steps skip it for a while (the kept block's back-off).
        let fixed_policy = self.memory.as_ref().map_or_else(KeptPolicy::default, |last| last.fixed_point);
        let forced = Sys::HAS_FORCE || Sys::HAS_DISSIPATION;
        let coupling = self.memory.as_ref().map_or_else(KeptPolicy::default, |last| last.coupling);
        // The coupling policy after this step, if it goes on.
        let mut coupling_after = coupling;
        let iteration = self.method.iteration();
        let fixed_offered = self.method.is_collocation()
            && match iteration {
                StageIteration::Newton => false,
                StageIteration::FixedPoint => true,
                StageIteration::Automatic => fixed_policy.offers(),
            };
        let mut fixed_spent = 0;
        let mut velocity_hessians = 0;
        // The block storage of the step (none before the first step:
        // allocated when first written): the fixed point's coupled matrix,
        // then Newton's own block.
        let mut storage =
            self.memory.as_mut().map_or_else(Lu::empty, |last| core::mem::replace(&mut last.spare, Lu::empty()));
        if fixed_offered {
            let p = (&p0, &self.p_carry);
            // Alone, the fixed point is only stopped by divergence.
            let slowest = match iteration {
                StageIteration::FixedPoint => 1.0,
                _ => collocation::SLOWEST_CONTRACTION,
            };
            // A constant mass matrix is inverted once per run (kept in the
            // memory from the first step on).
            let mut computed = None;
            if Sys::SEPARABILITY.has_constant_mass()
                && self.memory.as_ref().is_none_or(|last| last.mass_inverse.is_empty())
            {
                computed = collocation::constant_mass_inverse(&self.system, t0, q0, self.v0);
            }
            let mass_inverse = match (&computed, &self.memory) {
                (Some(m), _) => Some(&**m),
                (None, Some(last)) if !last.mass_inverse.is_empty() => Some(&*last.mass_inverse),
                _ => None,
            };
            // Forced and damped systems start with the coupled matrix (the
            // damping stops the block-diagonal iteration); the others start
            // block-diagonal and switch where a round contracts slowly.
            let start_coupled = forced || !coupling.offers();
            let coupled = Some(storage.matrix_mut());
            let solved = collocation::solve(
                &self.system,
                &self.method,
                t0,
                h,
                (&q0, &e),
                p,
                &predicted,
                slowest,
                mass_inverse,
                coupled,
                start_coupled,
            );
            // Hessians in `v` the first iteration evaluated: one for a
            // constant mass matrix inverted at this step, none for one kept.
            velocity_hessians = match (&computed, mass_inverse) {
                (Some(_), _) => 1,
                (None, Some(_)) => 0,
                (None, None) => R,
            };
            if self.memory.is_some()
                && let Some(m) = computed.take()
            {
                self.keep_mass_inverse(m);
            }
            let ended_coupled = match &solved {
                Ok(c) => c.coupled,
                Err(failure) => failure.coupled,
            };
            if !forced {
                // Offered: started block-diagonal; kept: stayed so.
                coupling_after = coupling.after(!start_coupled, start_coupled, !ended_coupled);
            }
            match solved {
                Ok(c) => {
                    self.commit_fixed_point(h, t1, c, &predicted, velocity_hessians, coupling_after, storage)?;
                    // The first step's memory exists only now.
                    if let Some(m) = computed {
                        self.keep_mass_inverse(m);
                    }
                    return Ok(());
                }
                Err(failure) if iteration == StageIteration::FixedPoint => {
                    let failure = NewtonFailure::Rejected { iterations: failure.iterations, reason: failure.reason };
                    self.keep_storage(KeptBlock::Drop, storage);
                    return Err(self.fail(h, failure));
                }
                Err(failure) => fixed_spent = failure.iterations,
            }
        }
        // The condition estimate (Hager's, a few triangular solves whose
        // latency measured a fifth of a double-pendulum step at s = 4) is made
        // only for a step that fails (`ill_conditioned`, below), so the
        // iterations run without it (`min_rcond` 0); a converged iteration
        // has found a root of the block system whatever the conditioning of
        // its Jacobian.
        let (system, g, min_rcond) = (&self.system, &self.method, 0.0);
        let pc = self.p_carry;
        // Simplified Newton first: the Jacobian is assembled and factored at
        // the first guess only, and later iterations cost the gradient of L at
        // the quadrature points and one triangular solve (N instead of
        // N(2N + 1) hyper-dual evaluations per point, no assembly, no LU). With
        // the extrapolated guess it converges in about as many iterations as
        // full Newton. If it fails: full Newton from the same guess, then from
        // the straight line at the last secant velocity (v0 at the first step).
        //
        // The Jacobian changes by O(h) from one step to the next, so a step
        // of the same size as the last one starts its simplified iteration
        // from the last step's factored block (kept in the memory), and only
        // assembles and factors its own where that one contracts slowly: most
        // steps then cost no Hessian, no assembly and no LU at all.
        let policy = self.memory.as_ref().map_or_else(KeptPolicy::default, |last| last.kept_policy);
        let has_kept =
            Self::KEEPS_JACOBIAN && matches!(&self.memory, Some(LastStep { jacobian: Some(h_lu), .. }) if *h_lu == h);
        let offered = has_kept && policy.offers();
        // The step's own block goes into the memory's spare storage (taken
        // above).
        if offered && let Some(LastStep { jacobian: Some(_), block, .. }) = &mut self.memory {
            // Kept for a second step: from here on it serves several solves
            // per step, each cheaper as a product with the inverse. (Inverting
            // changes no result a failed step could leave behind: a run
            // without that step inverts the same factors at the same point.)
            block.invert_in_place(&mut storage);
        }
        let cached = match &self.memory {
            Some(LastStep { jacobian: Some(_), block, .. }) if offered => Some(block),
            _ => None,
        };
        let cached_lu = cached.is_some();
        // One factorisation in place for all attempts of the step, the kept
        // one borrowed: the block (1.2 kB at sN = 12) is never copied.
        let mut work = Work::new(cached, storage);
        let linearize = |x: &Nodes<N, S, T>, work: &mut Work<'_, N, S, T>| {
            // Whether this iteration assembles a new Jacobian.
            let fresh = !(work.simplified && work.valid);
            let lin = linearize(system, g, t0, h, (&q0, &e), (&p0, &pc), &x.0, min_rcond, work)?;
            if work.simplified {
                // A frozen Jacobian that contracts slowly (a large step, a poor
                // guess) is refreshed at the next iterate. A fresh one's first
                // correction is not judged against the stale one's before it.
                let size = max_abs(lin.correction.0.as_flattened());
                if work.last_correction.replace(size).is_some_and(|last| !fresh && size > 0.05 * last) {
                    work.valid = false;
                }
            }
            Ok(lin)
        };
        // An iteration with a kept Jacobian contracts linearly (by up to 0.05
        // per iteration) where one with the step's own converges at once, and
        // would stop within `rtol` of the root on the same side step after
        // step: measured as a drift of 5e-10 in q over 20 000 pendulum steps.
        // It is held to a tolerance 100 times tighter, which costs about one
        // more gradient iteration and leaves the error at round-off.
        let kept_options = NewtonOptions { rtol: self.newton.rtol * 1e-2, ..self.newton };
        let attempt = |guess: BlockVector<N, S, T>, simplify: bool, kept: bool, work: &mut Work<'_, N, S, T>| {
            let options = if kept { &kept_options } else { &self.newton };
            work.start(simplify, kept);
            newton::solve(Nodes(guess), options, |x: &Nodes<N, S, T>, _| linearize(x, work))
        };
        let mut spent = fixed_spent;
        // (Degree 1 has a single block: full Newton is cheaper there, measured
        // 148 against 222 ns per pendulum step.)
        let mut solved = attempt(predicted, S >= 2, cached_lu, &mut work);
        // A kept Jacobian that did not converge: the usual ladder, from a
        // simplified iteration with this step's own Jacobian.
        if cached_lu && solved.is_err() {
            if let Err(failure) = &solved {
                spent += failure.iterations();
            }
            solved = attempt(predicted, true, false, &mut work);
        }
        for (guess, simplify) in [(None, false), (Some(()), false)] {
            let Err(failure) = &solved else { break };
            spent += failure.iterations();
            let guess = match guess {
                None => predicted,
                Some(()) => {
                    let v = match &self.memory {
                        Some(last) => last.d[S - 1].map(|x| x / last.h),
                        None => self.v0,
                    };
                    g.control.map(|tau| v.map(|v| v * tau * h))
                }
            };
            solved = attempt(guess, simplify, false, &mut work);
        }
        // Every attempt counts in the iterations reported. A failure with a
        // factored block too ill-conditioned for `min_rcond` is reported as
        // the singular Jacobian it is.
        let solved = match solved {
            Ok((x, mut report)) => {
                report.iterations += spent;
                Ok((x, report))
            }
            Err(failure) => Err(with_iterations(ill_conditioned(failure, &work, self.newton.min_rcond), spent)),
        };
        // Linearisations with a kept and with a new Jacobian, for the counts.
        let (kept_linearisations, new_linearisations) = (work.gradients, work.hessians);
        // The block the converged simplified iteration used, for the next
        // step, and the storage that goes back to the memory.
        let (jacobian, storage) = match (Self::KEEPS_JACOBIAN && work.simplified && work.valid, work.uses_kept) {
            (true, true) => (KeptBlock::Same, work.lu),
            (true, false) => (KeptBlock::New(h, work.lu), Lu::empty()),
            (false, _) => (KeptBlock::Drop, work.lu),
        };
        let (d, report) = match solved {
            Ok((x, report)) => (x.0, report),
            Err(failure) => {
                self.keep_storage(jacobian, storage);
                return Err(self.fail(h, failure));
            }
        };
        if let Some(last) = &self.memory {
            let f = |x: &[T; N]| x.map(|v| v.to_f64());
            let rho = (h / last.h).to_f64();
            let reached = f(&last.d[S - 1]).map(|x| x * rho);
            if implausible_growth(&f(&d[S - 1]), &f(&predicted[S - 1]), &reached, &f(&q0)) {
                let reason = IMPLAUSIBLE_GROWTH;
                self.keep_storage(jacobian, storage);
                return Err(self.fail(h, NewtonFailure::Rejected { iterations: report.iterations, reason }));
            }
        }
        let kept = matches!(jacobian, KeptBlock::Same);
        let collocation = self.method.is_collocation() && iteration == StageIteration::Automatic;
        // Where the fixed point is the method's iteration, it also finishes
        // the steps Newton solved: from Newton's root it reaches round-off in
        // a few rounds, and the step then takes the update of the fixed
        // point's coefficients, with the gradients at its stage values.
        // Newton's root is held to its tolerance only, an error of the same
        // sign step after step: on Kepler in polar coordinates (s = 6, 1000
        // orbits, 57 082 steps) the few steps Newton took left a phase error
        // of 2.9e-8 against 2.5e-10 finished (and 3.0e-8 with the fixed
        // point's update taken at Newton's velocities without a round).
        let mut report = report;
        let polished = if collocation {
            let mass_inverse = self.memory.as_ref().map(|last| &*last.mass_inverse).filter(|m| !m.is_empty());
            let polished = collocation::solve(
                &self.system,
                &self.method,
                t0,
                h,
                (&q0, &e),
                (&p0, &pc),
                &d,
                1.0,
                mass_inverse,
                None,
                false,
            );
            let iterations = match &polished {
                Ok(c) => c.iterations,
                Err(failure) => failure.iterations,
            };
            report.iterations += iterations;
            Some((polished.ok(), iterations, mass_inverse.is_some()))
        } else {
            None
        };
        match &polished {
            Some((Some(c), _, _)) => {
                self.commit(h, t1, c.d, report, Some((&c.point_forces, c.lagrangian_finite)), jacobian, storage)?
            }
            _ => self.commit(h, t1, d, report, None, jacobian, storage)?,
        }
        if let Some(last) = &mut self.memory {
            last.kept_policy = policy.after(offered, has_kept && !offered, kept);
            last.fixed_point = fixed_policy.after(fixed_offered, collocation && !fixed_offered, false);
            last.coupling = coupling_after;
            // Every linearisation of every attempt, the fixed-point
            // iterations before them, and the momentum update.
            let fixed_gradients = fixed_spent.saturating_sub(1);
            last.evaluations.gradients += (R * (kept_linearisations + fixed_gradients + 1)) as u64;
            last.evaluations.hessians += (R * new_linearisations) as u64;
            last.evaluations.velocity_hessians += velocity_hessians as u64;
            // The finishing rounds: Hessians in `v` at the first (none with
            // a kept `M⁻¹`), gradients at the others and, where they
            // converged, for the update, which then replaces Newton's.
            if let Some((converged, iterations, kept_inverse)) = &polished {
                let update = usize::from(converged.is_some());
                last.evaluations.gradients += (R * (iterations - 1 + update)) as u64;
                last.evaluations.velocity_hessians += if *kept_inverse { 0 } else { R as u64 };
            }
        }
        Ok(())
    }

    /// Keeps `M⁻¹` of a constant mass matrix for the later steps.
    fn keep_mass_inverse(&mut self, m: Box<[[T; N]]>) {
        if let Some(last) = &mut self.memory
            && last.mass_inverse.is_empty()
        {
            last.mass_inverse = m;
        }
    }

    /// Applies a step the fixed-point iteration solved (`converged`, from
    /// the guess `predicted`), with the checks of a Newton step; the kept
    /// Newton block stays in the memory for the steps that need it, and
    /// `coupling` becomes the memory's coupling policy.
    #[allow(clippy::too_many_arguments)]
    fn commit_fixed_point(
        &mut self,
        h: T,
        t1: T,
        converged: collocation::Converged<N, S, R, T>,
        predicted: &BlockVector<N, S, T>,
        velocity_hessians: usize,
        coupling: KeptPolicy,
        storage: Lu<N, S, T>,
    ) -> Result<(), Error<T>> {
        let collocation::Converged {
            d,
            point_forces,
            lagrangian_finite,
            iterations,
            residual_norm,
            correction_norm,
            ..
        } = converged;
        let report = NewtonReport { iterations, residual_norm, correction_norm };
        if let Some(last) = &self.memory {
            let f = |x: &[T; N]| x.map(|v| v.to_f64());
            let rho = (h / last.h).to_f64();
            let reached = f(&last.d[S - 1]).map(|x| x * rho);
            if implausible_growth(&f(&d[S - 1]), &f(&predicted[S - 1]), &reached, &f(&self.state.q)) {
                self.keep_storage(KeptBlock::Drop, storage);
                return Err(self.fail(h, NewtonFailure::Rejected { iterations, reason: IMPLAUSIBLE_GROWTH }));
            }
        }
        self.commit(h, t1, d, report, Some((&point_forces, lagrangian_finite)), KeptBlock::Same, storage)?;
        if let Some(last) = &mut self.memory {
            last.fixed_point = KeptPolicy::default();
            last.coupling = coupling;
            // The first iteration's gradients come with the Hessians in v;
            // the momentum update's at the returned stage values are one
            // sweep more.
            last.evaluations.gradients += (R * iterations) as u64;
            last.evaluations.velocity_hessians += velocity_hessians as u64;
        }
        Ok(())
    }

    /// Applies a step of size `h` (end time `t1`) whose block system is
    /// solved by the increments `d`: the momentum update, the Kahan sums and
    /// the checks of every published value; `point_forces` the
    /// `∂L/∂q + F` at the quadrature points where the solve already has them
    /// at its solution, with whether `L` is finite there (`None`: evaluated
    /// here); `jacobian`
    /// the block to keep and `storage` the step's other block storage, both
    /// for the memory. On failure nothing changes but the storage going back
    /// to the memory.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    pub(super) fn commit(
        &mut self,
        h: T,
        t1: T,
        d: BlockVector<N, S, T>,
        report: NewtonReport,
        point_forces: Option<(&[[T; N]; R], bool)>,
        jacobian: KeptBlock<N, S, T>,
        storage: Lu<N, S, T>,
    ) -> Result<(), Error<T>> {
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
            // The derivatives can be finite where L is not (L = ln(1 − q)
            // past q = 1 has a finite derivative on the wrong branch): the
            // step is only valid where the action itself is.
            let lq = match point_forces {
                // The force is in them already, and L was evaluated with them.
                Some((forces, finite)) => {
                    lagrangian_finite &= finite;
                    forces[j]
                }
                None => {
                    let (t, q, v) = g.point(t0, h, (&q0, &e), &d, j);
                    let (l, mut lq, _) = value_gradient_at(system, t, q, v);
                    if Sys::HAS_FORCE || Sys::HAS_DISSIPATION {
                        // p_{k+1} − p_k = h Σ_j b_j (∂L/∂q + F)(c_j): the forces on
                        // all s + 1 nodes sum to h Σ_j b_j F_j (the basis sums to one).
                        let f = generalized_force(system, t, q, v);
                        for i in 0..N {
                            lq[i] += f[i];
                        }
                    }
                    lagrangian_finite &= l.is_finite();
                    lq
                }
            };
            let w = g.quadrature().weights()[j] * h;
            for i in 0..N {
                dp[i] += w * lq[i];
            }
        }
        let (p1, p_carry) = add_increment(self.summation, &p0, &self.p_carry, &dp);
        // q_{k+1} = (q_k + e_k) + D_s, Kahan-summed (`e_k` zero under plain summation).
        let (q1, carry) = add_increment(self.summation, &q0, &e, &d[S - 1]);
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
            self.keep_storage(jacobian, storage);
            return Err(Error::NonFinite {
                state: self.state.into(),
                h: h.to_f64(),
                iterations: report.iterations,
                quantity,
            });
        }
        match &mut self.memory {
            Some(last) => {
                (last.t0, last.h, last.q0, last.carry, last.d) = (t0, h, q0, e, d);
                match jacobian {
                    // The kept block stays where it is.
                    KeptBlock::Same => last.spare = storage,
                    // The old kept block's storage becomes the spare.
                    KeptBlock::New(h_lu, lu) => {
                        last.spare = core::mem::replace(&mut last.block, lu);
                        last.jacobian = Some(h_lu);
                        last.kept_policy = KeptPolicy::default();
                    }
                    KeptBlock::Drop => {
                        last.spare = storage;
                        last.jacobian = None;
                        last.kept_policy = KeptPolicy::default();
                    }
                }
            }
            memory @ None => {
                // The first step allocates both blocks the later ones reuse.
                let (jacobian, block, spare) = match jacobian {
                    KeptBlock::New(h_lu, lu) => (Some(h_lu), lu, Lu::allocated()),
                    _ => (None, Lu::allocated(), storage),
                };
                let spare = if spare.is_allocated() { spare } else { Lu::allocated() };
                *memory = Some(LastStep {
                    t0,
                    h,
                    q0,
                    carry: e,
                    d,
                    jacobian,
                    block,
                    spare,
                    kept_policy: KeptPolicy::default(),
                    evaluations: PointEvaluations::default(),
                    fixed_point: KeptPolicy::default(),
                    coupling: KeptPolicy::default(),
                    mass_inverse: Box::new([]),
                });
            }
        }
        self.carry = carry;
        self.p_carry = p_carry;
        self.state = State { step: step + 1, t: t1, q: q1, p: p1 };
        self.stats.steps += 1;
        self.stats.newton_iterations += report.iterations as u64;
        self.stats.last = report;
        Ok(())
    }

    /// `(t0, h, q0, carry, d)` of the last step.
    #[allow(clippy::type_complexity)]
    pub(super) fn last_step_parts(&self) -> Option<(T, T, [T; N], [T; N], BlockVector<N, S, T>)> {
        self.memory.as_ref().map(|l| (l.t0, l.h, l.q0, l.carry, l.d))
    }

    /// Gives the block storage of a step that failed back to the memory (as
    /// its spare: what the step factored is not kept), so that the next
    /// step does not allocate. Before the first step there is no memory to
    /// keep it.
    pub(super) fn keep_storage(&mut self, jacobian: KeptBlock<N, S, T>, storage: Lu<N, S, T>) {
        let storage = match jacobian {
            KeptBlock::New(_, lu) => lu,
            _ => storage,
        };
        if let Some(last) = &mut self.memory
            && storage.is_allocated()
        {
            last.spare = storage;
        }
    }
}

impl<const S: usize, const R: usize, T: Real> crate::integrator::Sealed for Galerkin<S, R, T> {}

impl<const S: usize, const R: usize, T: Real> Method<T> for Galerkin<S, R, T> {
    type Memory<const N: usize> = GalerkinMemory<N, S, T>;

    fn method_order(&self) -> u32 {
        self.order()
    }

    fn memory<const N: usize>(&self) -> Self::Memory<N> {
        None
    }

    fn check(&self) -> Result<(), &'static str> {
        Galerkin::check(self)
    }

    fn supports<Sys: Lagrangian<N>, const N: usize>(&self, policy: &StepPolicy) -> Result<(), Error<T>> {
        supports_policy::<Sys, N, T>(policy)
    }

    fn legendre<Sys: Lagrangian<N>, const N: usize>(
        system: &Sys,
        t0: T,
        q0: [T; N],
        v0: [T; N],
    ) -> Result<([T; N], T), Error<T>> {
        if const { beyond_forward(N) } {
            return Err(refused());
        }
        legendre(system, t0, q0, v0)
    }

    #[inline(always)]
    fn fixed_step<Sys: Lagrangian<N>, const N: usize>(
        it: &mut Integrator<Sys, Self, N, T>,
        h: T,
        t1: T,
    ) -> Result<(), Error<T>> {
        if const { beyond_forward(N) } {
            return Err(refused());
        }
        it.step_nodes(h, t1)
    }

    fn energy_step<Sys: Lagrangian<N>, const N: usize>(
        it: &mut Integrator<Sys, Self, N, T>,
        bounds: StepBounds,
    ) -> Result<(), Error<T>> {
        if const { beyond_forward(N) } {
            return Err(refused());
        }
        if const { !has_energy_steps::<Sys, N>() } {
            return Err(no_energy_steps());
        }
        it.energy_step_nodes(bounds)
    }

    fn reread_energy<Sys: Lagrangian<N>, const N: usize>(it: &mut Integrator<Sys, Self, N, T>) {
        if const { beyond_forward(N) || !has_energy_steps::<Sys, N>() } {
            return;
        }
        it.reread_node_energy();
    }

    fn last_step_size<const N: usize>(memory: &Self::Memory<N>) -> Option<T> {
        memory.as_ref().map(|last| last.h)
    }

    fn discrete_energy<Sys: Lagrangian<N>, const N: usize>(it: &Integrator<Sys, Self, N, T>) -> T {
        it.node_discrete_energy()
    }
}

/// Whether `start` refuses a Galerkin rule on `n` coordinates: above
/// [`Derivatives::FORWARD_MAX_N`](crate::Derivatives::FORWARD_MAX_N), where
/// it has no derivatives (Galerkin rules have forward mode only). Used as
/// `if const { beyond_forward(N) }` in front of every step path: a
/// function's frame is reserved on entry whatever branch runs, so code that
/// inlines a step of a size `start` refuses would still reserve its `N²`
/// derivative values on the stack of the caller that holds the refused
/// integrator.
pub(crate) const fn beyond_forward(n: usize) -> bool {
    n > crate::Derivatives::FORWARD_MAX_N
}

/// The error of a step path [`beyond_forward`] compiles out (never reached:
/// `start` refuses first).
pub(crate) fn refused<T: Real>() -> Error<T> {
    Error::Unsupported {
        what: "galerkin rules above `Derivatives::FORWARD_MAX_N` coordinates: they have forward-mode derivatives only",
    }
}

/// Whether a Galerkin rule can take energy-preserving steps of `Sys`: an
/// autonomous system without forces or dissipation that is not one of the
/// runtime's time-transformed systems ([`supports_policy`] and `start`
/// refuse the others). Used as `if const { !has_energy_steps::<Sys, N>() }`
/// in front of the energy-step paths, so that the energy-step code (a
/// quarter of a test binary's code) is not compiled for systems that can
/// never take such a step.
pub(crate) const fn has_energy_steps<Sys: Lagrangian<N> + ?Sized, const N: usize>() -> bool {
    Sys::ENERGY_STEPS && Sys::AUTONOMOUS && !Sys::HAS_FORCE && !Sys::HAS_DISSIPATION
}

/// The error of an energy-step path [`has_energy_steps`] compiles out
/// (never reached: `start` refuses the policy first).
pub(crate) fn no_energy_steps<T: Real>() -> Error<T> {
    Error::Unsupported {
        what: "energy-preserving galerkin steps for a forced, dissipative, time-dependent or time-transformed system",
    }
}

/// Why a Galerkin rule refuses an accuracy bound on its energy steps.
pub(crate) const GALERKIN_ACCURACY_BOUND: &str = "an accuracy bound (`StepBounds::with_accuracy`) on energy-preserving galerkin steps (and one-point rules in a real type other than f64, which run as galerkin rules): the capped step of least energy mismatch is written for the one-point rules in f64";

/// The policies a Galerkin rule supports for the system `Sys`.
pub(crate) fn supports_policy<Sys: Lagrangian<N>, const N: usize, T: Real>(
    policy: &StepPolicy,
) -> Result<(), Error<T>> {
    if let StepPolicy::EnergyPreserving(StepBounds { accuracy: Some(_), .. }) = policy {
        return Err(Error::Unsupported { what: GALERKIN_ACCURACY_BOUND });
    }
    if matches!(policy, StepPolicy::EnergyPreserving(_)) && (Sys::HAS_FORCE || Sys::HAS_DISSIPATION) {
        return Err(Error::Unsupported {
            what: "energy-balance steps for a system with `force` or `dissipation` with a galerkin rule (and \
                   one-point rules in a real type other than f64, which run as galerkin rules); use fixed steps, \
                   or the midpoint, trapezoid and α-β rules in f64",
        });
    }
    if matches!(policy, StepPolicy::EnergyPreserving(_)) && !Sys::AUTONOMOUS {
        return Err(Error::Unsupported {
            what: "energy-preserving galerkin steps for a time-dependent lagrangian (and one-point rules in a \
                   real type other than f64, which run as galerkin rules); use fixed steps, or the \
                   energy-preserving midpoint and trapezoid rules in f64",
        });
    }
    Ok(())
}

/// `p0 = ∂L/∂v` and `E_L` at the initial data, in the run's real type, after
/// the checks of [`IntegratorBuilder::start`].
#[allow(clippy::type_complexity)]
pub(crate) fn legendre<Sys: Lagrangian<N>, const N: usize, T: Real>(
    system: &Sys,
    t0: T,
    q0: [T; N],
    v0: [T; N],
) -> Result<([T; N], T), Error<T>> {
    // Only the derivatives in `v`: the whole Hessian in `(q, v)` would cost
    // four times as much on 16 coordinates, for blocks nobody reads here.
    let (value, p0, vv) = velocity_derivatives(system, t0, q0, v0);
    if !all_finite(&p0) || !value.is_finite() {
        return Err(Error::InvalidInitialData {
            reason: "the lagrangian or its momentum is not finite at the initial data",
        });
    }
    // Regularity is a yes-or-no question: asked of the Hessian rounded to f64.
    let hessian = SMatrix::<f64, N, N>::from_fn(|i, k| vv[i][k].to_f64());
    if !hessian.iter().all(|x| x.is_finite()) || hessian.try_inverse().is_none() {
        return Err(Error::InvalidInitialData {
            reason: "∂²L/∂v² is singular at the initial data: the legendre transform is not regular",
        });
    }
    let mut energy = -value;
    for i in 0..N {
        energy += v0[i] * p0[i];
    }
    if !energy.is_finite() {
        return Err(Error::InvalidInitialData { reason: "the energy is not finite at the initial data" });
    }
    Ok((p0, energy))
}

impl<Sys, const N: usize, const S: usize, const R: usize, T> Integrator<Sys, Galerkin<S, R, T>, N, T>
where
    Sys: Lagrangian<N>,
    T: Real,
{
    /// The discrete energy of the last step: `E = −∂A/∂t_{k+1}` at fixed
    /// nodes, `Σ_j b_j [E_L(c_j) − h c_j ∂L/∂t(c_j)]` (for an autonomous `L`
    /// the quadrature of the continuous energy along the step polynomial);
    /// at `k = 0` the energy of the initial data.
    pub(crate) fn node_discrete_energy(&self) -> T {
        let g = &self.method;
        discrete_energy_of(&self.system, g, self.memory.as_ref(), (self.state.t, &self.state.q, &self.v0))
    }
}

/// The discrete energy of the step `last` of the rule `g` (see
/// `node_discrete_energy`), or the energy at `(t, q, v0)` before the first step.
pub(crate) fn discrete_energy_of<Sys, const N: usize, const S: usize, const R: usize, T>(
    system: &Sys,
    g: &Galerkin<S, R, T>,
    last: Option<&LastStep<N, S, T>>,
    (t, q, v0): (T, &[T; N], &[T; N]),
) -> T
where
    Sys: Lagrangian<N>,
    T: Real,
{
    let Some(last) = last else {
        let (l, _, lv) = point_gradient(system, t, *q, *v0);
        let mut e = -l;
        for i in 0..N {
            e += v0[i] * lv[i];
        }
        return e;
    };
    let mut e = super::method::step_energy(system, g, last.t0, last.h, (&last.q0, &last.carry), &last.d);
    if !Sys::AUTONOMOUS {
        for j in 0..R {
            let (t, q, v) = g.point(last.t0, last.h, (&last.q0, &last.carry), &last.d, j);
            let lt = system
                .lagrangian(
                    num_dual::Dual::new(t, T::one()),
                    q.map(num_dual::Dual::from_re),
                    v.map(num_dual::Dual::from_re),
                )
                .eps;
            e -= g.quadrature().weights()[j] * last.h * g.quadrature().nodes()[j] * lt;
        }
    }
    e
}

/// Readouts that solve in `f64` (the inverse Legendre transform, the tangent map).
impl<const S: usize, const R: usize> F64Readouts for Galerkin<S, R> {
    fn velocity_guess<Sys: Lagrangian<N>, const N: usize>(it: &Integrator<Sys, Self, N>) -> [f64; N] {
        match &it.memory {
            // The velocity at the end of the last step's polynomial.
            Some(last) => core::array::from_fn(|i| {
                (0..S).map(|n| it.method.basis_derivative(n + 1, 1.0) * last.d[n][i]).sum::<f64>() / last.h
            }),
            None => it.v0,
        }
    }

    /// By the implicit function theorem on the block system, with the
    /// interior nodes as functions of `(q_k, p_k)`; the Hessian comes from
    /// [`Galerkin::node_hessian`]. Allocates.
    fn tangent_map<Sys: Lagrangian<N>, const N: usize>(it: &Integrator<Sys, Self, N>) -> Option<TangentMap<N>> {
        if const { beyond_forward(N) } {
            return None;
        }
        let last = it.memory.as_ref()?;
        let q0 = core::array::from_fn(|i| last.q0[i] + last.carry[i]);
        tangent_map(&it.system, &it.method, last.t0, last.h, q0, &last.d)
    }

    /// The forcing impulse `Σ_m F^m·ξ(Q_m)` of the last step over its nodes
    /// `Q_0 = q_{k−1}, …, Q_s = q_k`, with `F^m = h Σ_j b_j ℓ_m(c_j) F(c_j)` the
    /// discrete force on node `m`.
    ///
    /// For a symmetry of `L` (`ξ` with `∂L/∂q·ξ + ∂L/∂v·ξ'(q)v = 0` along the
    /// step) the step action is invariant, the interior equations
    /// `∂A/∂Q_m + F^m = 0` hold, and so `J_k − J_{k−1}` equals this impulse
    /// (the discrete Noether theorem with forcing, through the basis).
    fn forcing_impulse<Sys: Lagrangian<N>, const N: usize>(
        it: &Integrator<Sys, Self, N>,
        symmetry: &(impl crate::noether::Generator<N> + ?Sized),
    ) -> Option<f64> {
        if const { beyond_forward(N) } {
            return None;
        }
        let last = it.memory.as_ref()?;
        Some(it.method.forcing_impulse(&it.system, (last.t0, last.h), (&last.q0, &last.carry), &last.d, symmetry))
    }

    /// The step's polynomial through its nodes (order `s + 1`).
    type Native<const N: usize> = GalerkinPolynomial<N, S>;

    fn native<Sys: Lagrangian<N>, const N: usize>(
        it: &Integrator<Sys, Self, N>,
        start: &Node<N>,
        end: &Node<N>,
    ) -> GalerkinPolynomial<N, S> {
        let nodes = it.last_nodes().unwrap_or([end.q; S]);
        GalerkinPolynomial::new(start.t, end.t - start.t, *it.method.control_nodes(), start.q, nodes)
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
    work: &mut Work<'_, N, S, T>,
) -> Result<Linearization<Nodes<N, S, T>>, Breakdown>
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
    // The Jacobian only where the iteration needs a new one; assembled in
    // place into the factorisation's storage.
    let frozen = work.simplified && work.valid;
    let check = core::mem::replace(&mut work.check, false) && !frozen;
    if !frozen {
        // A new block, in the step's own storage (a kept one stays as it is).
        work.uses_kept = false;
    }
    if frozen {
        work.gradients += 1;
    } else {
        work.hessians += 1;
    }
    let jac: &mut BlockMatrix<N, S, T> = work.lu.matrix_mut();
    if !frozen {
        jac.fill_zero();
    }
    let mut direct = [zero; N];
    let mut grad: BlockVector<N, S, T> = [[zero; N]; S];
    // Discrete forces on the nodes Q_0 … Q_{s−1} (the last node's, F^s, only
    // enters p_{k+1}).
    let mut fnode: BlockVector<N, S, T> = [[zero; N]; S];
    let forced = Sys::HAS_FORCE || Sys::HAS_DISSIPATION;
    // `w_j ∂L/∂q` and `w_j ∂L/∂v / h` at each point, and their largest sizes.
    let mut wq: [[T; N]; R] = [[zero; N]; R];
    let mut wv: [[T; N]; R] = [[zero; N]; R];
    let mut term_max = [(0.0f64, 0.0f64); R];
    for j in 0..R {
        let (t, q, v) = g.point(t0, h, base, d, j);
        // The Hessian only when the Jacobian is to be assembled.
        let (lq, lv, pd) = match frozen {
            true => {
                let (lq, lv) = gradient_at(system, t, q, v);
                (lq, lv, None)
            }
            false => {
                let pd = PointDerivatives::at(system, t, q, v);
                (pd.q, pd.v, Some(pd))
            }
        };
        let b = g.quadrature().weights()[j];
        let (row, row_d, col, col_d) = (&g.row[j], &g.row_d[j], &g.col[j], &g.col_d[j]);
        // Lagrange–d'Alembert: the virtual work h Σ_j b_j F_j·δq(c_j) puts
        // h b_j ℓ_m(c_j) F_j on node m (Fu, Dai & Tang's discrete forces, through
        // the basis); with the Jacobian, their derivatives in the unknowns.
        if forced {
            let f = if frozen {
                g.point_forces(system, j, h, (t, q, v), &mut fnode, None::<&mut NoJacobian<T>>).0
            } else {
                let mut entry = |rho: usize, i: usize, n: usize, k: usize, x: T| jac[rho][i][n][k] += x;
                g.point_forces(system, j, h, (t, q, v), &mut fnode, Some(&mut entry)).0
            };
            let w = b * h;
            for m in 0..S {
                for i in 0..N {
                    scale[m] = f64::max(scale[m], (w * (row[m] * f[i])).abs().to_f64());
                }
            }
        }
        // The weight w = b h is rounded once and shared by every row: all rows
        // are then derivatives of the same action Σ w_j L, whatever the
        // rounding. The point's terms w ∂L/∂q and w ∂L/∂v / h are kept and
        // contracted with the basis after the loop (one small matrix product
        // instead of a product per node and coordinate at every point).
        let w = b * h;
        let (mut a_max, mut b_max) = (0.0f64, 0.0f64);
        for i in 0..N {
            let (x, y) = (w * lq[i], w * (lv[i] / h));
            wq[j][i] = x;
            wv[j][i] = y;
            // ∂A/∂q_k at fixed increments.
            direct[i] += x;
            a_max = a_max.max(x.abs().to_f64());
            b_max = b_max.max(y.abs().to_f64());
        }
        scale[0] = scale[0].max(a_max);
        term_max[j] = (a_max, b_max);
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
    // ∂A/∂D_m = Σ_j ℓ_m(c_j) w_j ∂L/∂q + ℓ_m'(c_j) w_j ∂L/∂v / h for the
    // nodes m = 1 … s. The terms only size the round-off of the residual, so
    // the largest is bounded by the largest basis value and the largest
    // point term rather than found.
    let (a_max, b_max) = term_max.iter().fold((0.0f64, 0.0f64), |(a, b), &(x, y)| (a.max(x), b.max(y)));
    for m in 0..S {
        for j in 0..R {
            let (c, cd) = (g.col[j][m], g.col_d[j][m]);
            for i in 0..N {
                grad[m][i] += c * wq[j][i] + cd * wv[j][i];
            }
        }
        let k = if m + 1 < S { m + 1 } else { 0 };
        scale[k] = scale[k].max(g.col_max[m] * a_max + g.col_d_max[m] * b_max);
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
    if !frozen {
        work.valid = false;
        work.lu.factor_in_place().map_err(|f| match f {
            LuFailure::Singular => Breakdown::Singular(0.0),
            LuFailure::NonFinite => Breakdown::NonFinite("jacobian"),
        })?;
        work.valid = true;
    }
    if check && min_rcond > 0.0 {
        let rc = work.lu.rcond();
        if rc.is_nan() || rc < min_rcond {
            return Err(Breakdown::Singular(rc));
        }
    }
    let x = work.active().solve(&r);
    let correction = Nodes(x.map(|b| b.map(|v| -v)));
    let mut residual_ratio: f64 = 0.0;
    for rho in 0..S {
        residual_ratio = residual_ratio.max(max_abs(&r[rho]) / scale[rho]);
    }
    Ok(Linearization {
        correction,
        residual_norm: max_abs(r.as_flattened()),
        cancelled: residual_ratio,
        scale: 1.0,
        kept: false,
        floor: 0.0,
    })
}

/// The state of the Newton iteration of one step across its attempts: the
/// factored block, held in place, and whether the simplified iteration may
/// keep using it.
pub(super) struct Work<'a, const N: usize, const S: usize, T> {
    /// The factored block of an earlier step, borrowed from the memory (not
    /// copied: 1.2 kB at sN = 12).
    kept: Option<&'a Lu<N, S, T>>,
    /// The iteration uses `kept`, not `lu`.
    pub(super) uses_kept: bool,
    /// The step's own factored Newton block (or storage for the next one).
    pub(super) lu: Lu<N, S, T>,
    /// The block in use holds a factorisation the simplified iteration may use.
    pub(super) valid: bool,
    /// Simplified Newton (the Jacobian kept while it contracts) rather than full.
    pub(super) simplified: bool,
    /// The condition estimate is due at the next linearisation, if it factors.
    pub(super) check: bool,
    /// Size of the last correction of the simplified iteration.
    pub(super) last_correction: Option<f64>,
    /// Linearisations with a kept Jacobian (gradients of `L` only), over all solves.
    pub(super) gradients: usize,
    /// Linearisations that assembled a new Jacobian, over all solves.
    pub(super) hessians: usize,
}

impl<'a, const N: usize, const S: usize, T: Real> Work<'a, N, S, T> {
    /// Starting from a kept factorisation, or from none.
    #[inline]
    pub(super) fn new(kept: Option<&'a Lu<N, S, T>>, storage: Lu<N, S, T>) -> Self {
        let valid = kept.is_some();
        Self {
            kept,
            uses_kept: valid,
            lu: storage,
            valid,
            simplified: true,
            check: true,
            last_correction: None,
            gradients: 0,
            hessians: 0,
        }
    }

    /// Prepares a new solve: simplified or full Newton, from the kept
    /// factorisation (`kept`) or from a new one. Where the caller asks for a
    /// condition estimate (`min_rcond > 0`: energy-preserving steps; fixed
    /// steps estimate only on failure), it is made on the first
    /// linearisation of each solve, if that one factors.
    #[inline]
    pub(super) fn start(&mut self, simplified: bool, kept: bool) {
        self.simplified = simplified;
        self.uses_kept = kept && self.kept.is_some();
        self.valid = self.uses_kept;
        self.check = true;
        self.last_correction = None;
    }

    /// The factorisation the iteration solves with.
    #[inline]
    pub(super) fn active(&self) -> &Lu<N, S, T> {
        match (self.uses_kept, self.kept) {
            (true, Some(kept)) => kept,
            _ => &self.lu,
        }
    }
}

/// `failure` as [`NewtonFailure::Singular`] when the block the iteration
/// last factored (or borrowed) is too ill-conditioned for `min_rcond`: the
/// condition estimate of a fixed step, made only when its solve fails.
fn ill_conditioned<const N: usize, const S: usize, T: Real>(
    failure: NewtonFailure,
    work: &Work<'_, N, S, T>,
    min_rcond: f64,
) -> NewtonFailure {
    let (NewtonFailure::NotConverged(_) | NewtonFailure::NonFinite { .. }) = failure else { return failure };
    if !work.valid || min_rcond <= 0.0 {
        return failure;
    }
    let rcond = work.active().rcond();
    if rcond.is_nan() || rcond < min_rcond {
        NewtonFailure::Singular { iterations: failure.iterations(), rcond }
    } else {
        failure
    }
}

/// What the memory keeps of the block a step converged with.
pub(super) enum KeptBlock<const N: usize, const S: usize, T> {
    /// The one it already holds (the step used it throughout).
    Same,
    /// A new one, factored for steps of this size.
    New(T, Lu<N, S, T>),
    /// None.
    Drop,
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::system::Scalar;

    /// A failed solve whose last block is nearly singular is reported as a
    /// singular Jacobian with the estimated condition; a failure with a
    /// well-conditioned block, or of another kind, is left as it is.
    #[test]
    fn a_failure_with_an_ill_conditioned_block_is_a_singular_jacobian() {
        let factored = |eps: f64| {
            let mut work = Work::<1, 2, f64>::new(None, Lu::empty());
            *work.lu.matrix_mut() = BlockMatrix::from_blocks([[[[1.0], [1.0]]], [[[1.0], [1.0 + eps]]]]);
            work.lu.factor_in_place().unwrap();
            work.valid = true;
            work
        };
        let report = NewtonReport { iterations: 7, residual_norm: 1e-3, correction_norm: 1e-2 };
        let not_converged = NewtonFailure::NotConverged(report);
        match ill_conditioned(not_converged, &factored(1e-15), 1e-13) {
            NewtonFailure::Singular { iterations, rcond } => {
                assert_eq!(iterations, 7);
                assert!(rcond < 1e-13 && rcond > 1e-17, "{rcond:e}");
            }
            other => panic!("{other:?}"),
        }
        assert_eq!(ill_conditioned(not_converged, &factored(0.5), 1e-13), not_converged);
        // Without the check (`min_rcond = 0`) or a factored block, unchanged.
        assert_eq!(ill_conditioned(not_converged, &factored(1e-15), 0.0), not_converged);
        let mut stale = factored(1e-15);
        stale.valid = false;
        assert_eq!(ill_conditioned(not_converged, &stale, 1e-13), not_converged);
        let rejected = NewtonFailure::Rejected { iterations: 2, reason: "test" };
        assert_eq!(ill_conditioned(rejected, &factored(1e-15), 1e-13), rejected);
    }

    #[test]
    fn the_kept_block_pauses_after_each_refresh_for_twice_as_long() {
        // Refreshed (offered, not kept) four times in a row: pauses 1, 3, 7, 15, 15.
        let mut policy = KeptPolicy::default();
        let mut pauses = Vec::new();
        for _ in 0..5 {
            assert!(policy.offers());
            policy = policy.after(true, false, false);
            pauses.push(policy.skip);
            for _ in 0..policy.skip {
                assert!(!policy.offers());
                policy = policy.after(false, true, false);
            }
        }
        assert_eq!(pauses, [1, 3, 7, 15, 15]);
        // A step that keeps the block throughout resets the pause.
        assert_eq!(policy.after(true, false, true), KeptPolicy::default());
        // Steps without a kept block to offer (a new step size) leave it alone.
        let paused = KeptPolicy { skip: 2, backoff: 3 };
        assert_eq!(paused.after(false, false, false), paused);
    }

    /// `L = ½|v|² + 1/|q|`.
    struct Kepler;

    impl Lagrangian<2> for Kepler {
        const AUTONOMOUS: bool = true;
        const CYCLIC: [bool; 2] = [false; 2];
        fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 2], v: [D; 2]) -> D {
            (v[0] * v[0] + v[1] * v[1]) * 0.5 + (q[0] * q[0] + q[1] * q[1]).sqrt().recip()
        }
    }

    /// Kepler e = 0.5 from pericentre with `n` steps of Galerkin s = 6, the
    /// `k`-th of size `size(k)`; the final state and Newton iterations per step.
    fn kepler_run(n: usize, size: impl Fn(usize) -> f64) -> ([f64; 2], [f64; 2], f64) {
        let newton = Galerkin::<6, 6>::gauss().with_iteration(StageIteration::Newton);
        let mut sim = Integrator::new(Kepler, newton, size(0)).start(0.0, [0.5, 0.0], [0.0, 3f64.sqrt()]).unwrap();
        for k in 0..n {
            sim.set_step_size(size(k)).unwrap();
            sim.step().unwrap();
        }
        let s = sim.stats();
        (sim.state().q, sim.state().p, s.newton_iterations as f64 / s.steps as f64)
    }

    /// Every linearisation costs `R` derivative evaluations and the momentum
    /// update `R` gradients more; with the kept block most steps assemble no
    /// Jacobian, so Hessians are a small share of the evaluations.
    #[test]
    fn point_evaluations_count_every_linearisation() {
        let newton = Galerkin::<6, 6>::gauss().with_iteration(StageIteration::Newton);
        let mut sim = Integrator::new(Kepler, newton, 0.1).start(0.0, [0.5, 0.0], [0.0, 3f64.sqrt()]).unwrap();
        assert_eq!(sim.point_evaluations(), PointEvaluations::default());
        sim.run(200, |_| {}).unwrap();
        let (e, s) = (sim.point_evaluations(), sim.stats());
        assert_eq!(e.gradients + e.hessians, 6 * (s.newton_iterations + s.steps), "{e:?} {s:?}");
        // The first step assembles its own Jacobian; afterwards a kept one
        // serves most steps (Hessians on fewer than one step in four).
        assert!(e.hessians >= 6, "{e:?}");
        assert!(e.hessians < 6 * s.steps / 4, "{e:?} {s:?}");
        // The fixed-point iteration: gradients at every point per iteration
        // (the first with the Hessian in v) and for the momentum update at
        // the returned stage values.
        let fixed = Galerkin::<6, 6>::gauss().with_iteration(StageIteration::FixedPoint);
        let mut sim = Integrator::new(Kepler, fixed, 0.05).start(0.0, [0.5, 0.0], [0.0, 3f64.sqrt()]).unwrap();
        sim.run(200, |_| {}).unwrap();
        let (e, s) = (sim.point_evaluations(), sim.stats());
        assert_eq!((e.hessians, e.velocity_hessians, e.gradients), (0, 6 * 200, 6 * s.newton_iterations), "{e:?}");
    }

    /// `L = ½(ṙ² + r²φ̇²) + 1/r`: Kepler in polar coordinates, a mass
    /// matrix `diag(1, r²)`.
    struct KeplerPolar;

    impl Lagrangian<2> for KeplerPolar {
        const AUTONOMOUS: bool = true;
        const CYCLIC: [bool; 2] = [false, true];
        fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 2], v: [D; 2]) -> D {
            (v[0] * v[0] + q[0] * q[0] * v[1] * v[1]) * 0.5 + q[0].recip()
        }
    }

    /// The energy of the fixed-point steps stays within a few ulps over 100
    /// orbits of Kepler e = 0.5 in polar coordinates (s = 6, 100 steps per
    /// orbit, truncation error far below round-off). Measured: 4e-16 with
    /// the momentum update evaluated at the returned stage values and the
    /// coefficients `μ_ij (h b_j)`; 3.8e-14, drifting linearly (a phase
    /// error of 1.3e-8 after 1000 orbits), with the update taking the
    /// gradients of the last round before its correction, or evaluated at
    /// stage values rounded through the node increments.
    #[test]
    fn the_fixed_point_keeps_the_energy_of_a_long_orbit_at_round_off() {
        let energy = |q: [f64; 2], p: [f64; 2]| 0.5 * (p[0] * p[0] + p[1] * p[1] / (q[0] * q[0])) - 1.0 / q[0];
        let h = 2.0 * core::f64::consts::PI / 100.0;
        let v0 = [0.0, 3f64.sqrt() / 0.5];
        let mut sim = Integrator::new(KeplerPolar, Galerkin::<6, 6>::gauss(), h).start(0.0, [0.5, 0.0], v0).unwrap();
        let e0 = energy(sim.state().q, sim.state().p);
        sim.run(10_000, |_| {}).unwrap();
        let drift = energy(sim.state().q, sim.state().p) - e0;
        assert!(drift.abs() < 4e-15, "{drift:e}");
    }

    /// Kepler with its constant mass matrix declared: `M⁻¹` is kept.
    struct ConstantMassKepler;

    impl Lagrangian<2> for ConstantMassKepler {
        const AUTONOMOUS: bool = true;
        const CYCLIC: [bool; 2] = [false, false];
        const SEPARABILITY: crate::Separability = crate::Separability::ConstantMass;
        fn lagrangian<D: Scalar>(&self, t: D, q: [D; 2], v: [D; 2]) -> D {
            Kepler.lagrangian(t, q, v)
        }
    }

    /// A constant mass matrix is inverted once per run, and the steps are
    /// those of the inverse formed at every point, bit for bit.
    #[test]
    fn a_constant_mass_matrix_is_inverted_once() {
        let fixed = Galerkin::<4, 4>::gauss().with_iteration(StageIteration::FixedPoint);
        let (q0, v0) = ([0.5, 0.0], [0.0, 3f64.sqrt()]);
        let mut kept = Integrator::new(ConstantMassKepler, fixed, 0.05).start(0.0, q0, v0).unwrap();
        let mut every = Integrator::new(Kepler, fixed, 0.05).start(0.0, q0, v0).unwrap();
        kept.run(200, |_| {}).unwrap();
        every.run(200, |_| {}).unwrap();
        assert_eq!(kept.state(), every.state());
        assert_eq!(kept.point_evaluations().velocity_hessians, 1);
        assert_eq!(every.point_evaluations().velocity_hessians, 4 * 200);
    }

    /// `L = ½v² + ln q`, defined for `q > 0` only.
    struct Logarithmic;

    impl Lagrangian<1> for Logarithmic {
        const AUTONOMOUS: bool = true;
        const CYCLIC: [bool; 1] = [false];
        fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 1], v: [D; 1]) -> D {
            v[0] * v[0] * 0.5 + q[0].ln()
        }
    }

    #[test]
    fn a_failed_step_counts_no_evaluations() {
        // From q = 1 towards 0 at speed 10: steps of 0.01 stay in q > 0, a
        // step of 1 leaves it (ln q is NaN there) and fails.
        let mut sim = Integrator::new(Logarithmic, Galerkin::<3, 3>::gauss(), 0.01).start(0.0, [1.0], [-10.0]).unwrap();
        sim.run(3, |_| {}).unwrap();
        let before = sim.point_evaluations();
        assert!(before.gradients + before.hessians > 0, "{before:?}");
        sim.set_step_size(1.0).unwrap();
        assert!(sim.step().is_err());
        assert_eq!(sim.point_evaluations(), before);
    }

    #[test]
    fn a_kept_jacobian_gives_the_steps_of_a_fresh_one() {
        const { assert!(Integrator::<Kepler, Galerkin<6, 6>, 2>::KEEPS_JACOBIAN) };
        let n = 20_000;
        // Constant steps reuse the last step's block; steps whose sizes
        // alternate by one ulp never do (the kept block is for another h),
        // and differ from constant steps by O(ε) in h only.
        let (q_kept, p_kept, it_kept) = kepler_run(n, |_| 0.1);
        let (q_fresh, p_fresh, it_fresh) = kepler_run(n, |k| if k % 2 == 0 { 0.1 } else { 0.1f64.next_up() });
        // Measured: 5e-10 apart in q with the kept block held to `rtol`
        // alone (its iteration stopped on the same side of the root step
        // after step), 2e-12 with `rtol/100`.
        for i in 0..2 {
            assert!((q_kept[i] - q_fresh[i]).abs() < 2e-11, "{q_kept:?} {q_fresh:?}");
            assert!((p_kept[i] - p_fresh[i]).abs() < 2e-11, "{p_kept:?} {p_fresh:?}");
        }
        // The fresh path converges in two iterations; the kept one needs more,
        // but far fewer than the cap.
        assert!(it_fresh <= 2.5 && it_kept <= 5.0, "{it_fresh} {it_kept}");
    }
}
