//! Holonomic constraints on a Galerkin discrete Lagrangian: the constraint
//! imposed at every control node of the step polynomial, RATTLE-style at
//! the ends.
//!
//! ```text
//! unknowns D_m = Q_m − q_k (m = 1 … s), Λ_m (m = 1 … s − 1), λ_k:
//!     p_k + ∂A/∂Q_0 + F^0 + G(t_k, q_k)ᵀ λ_k = 0
//!     ∂A/∂Q_m + F^m + G(t_m, Q_m)ᵀ Λ_m = 0,   m = 1 … s − 1
//!     g(t_m, Q_m) = 0,                         m = 1 … s      (Q_s = q_{k+1}, t_m = t_k + τ_m h)
//! then p_{k+1} = ∂A/∂Q_s + F^s + G(t_{k+1}, q_{k+1})ᵀ μ_k
//! with G(t_{k+1}, q_{k+1}) v(q_{k+1}, p_{k+1}) + ∂g/∂t(t_{k+1}, q_{k+1}) = 0.
//! ```
//!
//! Forces and dissipation enter by the discrete Lagrange–d'Alembert
//! principle exactly as in the unconstrained Galerkin step: the discrete
//! forces `F^m = h Σ_j b_j ℓ_m(c_j) F(c_j)` of the stage points
//! (`galerkin/forces.rs`) are added to the rows `∂A/∂Q_m` (`m = 0 … s − 1`)
//! and `F^s` to the end momentum, `p_{k+1} = ∂A/∂Q_s + F^s + Gᵀμ_k`.
//! Time-dependent constraints `g(t, q)` are imposed at each node's own time
//! `t_k + τ_m h` (the end node at the step's end time), and the end
//! momentum on their hidden form `G v + ∂g/∂t = 0`; a time-dependent `L`
//! needs nothing more, the action is already evaluated at the stage times.
//! The orders below are measured with forces and moving constraints too:
//! `2s` for `s = 2, 3` on a damped, driven pendulum and on a pendulum on an
//! oscillating support under a varying gravity, against minimal
//! coordinates (`tests/constraints/forces.rs`, `tests/constraints/time.rs`).
//!
//! This is the discrete action `A(Q_0, …, Q_s)` of the Galerkin rule
//! (`docs/theory.md` §5) made stationary over step polynomials whose nodes
//! lie on the constraint manifold (Marsden & West, *Discrete mechanics and
//! variational integrators*, Acta Numerica 2001, §3.4: the constrained
//! discrete Euler–Lagrange equations with a multiplier per constrained
//! node), written in position–momentum form with the end node's momentum
//! projected onto the hidden constraint as in RATTLE (`cotangent.rs`). The
//! map is a constrained variational integrator, hence symplectic on the
//! constrained cotangent bundle, and `g` and `G v` hold at every node to
//! Newton's tolerance.
//!
//! Order: with Gauss–Lobatto control nodes and the `s + 1`-point
//! Gauss–Lobatto quadrature the nodes are the quadrature points and the
//! step is the `s + 1`-stage Lobatto IIIA–IIIB pair for constrained
//! Hamiltonian systems (Hairer, Lubich & Wanner, *Geometric Numerical
//! Integration*, §VII.1.5, the method with `0 = g(Q_i)` at every stage and
//! the hidden constraint at the end; Jay, SIAM J. Numer. Anal. 33, 1996),
//! of order `2s`. With `s` Gauss–Legendre points the nodes are not
//! quadrature points; the order is measured, not proved here: `2s` for
//! `s = 2, 3` on a bead on a circle in a cubic potential and on the
//! Cartesian double pendulum against minimal coordinates
//! (`tests/constraints/galerkin.rs`).
//!
//! A simplified Newton iteration on the `(sN + sM)` saddle-point system,
//! dense, in storage the memory allocates once, so stepping does not
//! allocate (`saddle.rs`). The matrix — the Hessian blocks of the action by
//! the chain rule from the Hessian of `L` at the quadrature points, the
//! constraint Jacobians `G(Q_m)` — is assembled and LU-factored at the first
//! guess of a step and its factors kept through the step's iterations: an
//! iteration that reuses them costs the gradient of `L` at the quadrature
//! points, `g` and `G` at the nodes (the residual) and two triangular
//! solves. They are refreshed at the current iterate where a correction is
//! more than `SLOWEST_CONTRACTION` times the one before. Factors are not
//! kept from one step to the next: a matrix one step old contracts by a few
//! per cent per iteration from the predictor's error, and the extra
//! iterations cost more than the matrix they save (callgrind,
//! `bench/constrained-instructions.sh` on a build that kept them, double
//! pendulum at `h = 0.01`: 102 034 against 88 043 instructions per step at
//! `s = 4`, 33 957 against 27 677 at `s = 2`, 48 070 against 37 905 for
//! Yoshida's fourth-order composition of three RATTLE steps). If the
//! simplified iteration fails, Newton's method
//! from the same guess (a new matrix every iteration) decides the step, so
//! a kept matrix never turns a step into a failure or hides a singular
//! configuration. Every iteration evaluates the whole residual at its
//! iterate, and the iteration stops where the correction it solves for —
//! of the nodes and of the multipliers — is at the tolerance (or
//! round-off): the residual, in the metric of a matrix whose iteration
//! contracts, is at the tolerance. The matrix of the interior rows leaves
//! out `Σ_a Λ_{m,a} ∇²g_a(Q_m)`: `Λ_m` is an impulse of size `O(h)` against
//! blocks of size `O(1/h)`, so the iteration still contracts by `O(h²)` per
//! step and converges to the same root.

