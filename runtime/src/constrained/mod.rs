//! Holonomic constraints `g(t, q) = 0`: the constrained discrete Euler–Lagrange
//! equations of a one-point discrete Lagrangian in position–momentum form
//! (RATTLE; Marsden & West, *Discrete mechanics and variational
//! integrators*, Acta Numerica 2001, §3.4; Hairer, Lubich & Wanner,
//! *Geometric Numerical Integration*, §VII.1):
//!
//! ```text
//! p_k     = −D₁A(q_k, q_{k+1}) − G(q_k)ᵀ λ_k,         g(q_{k+1}) = 0,
//! p_{k+1} =  D₂A(q_k, q_{k+1}) + G(q_{k+1})ᵀ μ_k,      G(q_{k+1}) v(q_{k+1}, p_{k+1}) = 0,
//! ```
//!
//! with `A = h L_d` the step action and `G = ∂g/∂q`. The first line is
//! solved for `(q_{k+1}, λ_k)` by a simplified Newton iteration on the
//! `(N + M)` saddle-point system, eliminated block-wise: the inverse of the
//! step Jacobian `J = ∂²A/∂q_k∂q_{k+1}` is kept through the iterations and
//! from one step to the next of the same size, and each iteration evaluates
//! the residual (the gradient `D₁A`, `g(q_{k+1})`) and `G(q_{k+1})` and
//! solves the `M × M` Schur complement `G(q_{k+1}) J⁻¹ G(q_k)ᵀ` for the
//! multiplier correction. `J` is evaluated anew (by hyper-duals) at the
//! first guess of a step of another size, and at the iterate where a
//! correction with the kept inverse is more than `SLOWEST_CONTRACTION`
//! times the one before; if the simplified iteration fails, Newton's method from the
//! same guess decides. It stops where the corrections of the positions and
//! of the multiplier are at the tolerance (or round-off), so the positions
//! are as close to the root as Newton's. The second line is solved for
//! `(v_{k+1}, μ_k)` by Newton's method with the Hessian `∂²L/∂v²` in place
//! of `J` (`cotangent.rs`: one iteration for a quadratic kinetic energy).
//! Both constraints then hold to Newton's tolerance at every node: the
//! positions on the manifold, the momenta on its cotangent space. The map
//! is symplectic on the constrained cotangent bundle (its derivative:
//! `constrained/tangent.rs`).
//!
//! Forces and dissipation enter by the discrete Lagrange–d'Alembert
//! principle ([`forcing`]): the rule's discrete forces
//! `F_k^−` and `F_k^+` are added to `D₁A` and `D₂A`, the constraint forces
//! `Gᵀλ`, `Gᵀμ` stay as they are. Time-dependent (rheonomic) constraints
//! `g(t, q) = 0` are imposed at each node's own time, `g(t_{k+1}, q_{k+1})
//! = 0` and `G(t_k, q_k)ᵀλ_k`, and their hidden form carries the motion of
//! the manifold: `G(t_{k+1}, q_{k+1}) v_{k+1} + ∂g/∂t(t_{k+1}, q_{k+1}) = 0`.
//! A time-dependent Lagrangian needs nothing more: the step action already
//! carries `t_k`. The constrained Galerkin rules and compositions carry all
//! three the same way (`galerkin.rs`, `composition.rs`).
//!
//! A rank-deficient `G` (redundant constraints, a dead point) shows as a
//! singular Schur complement and is a typed error, with the state kept.

mod composition;
mod cotangent;
pub mod dynamic;
mod energy;
mod galerkin;
mod galerkin_energy;
mod kkt;
mod linear;
mod project;
mod saddle;
mod sparsity;
mod tangent;
#[cfg(test)]
mod tests;

use nalgebra::{SMatrix, SVector};

use crate::dense::{Hermite, Node};
use crate::derivatives::{self, Segment};
use crate::discrete::DiscreteLagrangian;
use crate::error::{Error, Unplaced};
use crate::forcing::{self, DiscreteForces, EnergyBalance};
use crate::hyperdual::DualArray;
use crate::integrator::{F64Readouts, Integrator, Method, Sealed, StepBounds, StepPolicy, add_increment, predict_into};
use crate::mechanics::DiscreteMechanics;
use crate::real::max_abs;
use crate::state::State;
use crate::symplectic::TangentMap;
use crate::system::Lagrangian;

use cotangent::onto_cotangent;
use linear::{inverse, solve_schur_inverted};
use num_dual::Dual64;

/// The relative tolerance within which initial data must satisfy the
/// constraints and their hidden (velocity-level) form; see
/// [`Error::InconsistentConstraints`].
pub const CONSISTENCY_TOLERANCE: f64 = 1e-10;

/// A one-point discrete Lagrangian (midpoint, trapezoid, α-β) with the `M`
/// holonomic constraints of the system imposed at every node, RATTLE-style
/// (see the [module documentation](self)).
///
/// `M` must equal the system's [`Lagrangian::CONSTRAINTS`] (the length of
/// the array `fn constraints` returns); the integrator refuses the system
/// otherwise.
///
/// ```
/// use lagrangian_runtime::{Constrained, Integrator, Lagrangian, Midpoint, Scalar};
///
/// /// A pendulum as a point on a circle of radius 1, written by hand
/// /// (`#[lagrangian]` writes this from `fn constraints`).
/// struct Pendulum;
/// impl Lagrangian<2> for Pendulum {
///     const AUTONOMOUS: bool = true;
///     const CYCLIC: [bool; 2] = [false, false];
///     const CONSTRAINTS: usize = 1;
///     fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 2], v: [D; 2]) -> D {
///         (v[0] * v[0] + v[1] * v[1]) * 0.5 - q[1]
///     }
///     fn constraints<D: Scalar>(&self, _t: D, q: &[D; 2], g: &mut [D]) {
///         g[0] = q[0] * q[0] + q[1] * q[1] - 1.0;
///     }
/// }
///
/// let method = Constrained::<_, 1>::new(Midpoint);
/// let mut sim = Integrator::new(Pendulum, method, 0.01).start(0.0, [1.0, 0.0], [0.0, 0.0])?;
/// sim.run(1000, |_| {})?;
/// let [x, y] = sim.state().q;
/// assert!((x * x + y * y - 1.0).abs() < 1e-14);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Constrained<D, const M: usize> {
    /// The unconstrained rule whose action is made stationary on the manifold.
    pub rule: D,
}

impl<D: DiscreteLagrangian, const M: usize> Constrained<D, M> {
    /// The rule `rule` with `M` constraints imposed at the nodes.
    pub fn new(rule: D) -> Self {
        Self { rule }
    }
}

/// What a constrained method keeps of its last steps.
#[doc(hidden)]
#[derive(Clone, Copy, Debug)]
pub struct ConstrainedMemory<const N: usize, const M: usize> {
    /// The last step, `None` before the first.
    previous: Option<Segment<N>>,
    /// The step before it.
    earlier: Option<Segment<N>>,
    /// The multiplier `λ` of the last step: the next step's first guess.
    lambda: [f64; M],
    /// The velocity at the current node (the initial one at the start).
    velocity: [f64; N],
    /// The inverse step Jacobian the last step converged with.
    kept: Option<KeptInverse<N>>,
}

/// The largest ratio of successive corrections with which a simplified
/// iteration keeps its matrix (an inverse step Jacobian, the factors of a
/// saddle-point system): above it the matrix is refreshed at the next
/// iterate, from where the iteration converges like Newton's.
pub(super) const SLOWEST_CONTRACTION: f64 = 0.1;

impl<D: DiscreteLagrangian, const M: usize> Sealed for Constrained<D, M> {}