use nalgebra::{SMatrix, SVector};

use super::cotangent::onto_cotangent;
use super::linear::{SCHUR_MIN_RCOND, inverse};
use super::saddle::Work;
use super::{Constrained, SLOWEST_CONTRACTION, jacobian, rate, values};
use crate::banded::{DenseMatrix, StepMatrix};
use crate::dense::{Hermite, Node};
use crate::discrete::Midpoint;
use crate::error::{Error, Unplaced};
use crate::galerkin::{Galerkin, NoJacobian, PointDerivatives, point_gradient, supports_policy};
use crate::integrator::{F64Readouts, Integrator, Method, Sealed, StepBounds, StepPolicy, add_increment};
use crate::newton::NewtonOptions;
use crate::real::max_abs;
use crate::state::State;
use crate::symplectic::TangentMap;
use crate::system::Lagrangian;

/// The last step of a constrained Galerkin integrator.
#[derive(Clone, Copy, Debug)]
pub(super) struct Segment<const N: usize, const S: usize> {
    pub(super) t0: f64,
    pub(super) h: f64,
    pub(super) q0: [f64; N],
    pub(super) d: [[f64; N]; S],
}

/// The smallest ratio of pivots the dense solve accepts: below it the
/// saddle-point system is taken as singular.
const MIN_PIVOT_RATIO: f64 = 1e-14;

/// What a constrained Galerkin method keeps of its last step.
#[doc(hidden)]
#[derive(Clone, Debug)]
pub struct ConstrainedGalerkinMemory<const N: usize, const S: usize, const M: usize> {
    pub(super) last: Option<Segment<N, S>>,
    /// `λ_k` of the last step.
    pub(super) lambda: [f64; M],
    /// `Λ_1 … Λ_{s−1}` of the last step (the last entry unused).
    pub(super) interior: [[f64; M]; S],
    /// The velocity at the current node (the initial one at the start).
    pub(super) velocity: [f64; N],
    /// The saddle-point storage.
    pub(super) work: Work,
}

impl<const N: usize, const S: usize, const M: usize> ConstrainedGalerkinMemory<N, S, M> {
    pub(super) fn new() -> Self {
        let work = Work::new(S * (N + M));
        Self { last: None, lambda: [0.0; M], interior: [[0.0; M]; S], velocity: [0.0; N], work }
    }
}

/// The unknowns of a step: node increments and multipliers (a first
/// guess, or an iterate).
#[derive(Clone, Copy, Debug)]
pub(super) struct Guess<const N: usize, const S: usize, const M: usize> {
    pub(super) d: [[f64; N]; S],
    pub(super) lambda: [f64; M],
    pub(super) interior: [[f64; M]; S],
}

/// A solved step.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Solved<const N: usize, const S: usize, const M: usize> {
    pub(super) d: [[f64; N]; S],
    pub(super) lambda: [f64; M],
    pub(super) interior: [[f64; M]; S],
    pub(super) velocity: [f64; N],
    pub(super) momentum: [f64; N],
    pub(super) iterations: usize,
}

/// How an attempt at a step linearises its equations.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Linearisation {
    /// Simplified Newton: the matrix of the first guess, refreshed at the
    /// current iterate where it contracts slowly.
    Simplified,
    /// Newton: the matrix of every iterate.
    Full,
}

/// Adds `x` to entry `(i, j)` of a matrix being assembled (in range and
/// assemblable by construction).
#[inline(always)]
fn add(a: &mut DenseMatrix, i: usize, j: usize, x: f64) {
    let added = a.add(i, j, x);
    debug_assert!(added.is_ok(), "{added:?}");
}

/// One constrained Galerkin step of size `h` from `(t0, q0, p0)`; its
/// failure is placed by the caller at the state the step started from.
/// Writes only `work`.
///
/// Simplified Newton first, then, if that fails for any reason, Newton
/// from the same guess, whose failure is the step's error: a matrix kept
/// through the iterations never decides that a step fails.
#[allow(clippy::too_many_arguments)]
pub(super) fn solve_step<Sys, const N: usize, const S: usize, const R: usize, const M: usize>(
    system: &Sys,
    rule: &Galerkin<S, R>,
    options: &NewtonOptions,
    (t0, h, t1): (f64, f64, f64),
    (q0, p0): (&[f64; N], &[f64; N]),
    guess: Guess<N, S, M>,
    work: &mut Work,
) -> Result<Solved<N, S, M>, Unplaced>
where
    Sys: Lagrangian<N> + ?Sized,
{
    debug_assert_eq!(work.n(), S * (N + M));
    let (_, g0) = jacobian::<Sys, N, M>(system, t0, q0)
        .ok_or_else(|| Unplaced::new(|state| Error::NonFiniteConstraints { state }))?;
    let step = Step { system, rule, options, t0, h, t1, q0, p0, g0: &g0 };
    let (x, iterations) = match step.attempt(guess, Linearisation::Simplified, work) {
        Ok(converged) => converged,
        Err((_, spent)) => match step.attempt(guess, Linearisation::Full, work) {
            Ok((x, iterations)) => (x, spent + iterations),
            Err((error, _)) => return Err(error),
        },
    };
    let Guess { d, lambda, interior } = x;
    // Consecutive nodes on one branch of the manifold have constraint
    // normals that agree: `G(Q_m) G(Q_{m−1})ᵀ` has a positive definite
    // symmetric part (`≈ G Gᵀ` for a small step). Where it has not, the
    // step crosses a singular configuration (a dead point, `G = 0`) or
    // jumps to another branch; the one-point step's Schur complement test
    // in the Euclidean metric.
    let mut previous = g0;
    for m in 1..=S {
        let qm: [f64; N] = core::array::from_fn(|i| q0[i] + d[m - 1][i]);
        let (_, jm) = jacobian::<Sys, N, M>(system, step.node_time(m - 1), &qm)
            .ok_or_else(|| Unplaced::new(|state| Error::NonFiniteConstraints { state }))?;
        let agreement = jm * previous.transpose();
        if ((agreement + agreement.transpose()) * 0.5).cholesky().is_none() {
            return Err(Unplaced::new(|state| Error::SingularConstraints { state, rcond: inverse(agreement).1 }));
        }
        previous = jm;
    }
    let q1: [f64; N] = core::array::from_fn(|i| q0[i] + d[S - 1][i]);
    let jac1 = previous;
    // p_{k+1} = ∂A/∂Q_s + F^s + G(q_{k+1})ᵀμ on the hidden constraint
    // G(t_{k+1}, q_{k+1}) v + ∂g/∂t(t_{k+1}, q_{k+1}) = 0.
    let (_, grad) = rule.node_gradient(system, t0, h, *q0, &d);
    let (_, end_force) = rule.discrete_forces(system, (t0, h), (q0, &[0.0; N]), &d);
    let end: [f64; N] = core::array::from_fn(|i| grad[S - 1][i] + end_force[i]);
    let v_end: [f64; N] = core::array::from_fn(|i| (0..S).map(|m| rule.end_d[m] * d[m][i]).sum::<f64>() / h);
    let rate1 = SVector::from(
        rate::<Sys, N, M>(system, t1, &q1)
            .ok_or_else(|| Unplaced::new(|state| Error::NonFiniteConstraints { state }))?,
    );
    let on = onto_cotangent(system, (t1, q1), &end, (&jac1, &rate1), v_end, options, (h, iterations))?;
    if !q1.iter().chain(&on.momentum).all(|x| x.is_finite()) {
        return Err(Unplaced::new(|state| Error::NonFinite { state, h, iterations, quantity: "position" }));
    }
    Ok(Solved {
        d,
        lambda,
        interior,
        velocity: on.velocity,
        momentum: on.momentum,
        iterations: iterations + on.iterations,
    })
}