/// `g(t, q)` in `f64`.
pub(crate) fn values<S: Lagrangian<N> + ?Sized, const N: usize, const M: usize>(
    system: &S,
    t: f64,
    q: &[f64; N],
) -> [f64; M] {
    let mut g = [0.0; M];
    system.constraints(t, q, &mut g);
    g
}

/// `g(t, q)` and the Jacobian `G = ∂g/∂q` from one evaluation on duals
/// seeded on `q`; `None` when a value is not finite.
pub(crate) fn jacobian<S: Lagrangian<N> + ?Sized, const N: usize, const M: usize>(
    system: &S,
    t: f64,
    q: &[f64; N],
) -> Option<([f64; M], SMatrix<f64, M, N>)> {
    type D<const N: usize> = DualArray<[f64; N]>;
    let mut qd = q.map(D::<N>::from_re);
    for (i, x) in qd.iter_mut().enumerate() {
        x.eps[i] = 1.0;
    }
    let mut g = [D::<N>::from_re(0.0); M];
    system.constraints(D::from_re(t), &qd, &mut g);
    let value = g.map(|x| x.re);
    let jac = SMatrix::<f64, M, N>::from_fn(|i, j| g[i].eps[j]);
    (value.iter().all(|x| x.is_finite()) && jac.iter().all(|x| x.is_finite())).then_some((value, jac))
}

/// `∂g/∂t(t, q)`, the velocity of a moving constraint manifold, from one
/// evaluation on a dual number seeded on `t`; zero (and no evaluation) for
/// constraints that do not depend on time, `None` when not finite.
pub(crate) fn rate<S: Lagrangian<N> + ?Sized, const N: usize, const M: usize>(
    system: &S,
    t: f64,
    q: &[f64; N],
) -> Option<[f64; M]> {
    if S::CONSTRAINTS_AUTONOMOUS {
        return Some([0.0; M]);
    }
    let mut g = [Dual64::from_re(0.0); M];
    system.constraints(Dual64::new(t, 1.0), &q.map(Dual64::from_re), &mut g);
    let rate = g.map(|x| x.eps);
    rate.iter().all(|x| x.is_finite()).then_some(rate)
}

/// The relative distances of `(q, v)` from the manifold and its tangent
/// space (see [`Error::InconsistentConstraints`]); `rate` is `∂g/∂t`, so the
/// velocity condition is the hidden constraint `G v + ∂g/∂t = 0`.
pub(crate) fn inconsistency<const N: usize, const M: usize>(
    g: &[f64; M],
    jac: &SMatrix<f64, M, N>,
    rate: &[f64; M],
    q: &[f64; N],
    v: &[f64; N],
) -> (f64, f64) {
    let gv = jac * SVector::from(*v) + SVector::from(*rate);
    let (mut position, mut velocity) = (0.0f64, 0.0f64);
    for i in 0..M {
        let norm = jac.row(i).norm();
        position = position.max(g[i].abs() / norm);
        velocity = velocity.max(gv[i].abs() / norm);
    }
    (position / max_abs(q).max(1.0), if max_abs(v) > 0.0 { velocity / max_abs(v) } else { velocity })
}

impl<D: DiscreteLagrangian, const M: usize> Method<f64> for Constrained<D, M> {
    type Memory<const N: usize> = ConstrainedMemory<N, M>;

    const CONSTRAINTS: usize = M;

    fn method_order(&self) -> u32 {
        self.rule.order()
    }

    fn memory<const N: usize>(&self) -> ConstrainedMemory<N, M> {
        ConstrainedMemory { previous: None, earlier: None, lambda: [0.0; M], velocity: [0.0; N], kept: None }
    }