/// The data of one step's equations.
struct Step<'a, Sys: ?Sized, const N: usize, const S: usize, const R: usize, const M: usize> {
    system: &'a Sys,
    rule: &'a Galerkin<S, R>,
    options: &'a NewtonOptions,
    t0: f64,
    h: f64,
    /// The end time, `t0 + h` up to its rounding: the time of the last node.
    t1: f64,
    q0: &'a [f64; N],
    p0: &'a [f64; N],
    /// `G(q_k)`.
    g0: &'a SMatrix<f64, M, N>,
}

impl<Sys, const N: usize, const S: usize, const R: usize, const M: usize> Step<'_, Sys, N, S, R, M>
where
    Sys: Lagrangian<N> + ?Sized,
{
    /// Column of `λ_k`, after the node increments and `Λ_1 … Λ_{s−1}`.
    const LAMBDA_AT: usize = S * N + (S - 1) * M;

    /// Column of `Λ_m` (`m = 1 … s − 1`); row of `g(Q_m)` is `S N + (m − 1) M`.
    const fn interior_at(m: usize) -> usize {
        S * N + (m - 1) * M
    }

    /// The time of control node `m + 1`, at which a moving constraint holds
    /// there: the step's end time for the end node.
    fn node_time(&self, m: usize) -> f64 {
        if m + 1 == S { self.t1 } else { self.t0 + self.rule.control[m] * self.h }
    }

    /// One attempt from `x` by `linearisation`: the solution and the
    /// iterations spent, or the error and the iterations spent.
    ///
    /// Every iteration evaluates the whole residual at the iterate — the
    /// action's rows from the gradient of `L` at the quadrature points
    /// (with its Hessian only where the matrix is assembled anew), `g` at
    /// every node, the multiplier terms — and solves for the correction;
    /// the iteration stops where the correction, node increments and
    /// multipliers both, is at the tolerance. With a kept matrix that is
    /// the size of the residual in the metric of a nearby matrix, and the
    /// iterate after it is within the contraction factor times the
    /// tolerance of the root.
    fn attempt(
        &self,
        mut x: Guess<N, S, M>,
        linearisation: Linearisation,
        work: &mut Work,
    ) -> Result<(Guess<N, S, M>, usize), (Unplaced, usize)> {
        let Self { system, rule, options, t0, h, q0, p0, g0, .. } = *self;
        // Whether `work` holds the factors of this attempt's matrix.
        let mut factored = false;
        // The last correction with the current factors, to measure their contraction.
        let mut previous: Option<f64> = None;
        let (mut residual_norm, mut correction_norm) = (f64::INFINITY, f64::INFINITY);
        let mut iterations = 0;
        let forced = Sys::HAS_FORCE || Sys::HAS_DISSIPATION;
        while iterations < options.max_iterations {
            iterations += 1;
            let fresh = !factored;
            let (mut matrix, r) = if fresh {
                let (a, r) = work.assemble();
                (Some(a), r)
            } else {
                (None, work.rhs_zeroed())
            };
            // The action's rows (and their Jacobian), by the chain rule from
            // the gradient (and Hessian) of L at the quadrature points.
            for j in 0..R {
                let (t, q, v) = rule.point(t0, h, (q0, &[0.0; N]), &x.d, j);
                let b = rule.quadrature().weights()[j];
                let w = b * h;
                let (lq, lv) = match &mut matrix {
                    Some(a) => {
                        let pd = PointDerivatives::at(system, t, q, v);
                        for rho in 0..S {
                            let (l, ld) = (rule.row[j][rho], rule.row_d[j][rho]);
                            for nn in 0..S {
                                let (c, cd) = (rule.col[j][nn], rule.col_d[j][nn]);
                                for i in 0..N {
                                    for k in 0..N {
                                        let entry = b
                                            * (h * l * c * pd.qq[i][k]
                                                + l * cd * pd.qv[i][k]
                                                + ld * c * pd.qv[k][i]
                                                + ld * cd * pd.vv[i][k] / h);
                                        add(a, rho * N + i, nn * N + k, entry);
                                    }
                                }
                            }
                        }
                        (pd.q, pd.v)
                    }
                    None => {
                        let (_, lq, lv) = point_gradient(system, t, q, v);
                        (lq, lv)
                    }
                };
                for rho in 0..S {
                    let (l, ld) = (rule.row[j][rho], rule.row_d[j][rho]);
                    for i in 0..N {
                        r[rho * N + i] += w * (l * lq[i]) + w * (ld * (lv[i] / h));
                    }
                }
                // Lagrange–d'Alembert: the discrete forces F^0 … F^{s−1} on
                // the rows' nodes (and their derivatives where the matrix is
                // assembled), as in the unconstrained step.
                if forced {
                    let mut nodes = [[0.0; N]; S];
                    match &mut matrix {
                        Some(a) => {
                            let mut entry = |rho: usize, i: usize, n: usize, k: usize, x: f64| {
                                add(a, rho * N + i, n * N + k, x);
                            };
                            rule.point_forces(system, j, h, (t, q, v), &mut nodes, Some(&mut entry));
                        }
                        None => {
                            rule.point_forces(system, j, h, (t, q, v), &mut nodes, None::<&mut NoJacobian<f64>>);
                        }
                    }
                    for (rho, node) in nodes.iter().enumerate() {
                        for i in 0..N {
                            r[rho * N + i] += node[i];
                        }
                    }
                }
            }
            // The size of the terms the multipliers balance, for the
            // round-off floor of their corrections.
            let action_scale = max_abs(&r[..S * N]).max(max_abs(p0));
            for i in 0..N {
                r[i] += p0[i];
                for c in 0..M {
                    r[i] += g0[(c, i)] * x.lambda[c];
                    if let Some(a) = &mut matrix {
                        add(a, i, Self::LAMBDA_AT + c, g0[(c, i)]);
                    }
                }
            }
            // The constraints at the nodes and their multipliers.
            for m in 1..=S {
                let qm: [f64; N] = core::array::from_fn(|i| q0[i] + x.d[m - 1][i]);
                let Some((gm, jm)) = jacobian::<Sys, N, M>(system, self.node_time(m - 1), &qm) else {
                    return Err((Unplaced::new(|state| Error::NonFiniteConstraints { state }), iterations));
                };
                let row = Self::interior_at(m);
                for c in 0..M {
                    r[row + c] = gm[c];
                    if let Some(a) = &mut matrix {
                        for i in 0..N {
                            add(a, row + c, (m - 1) * N + i, jm[(c, i)]);
                        }
                    }
                }
                if m < S {
                    for i in 0..N {
                        for c in 0..M {
                            r[m * N + i] += jm[(c, i)] * x.interior[m][c];
                            if let Some(a) = &mut matrix {
                                add(a, m * N + i, Self::interior_at(m) + c, jm[(c, i)]);
                            }
                        }
                    }
                }
            }
            residual_norm = max_abs(r);
            if !residual_norm.is_finite() {
                return Err((
                    Unplaced::new(|state| Error::NonFinite { state, h, iterations, quantity: "residual" }),
                    iterations,
                ));
            }
            if fresh {
                match work.factor() {
                    Ok(ratio) if ratio >= MIN_PIVOT_RATIO.max(options.min_rcond) => {}
                    Ok(ratio) | Err(Some(ratio)) => return Err((self.singular(&x.d, ratio, iterations), iterations)),
                    Err(None) => {
                        return Err((
                            Unplaced::new(|state| Error::NonFinite { state, h, iterations, quantity: "residual" }),
                            iterations,
                        ));
                    }
                }
                factored = true;
                previous = None;
            }
            if !work.solve() {
                return Err((
                    Unplaced::new(|state| Error::NonFinite { state, h, iterations, quantity: "correction" }),
                    iterations,
                ));
            }
            let dx = &work.rhs;
            for m in 0..S {
                for i in 0..N {
                    x.d[m][i] -= dx[m * N + i];
                }
            }
            for m in 1..S {
                for c in 0..M {
                    x.interior[m][c] -= dx[Self::interior_at(m) + c];
                }
            }
            for c in 0..M {
                x.lambda[c] -= dx[Self::LAMBDA_AT + c];
            }
            correction_norm = max_abs(&dx[..S * N]);
            if !correction_norm.is_finite() {
                return Err((
                    Unplaced::new(|state| Error::NonFinite { state, h, iterations, quantity: "correction" }),
                    iterations,
                ));
            }
            // No correction below the round-off of `q_k + D_m` is meaningful.
            let floor = 4.0 * f64::EPSILON * max_abs(q0).max(max_abs(&x.d[S - 1]));
            let mut converged = correction_norm <= options.rtol * max_abs(x.d.as_flattened()) + options.atol + floor;
            if linearisation == Linearisation::Simplified {
                // A correction of the nodes at round-off can come with one of
                // the multipliers that is not: with a matrix of another
                // iterate the next one would still move the nodes. The
                // multipliers balance the action's rows, whose round-off is
                // that of their terms and that of nodes at round-off (the
                // matrix's norm times the floor of the nodes).
                let multipliers = max_abs(x.interior.as_flattened()).max(max_abs(&x.lambda));
                let noise = 16.0 * f64::EPSILON * action_scale + work.norm() * floor;
                converged &= max_abs(&dx[S * N..]) <= options.rtol * multipliers + options.atol + noise / g0.amax();
            }
            if converged {
                return Ok((x, iterations));
            }
            match (linearisation, previous) {
                (Linearisation::Full, _) => factored = false,
                (Linearisation::Simplified, Some(last)) if correction_norm > SLOWEST_CONTRACTION * last => {
                    factored = false;
                }
                _ => previous = Some(correction_norm),
            }
        }
        let error =
            Unplaced::new(|state| Error::NewtonDidNotConverge { state, h, iterations, residual_norm, correction_norm });
        Err((error, iterations))
    }

    /// The error of a saddle-point matrix at the nodes `d` whose pivots
    /// have the ratio `ratio`: a rank-deficient constraint Jacobian at a
    /// node (redundant constraints, a dead point), else a singular step
    /// block.
    fn singular(&self, d: &[[f64; N]; S], ratio: f64, iterations: usize) -> Unplaced {
        let q0 = self.q0;
        let mut rcond = inverse(self.g0 * self.g0.transpose()).1;
        for m in 1..=S {
            let qm: [f64; N] = core::array::from_fn(|i| q0[i] + d[m - 1][i]);
            match jacobian::<Sys, N, M>(self.system, self.node_time(m - 1), &qm) {
                Some((_, jm)) => rcond = rcond.min(inverse(jm * jm.transpose()).1),
                None => return Unplaced::new(|state| Error::NonFiniteConstraints { state }),
            }
        }
        if rcond <= SCHUR_MIN_RCOND {
            return Unplaced::new(|state| Error::SingularConstraints { state, rcond });
        }
        Unplaced::new(|state| Error::SingularJacobian { state, h: self.h, iterations, rcond: ratio })
    }
}

/// The first guess of a step of size `h` after `last`: the last step's
/// polynomial extrapolated where the size is the same, otherwise the
/// straight line at the velocity `v`; the multipliers of the last step
/// scaled with the step (they are impulses).
pub(super) fn predict<const N: usize, const S: usize, const R: usize, const M: usize>(
    rule: &Galerkin<S, R>,
    h: f64,
    memory: &ConstrainedGalerkinMemory<N, S, M>,
    v: &[f64; N],
) -> Guess<N, S, M> {
    match &memory.last {
        Some(last) if last.h == h => {
            let mut d = [[0.0; N]; S];
            for (row, weights) in d.iter_mut().zip(&rule.extrapolate) {
                for (&w, dn) in weights.iter().zip(&last.d) {
                    for (x, &y) in row.iter_mut().zip(dn) {
                        *x += w * y;
                    }
                }
            }
            Guess { d, lambda: memory.lambda, interior: memory.interior }
        }
        last => {
            let rho = last.map_or(0.0, |l| h / l.h);
            Guess {
                d: rule.control.map(|tau| v.map(|v| v * tau * h)),
                lambda: memory.lambda.map(|x| x * rho),
                interior: memory.interior.map(|m| m.map(|x| x * rho)),
            }
        }
    }
}

/// The hidden constraint `G(t, q) v + ∂g/∂t(t, q)` at the node `state`
/// with velocity `v`.
pub(super) fn hidden_constraint<Sys, const N: usize, const M: usize>(
    system: &Sys,
    state: &State<N>,
    v: [f64; N],
) -> Result<[f64; M], Error>
where
    Sys: Lagrangian<N> + ?Sized,
{
    let non_finite = || Error::NonFiniteConstraints { state: (*state).into() };
    let (_, jac) = jacobian::<Sys, N, M>(system, state.t, &state.q).ok_or_else(non_finite)?;
    let rate = rate::<Sys, N, M>(system, state.t, &state.q).ok_or_else(non_finite)?;
    Ok((jac * SVector::from(v) + SVector::from(rate)).into())
}