    fn supports<S: Lagrangian<N>, const N: usize>(&self, policy: &StepPolicy) -> Result<(), Error> {
        if M == 0 || M >= N {
            return Err(Error::InvalidMethod {
                reason: "holonomic constraints: the number of constraints M must satisfy 0 < M < N",
            });
        }
        if let StepPolicy::EnergyPreserving(bounds) = policy {
            if !S::CONSTRAINTS_AUTONOMOUS {
                return Err(Error::Unsupported { what: energy::MOVING_CONSTRAINTS });
            }
            if bounds.accuracy.is_some() {
                return Err(Error::Unsupported { what: energy::ACCURACY_BOUND });
            }
        }
        Ok(())
    }

    fn supports_derivatives<S: Lagrangian<N>, const N: usize>(
        &self,
        reverse: bool,
        _: &StepPolicy,
    ) -> Result<(), Error> {
        if reverse {
            return Err(Error::Unsupported {
                what: "reverse-mode derivatives (systems larger than `Derivatives::FORWARD_MAX_N`) with holonomic constraints",
            });
        }
        Ok(())
    }

    fn legendre<S: Lagrangian<N>, const N: usize>(
        system: &S,
        t0: f64,
        q0: [f64; N],
        v0: [f64; N],
    ) -> Result<([f64; N], f64), Error> {
        let state = State { step: 0, t: t0, q: q0, p: [0.0; N] };
        let (g, jac) =
            jacobian::<S, N, M>(system, t0, &q0).ok_or_else(|| Error::NonFiniteConstraints { state: state.into() })?;
        let (_, rcond) = inverse(jac * jac.transpose());
        if rcond < 1e-12 {
            return Err(Error::SingularConstraints { state: state.into(), rcond });
        }
        let rate =
            rate::<S, N, M>(system, t0, &q0).ok_or_else(|| Error::NonFiniteConstraints { state: state.into() })?;
        let (position, velocity) = inconsistency(&g, &jac, &rate, &q0, &v0);
        if !(position <= CONSISTENCY_TOLERANCE && velocity <= CONSISTENCY_TOLERANCE) {
            return Err(Error::InconsistentConstraints { position, velocity, tolerance: CONSISTENCY_TOLERANCE });
        }
        let p0 = system.momentum(t0, q0, v0);
        let l = system.lagrangian(t0, q0, v0);
        if !l.is_finite() || !p0.iter().all(|x| x.is_finite()) {
            return Err(Error::InvalidInitialData { reason: "L or ∂L/∂v is not finite at the initial data" });
        }
        let (_, rcond) = inverse(system.velocity_hessian(t0, q0, v0));
        if rcond < 1e-14 {
            return Err(Error::InvalidInitialData {
                reason: "∂²L/∂v² is singular at the initial data: the Legendre transform is not regular",
            });
        }
        let energy = (0..N).map(|i| v0[i] * p0[i]).sum::<f64>() - l;
        Ok((p0, energy))
    }

    fn fixed_step<S: Lagrangian<N>, const N: usize>(
        it: &mut Integrator<S, Self, N>,
        h: f64,
        t1: f64,
    ) -> Result<(), Error> {
        match step(it, h, t1) {
            Ok(()) => Ok(()),
            Err(error) => {
                it.stats.failed_steps += 1;
                Err(error)
            }
        }
    }

    fn energy_step<S: Lagrangian<N>, const N: usize>(
        it: &mut Integrator<S, Self, N>,
        bounds: StepBounds,
    ) -> Result<(), Error> {
        energy::energy_step(it, bounds)
    }

    fn reread_energy<S: Lagrangian<N>, const N: usize>(it: &mut Integrator<S, Self, N>) {
        energy::reread_energy(it);
    }

    fn last_step_size<const N: usize>(memory: &ConstrainedMemory<N, M>) -> Option<f64> {
        memory.previous.map(|last| last.h)
    }

    fn discrete_energy<S: Lagrangian<N>, const N: usize>(it: &Integrator<S, Self, N>) -> f64 {
        match &it.memory.previous {
            // The constraint forces do no work on the step's end node: the
            // energy is that of the unconstrained action.
            Some(seg) => -derivatives::end_time_derivative(&it.system, &it.method.rule, seg),
            None => it.energy,
        }
    }
}