/// The discrete energy `Σ_j b_j E_L(c_j)` of the step `seg`.
pub(super) fn step_energy<Sys, const N: usize, const S: usize, const R: usize>(
    system: &Sys,
    rule: &Galerkin<S, R>,
    seg: &Segment<N, S>,
) -> f64
where
    Sys: Lagrangian<N> + ?Sized,
{
    let mut e = 0.0;
    for j in 0..R {
        let (t, q, v) = rule.point(seg.t0, seg.h, (&seg.q0, &[0.0; N]), &seg.d, j);
        let (l, _, lv) = point_gradient(system, t, q, v);
        e += rule.quadrature().weights()[j] * ((0..N).map(|i| v[i] * lv[i]).sum::<f64>() - l);
    }
    e
}

/// Takes the solved step of size `h` ending at `t1`.
pub(super) fn commit<Sys, const N: usize, const S: usize, const R: usize, const M: usize>(
    it: &mut Integrator<Sys, Constrained<Galerkin<S, R>, M>, N>,
    h: f64,
    t1: f64,
    solved: &Solved<N, S, M>,
) where
    Sys: Lagrangian<N>,
{
    let State { step, t: t0, q: q0, .. } = it.state;
    let (q_new, carry) = add_increment(it.summation, &q0, &it.carry, &solved.d[S - 1]);
    it.state = State { step: step + 1, t: t1, q: q_new, p: solved.momentum };
    it.carry = carry;
    it.p_carry = [0.0; N];
    let memory = &mut it.memory;
    memory.last = Some(Segment { t0, h, q0, d: solved.d });
    (memory.lambda, memory.interior, memory.velocity) = (solved.lambda, solved.interior, solved.velocity);
    it.stats.steps += 1;
    it.stats.newton_iterations += solved.iterations as u64;
}

impl<const S: usize, const R: usize, const M: usize> Constrained<Galerkin<S, R>, M> {
    /// The Galerkin rule `rule` with `M` constraints imposed at its control
    /// nodes, the end momentum on the hidden constraint (RATTLE-style). With
    /// Gauss–Lobatto nodes and `S + 1` Lobatto points it is the Lobatto
    /// IIIA–IIIB pair of order `2S`:
    ///
    /// ```
    /// use lagrangian_runtime::galerkin::{Galerkin, NodeFamily, Quadrature};
    /// use lagrangian_runtime::{Constrained, Integrator, Lagrangian, Scalar};
    ///
    /// /// A pendulum as a point on a circle of radius 1.
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
    /// let lobatto = Galerkin::<2, 3>::new(NodeFamily::GaussLobatto, Quadrature::gauss_lobatto());
    /// let method = Constrained::<_, 1>::galerkin(lobatto);
    /// let mut sim = Integrator::new(Pendulum, method, 0.05).start(0.0, [1.0, 0.0], [0.0, 0.0])?;
    /// sim.run(200, |_| {})?;
    /// let [x, y] = sim.state().q;
    /// assert!((x * x + y * y - 1.0).abs() < 1e-14);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn galerkin(rule: Galerkin<S, R>) -> Self {
        Self { rule }
    }
}

impl<const S: usize, const R: usize, const M: usize> Sealed for Constrained<Galerkin<S, R>, M> {}

impl<const S: usize, const R: usize, const M: usize> Method<f64> for Constrained<Galerkin<S, R>, M> {
    type Memory<const N: usize> = ConstrainedGalerkinMemory<N, S, M>;

    const CONSTRAINTS: usize = M;

    fn method_order(&self) -> u32 {
        self.rule.order()
    }

    fn memory<const N: usize>(&self) -> ConstrainedGalerkinMemory<N, S, M> {
        ConstrainedGalerkinMemory::new()
    }