/// One constrained step; on failure nothing in `it` has changed.
fn step<S: Lagrangian<N>, D: DiscreteLagrangian, const N: usize, const M: usize>(
    it: &mut Integrator<S, Constrained<D, M>, N>,
    h: f64,
    t1: f64,
) -> Result<(), Error> {
    let solved = positions(it, h, t1).map_err(|e| e.at(it.state))?;
    commit(it, solved, t1)
}

/// The solved position line of a step.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Positions<const N: usize, const M: usize> {
    /// The step from `q_k` to `q_{k+1}`.
    seg: Segment<N>,
    /// The multiplier `λ_k`.
    lambda: SVector<f64, M>,
    /// Newton iterations spent.
    iterations: usize,
    /// The inverse step Jacobian the iteration converged with.
    kept: KeptInverse<N>,
}

/// The inverse of the step Jacobian `J = ∂²A/∂q_k∂q_{k+1}` that a step of
/// size `h` converged with: the simplified iterations of later steps of the
/// same size start from it.
#[derive(Clone, Copy, Debug)]
struct KeptInverse<const N: usize> {
    h: f64,
    inverse: SMatrix<f64, N, N>,
    /// `‖J‖₁`.
    norm: f64,
}

/// The position line of a step of size `h` ending at `t1`: `(q_{k+1}, λ_k)`
/// from `p_k + D₁A + F_k^− + G(q_k)ᵀλ = 0`, `g(t1, q_{k+1}) = 0`.
///
/// Simplified Newton first: `J⁻¹` of the last step where it had the same
/// size (else of the first guess) kept through the iterations, each of
/// which costs the gradient `D₁A` and `G(q_{k+1})` (the Schur complement is
/// formed with the iterate's `G`), and refreshed at the iterate where it
/// contracts slowly. If that fails for any reason, Newton from the same
/// guess, whose failure is the step's error: a kept inverse never decides
/// that a step fails.
fn positions<S: Lagrangian<N>, D: DiscreteLagrangian, const N: usize, const M: usize>(
    it: &Integrator<S, Constrained<D, M>, N>,
    h: f64,
    t1: f64,
) -> Result<Positions<N, M>, Unplaced> {
    let state = it.state;
    let (_, g0) = jacobian::<S, N, M>(&it.system, state.t, &state.q)
        .ok_or_else(|| Unplaced::new(|state| Error::NonFiniteConstraints { state }))?;
    let mut dq = [0.0; N];
    {
        let last = it.memory.previous.as_ref().map(|s| (s.h, &s.dq[..]));
        let earlier = it.memory.earlier.as_ref().map(|s| (s.h, &s.dq[..]));
        let v = if it.memory.previous.is_some() { &it.memory.velocity } else { &it.v0 };
        predict_into(h, last, earlier, v, &mut dq);
    }
    let lambda = SVector::<f64, M>::from(it.memory.lambda);
    let kept = it.memory.kept.filter(|k| k.h == h).map(|k| (k.inverse, k.norm));
    match position_attempt(it, (h, t1), &g0, (dq, lambda), Some(kept)) {
        Ok(solved) => Ok(solved),
        Err((_, spent)) => {
            let mut solved = position_attempt(it, (h, t1), &g0, (dq, lambda), None).map_err(|(error, _)| error)?;
            solved.iterations += spent;
            Ok(solved)
        }
    }
}