    fn check(&self) -> Result<(), &'static str> {
        self.rule.check()
    }

    fn supports<Sys: Lagrangian<N>, const N: usize>(&self, policy: &StepPolicy) -> Result<(), Error> {
        // Moving constraints and accuracy bounds as for the one-point rules;
        // forces and a time-dependent `L` as without constraints.
        Constrained::<Midpoint, M>::new(Midpoint).supports::<Sys, N>(policy)?;
        supports_policy::<Sys, N, f64>(policy)
    }

    fn supports_derivatives<Sys: Lagrangian<N>, const N: usize>(
        &self,
        reverse: bool,
        policy: &StepPolicy,
    ) -> Result<(), Error> {
        Constrained::<Midpoint, M>::new(Midpoint).supports_derivatives::<Sys, N>(reverse, policy)
    }

    fn legendre<Sys: Lagrangian<N>, const N: usize>(
        system: &Sys,
        t0: f64,
        q0: [f64; N],
        v0: [f64; N],
    ) -> Result<([f64; N], f64), Error> {
        <Constrained<Midpoint, M> as Method<f64>>::legendre(system, t0, q0, v0)
    }

    fn fixed_step<Sys: Lagrangian<N>, const N: usize>(
        it: &mut Integrator<Sys, Self, N>,
        h: f64,
        t1: f64,
    ) -> Result<(), Error> {
        let State { t: t0, q: q0, p: p0, .. } = it.state;
        let v = if it.memory.last.is_some() { it.memory.velocity } else { it.v0 };
        let guess = predict(&it.method.rule, h, &it.memory, &v);
        let times = (t0, h, t1);
        let solved = solve_step(&it.system, &it.method.rule, &it.newton, times, (&q0, &p0), guess, &mut it.memory.work);
        match solved {
            Ok(solved) => {
                commit(it, h, t1, &solved);
                Ok(())
            }
            Err(error) => {
                it.stats.failed_steps += 1;
                Err(error.at(it.state))
            }
        }
    }

    fn energy_step<Sys: Lagrangian<N>, const N: usize>(
        it: &mut Integrator<Sys, Self, N>,
        bounds: StepBounds,
    ) -> Result<(), Error> {
        it.constrained_node_energy_step(bounds)
    }

    fn reread_energy<Sys: Lagrangian<N>, const N: usize>(it: &mut Integrator<Sys, Self, N>) {
        it.reread_constrained_node_energy();
    }

    fn last_step_size<const N: usize>(memory: &ConstrainedGalerkinMemory<N, S, M>) -> Option<f64> {
        memory.last.map(|last| last.h)
    }

    fn discrete_energy<Sys: Lagrangian<N>, const N: usize>(it: &Integrator<Sys, Self, N>) -> f64 {
        // The constraint forces do no work: the energy of the action.
        match &it.memory.last {
            Some(seg) => step_energy(&it.system, &it.method.rule, seg),
            None => it.energy,
        }
    }
}

impl<const S: usize, const R: usize, const M: usize> F64Readouts for Constrained<Galerkin<S, R>, M> {
    fn velocity_guess<Sys: Lagrangian<N>, const N: usize>(it: &Integrator<Sys, Self, N>) -> [f64; N] {
        if it.memory.last.is_some() { it.memory.velocity } else { it.v0 }
    }

    /// Not offered yet: the tangent map of a constrained step lives on the
    /// constraint manifold's cotangent bundle.
    fn tangent_map<Sys: Lagrangian<N>, const N: usize>(_: &Integrator<Sys, Self, N>) -> Option<TangentMap<N>> {
        None
    }

    /// `Σ_m F^m·ξ(Q_m)` over the nodes of the last step, as without
    /// constraints: the constraint forces `G(Q_m)ᵀΛ_m` have no component
    /// along a symmetry that the constraints respect (`G ξ = 0`).
    fn forcing_impulse<Sys: Lagrangian<N>, const N: usize>(
        it: &Integrator<Sys, Self, N>,
        symmetry: &(impl crate::noether::Generator<N> + ?Sized),
    ) -> Option<f64> {
        let last = it.memory.last.as_ref()?;
        Some(it.method.rule.forcing_impulse(&it.system, (last.t0, last.h), (&last.q0, &[0.0; N]), &last.d, symmetry))
    }

    type Native<const N: usize> = Hermite<N>;

    fn native<Sys: Lagrangian<N>, const N: usize>(
        _: &Integrator<Sys, Self, N>,
        start: &Node<N>,
        end: &Node<N>,
    ) -> Hermite<N> {
        Hermite::cubic(start, end)
    }
}

impl<Sys: Lagrangian<N>, const N: usize, const S: usize, const R: usize, const M: usize>
    Integrator<Sys, Constrained<Galerkin<S, R>, M>, N>
{
    /// The constraint values `g(t_k, q_k)` at the current node.
    pub fn constraint_values(&self) -> [f64; M] {
        values::<Sys, N, M>(&self.system, self.state.t, &self.state.q)
    }

    /// The hidden constraint `G(t_k, q_k) v_k + ∂g/∂t(t_k, q_k)` at the
    /// current node (`G v` for constraints that do not depend on time), with
    /// `v_k` the velocity of the momentum `p_k`.
    pub fn constraint_velocities(&self) -> Result<[f64; M], Error> {
        hidden_constraint(&self.system, &self.state, self.velocity()?)
    }

    /// The multiplier `λ_k` of the last step (zero before the first): with
    /// `G(q_k)ᵀλ_k` it is the constraint impulse on the step's start node.
    pub fn multipliers(&self) -> [f64; M] {
        self.memory.lambda
    }
}