/// One attempt at the position line from `(dq, λ)` with `G(q_k) = g0`:
/// simplified Newton from the inverse `kept` and `‖J‖₁` (`Some(None)`:
/// from the first guess's) or, with `None`, Newton. On failure the error and the
/// iterations spent.
#[allow(clippy::type_complexity)]
fn position_attempt<S: Lagrangian<N>, D: DiscreteLagrangian, const N: usize, const M: usize>(
    it: &Integrator<S, Constrained<D, M>, N>,
    (h, t1): (f64, f64),
    g0: &SMatrix<f64, M, N>,
    (mut dq, mut lambda): ([f64; N], SVector<f64, M>),
    kept: Option<Option<(SMatrix<f64, N, N>, f64)>>,
) -> Result<Positions<N, M>, (Unplaced, usize)> {
    let State { t: t0, q: q0, p: p0, .. } = it.state;
    let options = it.newton;
    let rule = it.method.rule;
    let system = &it.system;
    let g0t = g0.transpose();
    let simplified = kept.is_some();
    let mut kept_inverse = kept.flatten();
    // The last correction with the current inverse, to measure its contraction.
    let mut previous: Option<f64> = None;
    let mut iterations = 0;
    let (mut residual_norm, mut correction_norm) = (f64::INFINITY, f64::INFINITY);
    while iterations < options.max_iterations {
        iterations += 1;
        let seg = Segment { t0, h, q0, dq };
        let q1 = seg.q1();
        let Some((g1, jac1)) = jacobian::<S, N, M>(system, t1, &q1) else {
            return Err((Unplaced::new(|state| Error::NonFiniteConstraints { state }), iterations));
        };
        let (d_q0, (a_inv, a_norm)) = match kept_inverse {
            Some(kept) => {
                let (mut d_q0, _) = derivatives::start_gradient(system, &rule, &seg);
                if forcing::is_forced::<S, N>() {
                    let minus = forcing::discrete_forces(system, &rule, &seg).minus;
                    for i in 0..N {
                        d_q0[i] += minus[i];
                    }
                }
                (d_q0, kept)
            }
            None => {
                let sd = forcing::forced_step_derivatives(system, &rule, &seg);
                if !sd.d2_q0_q1.iter().all(|x| x.is_finite()) {
                    return Err((
                        Unplaced::new(|state| Error::NonFinite { state, h, iterations, quantity: "residual" }),
                        iterations,
                    ));
                }
                let (a_inv, rcond) = inverse(sd.d2_q0_q1);
                if rcond <= options.min_rcond {
                    return Err((
                        Unplaced::new(|state| Error::SingularJacobian { state, h, iterations, rcond }),
                        iterations,
                    ));
                }
                previous = None;
                (sd.d_q0, (a_inv, linear::norm1(&sd.d2_q0_q1)))
            }
        };
        let r1 = SVector::<f64, N>::from_fn(|i, _| p0[i] + d_q0[i]) + g0t * lambda;
        let r2 = SVector::<f64, M>::from(g1);
        residual_norm = r1.amax().max(r2.amax());
        if !residual_norm.is_finite() {
            return Err((
                Unplaced::new(|state| Error::NonFinite { state, h, iterations, quantity: "residual" }),
                iterations,
            ));
        }
        let (ddq, dlambda) = match solve_schur_inverted(&a_inv, &g0t, &jac1, &r1, &r2, options.min_rcond) {
            Ok(x) => x,
            Err(linear::Singular::Block(rcond)) => {
                return Err((
                    Unplaced::new(|state| Error::SingularJacobian { state, h, iterations, rcond }),
                    iterations,
                ));
            }
            Err(linear::Singular::Schur(rcond)) => {
                return Err((Unplaced::new(|state| Error::SingularConstraints { state, rcond }), iterations));
            }
        };
        kept_inverse = Some((a_inv, a_norm));
        for i in 0..N {
            dq[i] += ddq[i];
        }
        lambda += dlambda;
        correction_norm = ddq.amax();
        if !correction_norm.is_finite() {
            return Err((
                Unplaced::new(|state| Error::NonFinite { state, h, iterations, quantity: "correction" }),
                iterations,
            ));
        }
        // The constraint is evaluated at `q_k + Δq`, so no correction below
        // the round-off of that sum is meaningful: a step from rest has an
        // increment far smaller than the position.
        let floor = 4.0 * f64::EPSILON * max_abs(&q1).max(max_abs(&q0));
        let mut converged = correction_norm <= options.rtol * max_abs(&dq) + options.atol + floor;
        if simplified {
            // A correction of the positions at round-off can come with one
            // of the multiplier that is not: with an inverse of another
            // iterate the next one would still move the positions. The
            // multiplier balances `p_k + D₁A`, whose round-off is that of
            // its terms and that of positions at round-off (`‖J‖` times
            // their floor).
            let noise = 16.0 * f64::EPSILON * max_abs(&p0).max(max_abs(&d_q0)) + a_norm * floor;
            converged &= dlambda.amax() <= options.rtol * lambda.amax() + options.atol + noise / g0.amax();
        }
        if converged {
            let kept = KeptInverse { h, inverse: a_inv, norm: a_norm };
            return Ok(Positions { seg: Segment { t0, h, q0, dq }, lambda, iterations, kept });
        }
        match previous {
            _ if !simplified => kept_inverse = None,
            Some(last) if correction_norm > SLOWEST_CONTRACTION * last => kept_inverse = None,
            _ => previous = Some(correction_norm),
        }
    }
    let error =
        Unplaced::new(|state| Error::NewtonDidNotConverge { state, h, iterations, residual_norm, correction_norm });
    Err((error, iterations))
}

/// Solves the momentum line of the step whose positions are `solved` and
/// takes the step; on failure nothing in `it` has changed.
fn commit<S: Lagrangian<N>, D: DiscreteLagrangian, const N: usize, const M: usize>(
    it: &mut Integrator<S, Constrained<D, M>, N>,
    solved: Positions<N, M>,
    t1: f64,
) -> Result<(), Error> {
    let Positions { seg, lambda, iterations, kept } = solved;
    let (state, options, rule, system) = (it.state, it.newton, it.method.rule, &it.system);
    let Segment { h, q0, dq, .. } = seg;
    let q1 = seg.q1();
    let (_, jac1) =
        jacobian::<S, N, M>(system, t1, &q1).ok_or_else(|| Error::NonFiniteConstraints { state: state.into() })?;
    let end = forcing::end_momentum(system, &rule, &seg);
    let rate1 = SVector::from(
        rate::<S, N, M>(system, t1, &q1).ok_or_else(|| Error::NonFiniteConstraints { state: state.into() })?,
    );

    // Momenta: (v_{k+1}, μ_k) from ∂L/∂v(q_{k+1}, v) = D₂A + F⁺ + G(q_{k+1})ᵀμ,
    // G(q_{k+1}) v + ∂g/∂t = 0.
    let v = dq.map(|x| x / h);
    let on = onto_cotangent(system, (t1, q1), &end, (&jac1, &rate1), v, &options, (h, iterations))
        .map_err(|e| e.at(state))?;
    let (p1, v, momentum_iterations) = (on.momentum, on.velocity, on.iterations);
    if !q1.iter().chain(&p1).all(|x| x.is_finite()) || !t1.is_finite() {
        return Err(Error::NonFinite { state: state.into(), h, iterations, quantity: "position" });
    }

    // Commit.
    let (q_new, carry) = add_increment(it.summation, &q0, &it.carry, &dq);
    it.state = State { step: state.step + 1, t: t1, q: q_new, p: p1 };
    it.carry = carry;
    it.p_carry = [0.0; N];
    it.memory.earlier = it.memory.previous;
    it.memory.previous = Some(seg);
    it.memory.lambda = lambda.into();
    it.memory.velocity = v;
    it.memory.kept = Some(kept);
    it.stats.steps += 1;
    it.stats.newton_iterations += (iterations + momentum_iterations) as u64;
    Ok(())
}

impl<D: DiscreteLagrangian, const M: usize> F64Readouts for Constrained<D, M> {
    fn velocity_guess<S: Lagrangian<N>, const N: usize>(it: &Integrator<S, Self, N>) -> [f64; N] {
        if it.memory.previous.is_some() { it.memory.velocity } else { it.v0 }
    }

    /// The derivative of the last step's equations in the coordinates of
    /// `(q, p)`: symplectic on the tangent space of the constrained phase
    /// space (`constrained/tangent.rs`).
    fn tangent_map<S: Lagrangian<N>, const N: usize>(it: &Integrator<S, Self, N>) -> Option<TangentMap<N>> {
        let seg = it.memory.previous.as_ref()?;
        tangent::tangent_map(&it.system, &it.method, seg, &it.memory.lambda, &it.state.p, &it.memory.velocity)
    }

    /// The impulse of the discrete forces alone: the constraint forces
    /// `Gᵀλ`, `Gᵀμ` have no component along a symmetry that the
    /// constraints respect.
    fn forcing_impulse<S: Lagrangian<N>, const N: usize>(
        it: &Integrator<S, Self, N>,
        symmetry: &(impl crate::noether::Generator<N> + ?Sized),
    ) -> Option<f64> {
        Some(crate::noether::forcing_impulse(&it.system, &it.method.rule, it.memory.previous.as_ref()?, symmetry))
    }

    type Native<const N: usize> = Hermite<N>;

    fn native<S: Lagrangian<N>, const N: usize>(
        _: &Integrator<S, Self, N>,
        start: &Node<N>,
        end: &Node<N>,
    ) -> Hermite<N> {
        Hermite::cubic(start, end)
    }
}

impl<S: Lagrangian<N>, D: DiscreteLagrangian, const N: usize, const M: usize> Integrator<S, Constrained<D, M>, N> {
    /// The constraint values `g(t_k, q_k)` at the current node.
    pub fn constraint_values(&self) -> [f64; M] {
        values::<S, N, M>(&self.system, self.state.t, &self.state.q)
    }

    /// The hidden constraint `G(t_k, q_k) v_k + ∂g/∂t(t_k, q_k)` at the
    /// current node (`G v` for constraints that do not depend on time), with
    /// `v_k` the velocity of the momentum `p_k`.
    pub fn constraint_velocities(&self) -> Result<[f64; M], Error> {
        let v = self.velocity()?;
        let (t, q) = (self.state.t, &self.state.q);
        let non_finite = || Error::NonFiniteConstraints { state: self.state.into() };
        let (_, jac) = jacobian::<S, N, M>(&self.system, t, q).ok_or_else(non_finite)?;
        let rate = rate::<S, N, M>(&self.system, t, q).ok_or_else(non_finite)?;
        Ok((jac * SVector::from(v) + SVector::from(rate)).into())
    }

    /// The discrete forces `(F_k^−, F_k^+)` of the last step
    /// ([`forcing`](crate::forcing)), or `None` before the first step; zero
    /// for a system without forces. The constraint forces are not included.
    pub fn last_forces(&self) -> Option<DiscreteForces<N>> {
        Some(forcing::discrete_forces(&self.system, &self.method.rule, self.memory.previous.as_ref()?))
    }

    /// The energy balance `E_{k+1} − E_k = W_k` across the current node,
    /// between the last two steps ([`forcing`](crate::forcing)), or `None`
    /// before the second step. The constraint forces do no work on the
    /// manifold, so the residual is the method's local energy error, `O(h³)`
    /// per node, as without constraints.
    pub fn energy_balance(&self) -> Option<EnergyBalance> {
        let (behind, ahead) = (self.memory.earlier.as_ref()?, self.memory.previous.as_ref()?);
        Some(forcing::energy_balance(&self.system, &self.method.rule, behind, ahead))
    }

    /// The multiplier `λ_k` of the last step (zero before the first): with
    /// `G(q_k)ᵀλ_k` it is the constraint impulse on the step's start node.
    pub fn multipliers(&self) -> [f64; M] {
        self.memory.lambda
    }
}
