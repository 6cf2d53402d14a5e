//! Gauss Galerkin steps as collocation: the step equations solved by a
//! fixed-point iteration on the velocities at the points, without a Jacobian.
//!
//! With degree `s` and `s` Gauss–Legendre points the Galerkin step is the
//! `s`-stage Gauss collocation method of the Hamiltonian system in `(q, p)`
//! (Marsden & West, *Acta Numerica* 2001, §2.6; Hairer, Lubich & Wanner,
//! *Geometric Numerical Integration*, §VI.6.3). With `a_ij = ∫_0^{c_i} L_j`
//! and the stage velocities `V_i` as unknowns:
//!
//! ```text
//! Q_i = q_k + h Σ_j a_ij V_j
//! G_j = ∂L/∂q(t_j, Q_j, V_j) + F(t_j, Q_j, V_j)        (F = Q − ∂R/∂v, the generalised force)
//! P_i = p_k + h Σ_j a_ij G_j
//! V ← V + K⁻¹ (P − ∂L/∂v(t, Q, V)),   K_il = δ_il M_i + h a_il (X_i − Y_l − Φ_l) at the first guess
//! ```
//!
//! with `M = ∂²L/∂v²`, `X = ∂(∂L/∂v)/∂q`, `Y = Xᵀ`, `Φ = ∂F/∂v`: `−K` is the
//! Jacobian of the stage residuals to first order in `h` (see
//! [`coupled_columns`]).
//!
//! A fixed point solves the Galerkin equations of `stepper.rs`: testing them
//! with the degree-`s` polynomial `φ = ∫_0^τ L_i` (so `φ(c_j) = a_ji`,
//! `φ(1) = b_i`) and using `b_j a_ji + b_i a_ij = b_i b_j` (Gauss) gives
//! `∂L/∂v(Q_i, V_i) = P_i`, and the node increments of the step polynomial
//! are `D_m = h Σ_j (∫_0^{τ_m} L_j) V_j`. The converged step is therefore the
//! step Newton finds, to round-off (`tests/behaviour/galerkin_collocation.rs`).
//!
//! This is the iteration of Antoñana, Makazaga & Murua's IRKGL16 (*J. Comput.
//! Phys.* 2017), with the momentum equation solved in `v` by a Newton step
//! whose matrix keeps the terms of first order in `h`. With `M_i` alone
//! (block-diagonal `K`) it contracts like `h`, through the gyroscopic
//! (Coriolis) coupling `∂²L/∂q∂v` of a configuration-dependent mass matrix
//! and through the damping; with `K` it contracts like `h²`, through
//! `∂G/∂q` only. The `K` a forced or damped system starts with also takes
//! the terms of second order, `− h² Σ_j a_ij a_jl W_j` with `W = ∂G/∂q`
//! ([`second_order_terms`]), so that it contracts with the change of the
//! stage Jacobian along the step (a stiff spring that the step resolves
//! coarsely does not slow it). Each iteration costs one gradient of `L`
//! (and the force) per point and one solve with `M_i⁻¹` or with the
//! factors of `K`; both come from one Hessian in `v` per point at the first
//! guess (the mixed block from the same evaluation; `K` also takes `N`
//! derivatives of the force in `v`, and where forced or damped `∂²L/∂q²` by
//! one more sweep and `N` derivatives of the force in `q`), `K` with a
//! block elimination of `sN × sN` per step. Which one is chosen from the
//! observed contraction: a step starts with `M_i`, and switches to `K` for
//! its remaining rounds when a round gains less than
//! [`SLOWEST_CONTRACTION`]; the steps after a switch start with `K` for a
//! while (`stepper.rs`). Systems with forces or dissipation start with `K`
//! (the damping alone slows the block-diagonal iteration). A system whose
//! mass matrix is proven constant has no coupling in `L` and keeps `M⁻¹`
//! for the run instead. Where even `K` contracts slowly (a stiff step) or
//! the iteration diverges, the stepper falls back to Newton.
//!
//! Stopping: the iteration runs until its correction is at round-off (a few
//! ulps of the largest velocity), or the next one would be far below it by
//! the observed contraction, or it stops decreasing near round-off (IRKGL16's
//! criterion), so the step it returns is converged as far as `f64` allows,
//! as the Newton iteration's `rtol = 1e-14` is.
//!
//! Round-off: over long runs an error of the same sign in every step drifts
//! the energy linearly and the phase quadratically, where rounding errors of
//! random sign only random-walk (Brouwer's law). Three things keep the
//! step's errors of the second kind (Antoñana, Makazaga & Murua, *Numer.
//! Algorithms* 2017). The coefficients the step computes with satisfy the
//! symplecticity condition exactly: `h b_j` is rounded once and
//! `a_ij = μ_ij (h b_j)` with `μ_ij + μ_ji = 1` exact
//! (`Galerkin::stage_ratio`), the increments `h b_j V_j` and `h b_j G_j`
//! are rounded once and shared by the stages and the update, and the update
//! is `Σ_j` of them (Kahan-summed into the state, `stepper.rs`). The update
//! takes `G_j` at the stage values of the velocities it returns (one sweep
//! of gradients after the last round), not the last round's, evaluated
//! before its correction. And Newton's steps in the automatic iteration are
//! finished by this iteration from Newton's root. Measured on Kepler
//! `e = 0.5` in polar coordinates over 1000 orbits (s = 6, the report's
//! step counts from 48 000 to 543 058): phase errors between 2.6e-10 and
//! 4.0e-8 (1e-10 met at no three counts in a row) before, between 2.7e-12
//! and 2.9e-10 from 57 082 steps on after (3.7e-9 at 48 000 is the
//! truncation error), with the energy at a few ulps.

use crate::real::{Real, all_finite, gauss_jordan_into, max_abs};
use crate::system::{Lagrangian, generalized_force};

use super::forces::{force_position_jacobian, force_velocity_jacobian};
use super::linalg::{BlockMatrix, BlockVector};
use super::method::{
    Galerkin, gradient_at, position_hessian, value_gradient_at, velocity_derivatives, velocity_hessian,
};

/// Most iterations a step may take before Newton takes over.
const MAX_ITERATIONS: usize = 20;

/// A round contracts too slowly where it reduces the correction by less
/// than this: the block-diagonal iteration then switches to the coupled
/// matrix `K` for the rest of the step, and one with `K` gives the step to
/// Newton. Measured with callgrind (`bench/examples/galerkin_steps.rs` at
/// the report's settings): on the double pendulum (s = 4, 673 steps) no
/// round is that slow, and the block-diagonal iteration takes its 5.68
/// rounds per step throughout; on Kepler in polar coordinates (s = 6,
/// 48 000 steps over 1000 orbits), where the block-diagonal iteration gave
/// 1.75 Hessians per step to Newton, switching instead leaves 0.25 and
/// takes 690.0M → 546.5M instructions.
pub(super) const SLOWEST_CONTRACTION: f64 = 0.1;

/// A correction (relative to the largest stage velocity) at round-off.
const ROUND_OFF: f64 = 4.0 * f64::EPSILON;

/// The error a linearly contracting iteration leaves when it stops is on the
/// same side step after step, so the estimate of that error (the next
/// correction at the observed contraction) is held to a hundredth of
/// [`ROUND_OFF`]: at `ROUND_OFF` itself the bias, through the energy, became
/// a phase drift that lowered the fitted order of s = 6 over 1e5 radians of
/// the pendulum from 11.91 (Newton) to 11.82.
const LEFT_OVER: f64 = ROUND_OFF / 100.0;

/// A correction at most this large that no longer decreases has reached the
/// round-off of the iteration (IRKGL16's stopping rule).
const STALLED: f64 = 1024.0 * f64::EPSILON;

/// A converged fixed-point solve.
pub(super) struct Converged<const N: usize, const S: usize, const R: usize, T> {
    /// The node increments of the step polynomial.
    pub(super) d: BlockVector<N, S, T>,
    /// `G_j = ∂L/∂q + F` at the stage values of the returned velocities,
    /// for the momentum update `p_k + Σ_j (h b_j) G_j`.
    pub(super) point_forces: [[T; N]; R],
    /// Whether `L` is finite at every point.
    pub(super) lagrangian_finite: bool,
    /// The last rounds solved with the coupled matrix `K`.
    pub(super) coupled: bool,
    /// Iterations (gradients of `L` at every point each).
    pub(super) iterations: usize,
    /// `max |P_i − ∂L/∂v|` at the last iterate before its correction.
    pub(super) residual_norm: f64,
    /// The last correction relative to the largest stage velocity.
    pub(super) correction_norm: f64,
}

/// Why a fixed-point solve stopped without converging.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Failed {
    /// Iterations spent.
    pub(super) iterations: usize,
    /// What went wrong: a slow or diverging iteration, a non-finite value, a
    /// singular `∂²L/∂v²`.
    pub(super) reason: &'static str,
    /// The last rounds solved with the coupled matrix `K`.
    pub(super) coupled: bool,
}

/// Solves the step of size `h` from `(t0, q0 + e, p0 + pc)` by the fixed-point
/// iteration on the stage velocities, starting from the node increments
/// `guess`; fails where an iteration (away from round-off) reduces the
/// correction by less than the factor `slowest`. `mass_inverse`, the `N`
/// rows of `M⁻¹` of a system whose mass matrix is proven constant, replaces
/// the Hessian in `v` at every point (see [`constant_mass_inverse`]).
/// `coupled`, storage for the `sN × sN` iteration matrix `K` with the
/// first-order coupling (see [`coupled_columns`]): where given (and `R = S`,
/// no `mass_inverse`), the iteration solves with `K` from the first round
/// if `start_coupled`, and otherwise with the block-diagonal `M_i` until a
/// round contracts by less than `slowest`, then with `K` (formed from the
/// first round's derivatives, no evaluation more) for the rest of the step.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(super) fn solve<Sys, T, const N: usize, const S: usize, const R: usize>(
    system: &Sys,
    g: &Galerkin<S, R, T>,
    t0: T,
    h: T,
    (q0, e): (&[T; N], &[T; N]),
    (p0, pc): (&[T; N], &[T; N]),
    guess: &BlockVector<N, S, T>,
    slowest: f64,
    mass_inverse: Option<&[[T; N]]>,
    coupled: Option<&mut BlockMatrix<N, S, T>>,
    start_coupled: bool,
) -> Result<Converged<N, S, R, T>, Failed>
where
    Sys: Lagrangian<N> + ?Sized,
    T: Real,
{
    let zero = T::zero();
    let forced = Sys::HAS_FORCE || Sys::HAS_DISSIPATION;
    let mut coupled = coupled.filter(|_| R == S && mass_inverse.is_none());
    // Whether the rounds solve with the factors of `K` (else with `M_i⁻¹`).
    let mut with_k = start_coupled && coupled.is_some();
    let fail = |iterations, reason, with_k| Err(Failed { iterations, reason, coupled: with_k });
    // `h b_j` rounded once; the stages take `a_ij = μ_ij (h b_j)` and the
    // update `b_j = h b_j`, for the positions and the momenta alike (see
    // `Galerkin::stage_ratio`). `h a_ij` as one number only for `K`.
    let hb: [T; R] = core::array::from_fn(|j| g.quadrature().weights()[j] * h);
    let mu = &g.stage_ratio;
    let ha: [[T; R]; R] = core::array::from_fn(|i| core::array::from_fn(|j| mu[i][j] * hb[j]));
    // The guess's velocities at the points, the inverse of ∂²L/∂v² there
    // and the derivatives `K` is formed from, and the first iteration's
    // gradients from the same evaluation.
    let mut v = [[zero; N]; R];
    let mut m_inv = [[[zero; N]; N]; R];
    let mut vv = [[[zero; N]; N]; R];
    let mut qv = [[[zero; N]; N]; R];
    let mut fv = [[[zero; N]; N]; R];
    // W = ∂G/∂q = ∂²L/∂q² + ∂F/∂q at the points, for the second-order term
    // of the `K` a forced or damped system starts with (one more sweep per
    // point). A `K` formed at a switch takes no evaluation more, and goes
    // without; so does the `K` a conservative system starts with after a
    // switch: on Kepler in polar coordinates (s = 6, 48 000 steps) the term
    // took 6.42 → 5.90 rounds per step but 544.3M → 556.3M instructions.
    let mut gq = [[[zero; N]; N]; R];
    let second_order = with_k && forced;
    let mut force = [[zero; N]; R];
    let mut lv = [[zero; N]; R];
    for j in 0..R {
        let (t, q, vj) = g.point(t0, h, (q0, e), guess, j);
        let (lq, lvj) = if mass_inverse.is_some() {
            gradient_at(system, t, q, vj)
        } else {
            let d = velocity_hessian(system, t, q, vj);
            if coupled.is_some() {
                (vv[j], qv[j]) = (d.vv, d.qv);
                if forced {
                    fv[j] = force_velocity_jacobian(system, t, q, vj);
                }
                if second_order {
                    gq[j] = position_hessian(system, t, q, vj);
                    if forced {
                        let fq = force_position_jacobian(system, t, q, vj);
                        for r in 0..N {
                            for c in 0..N {
                                gq[j][r][c] += fq[r][c];
                            }
                        }
                    }
                }
            }
            // The block-diagonal matrix, for rounds before any switch.
            if !with_k {
                match invert(d.vv) {
                    Some(inv) => m_inv[j] = inv,
                    None => return fail(1, "∂²L/∂v² singular or not finite at a point of the first guess", with_k),
                }
            }
            (d.q, d.v)
        };
        (v[j], force[j], lv[j]) = (vj, lq, lvj);
        if forced {
            let f = generalized_force(system, t, q, vj);
            for i in 0..N {
                force[j][i] += f[i];
            }
        }
    }
    // `K` from the first round's derivatives, factored in the storage.
    let form_k = |k: &mut BlockMatrix<N, S, T>| {
        k.fill_zero();
        let rows = k.rows_mut();
        for l in 0..R {
            coupled_columns::<N, S, R, T>(rows, &ha, l, &vv[l], &qv[l], &fv[l]);
        }
        if second_order {
            second_order_terms::<N, S, R, T>(rows, &ha, &gq);
        }
        factor_blocks::<N, S, R, T>(rows)
    };
    if with_k
        && let Some(k) = coupled.as_deref_mut()
        && !form_k(k)
    {
        return fail(1, "the coupled iteration matrix is singular or not finite at the first guess", with_k);
    }
    // The times of the points, once per step, in locals: so that the
    // compiler keeps the time factor of `L` at them (a `sin(ωt)`) fixed
    // across the rounds. Read through `g` inside the rounds, next to the
    // switch to `K` (whose clearing may allocate), they were not, and every
    // round computed the factor again (the perturbed pendulum, s = 6: 1.6
    // times the calls of `sin`, under callgrind).
    let times: [T; R] = {
        let nodes = g.quadrature().nodes();
        core::array::from_fn(|j| t0 + nodes[j] * h)
    };
    let mut last = f64::INFINITY;
    for iteration in 1..=MAX_ITERATIONS {
        if iteration > 1 {
            // The position increments `h b_l V_l`, rounded once for all stages.
            let dq: [[T; N]; R] = core::array::from_fn(|l| v[l].map(|x| x * hb[l]));
            for j in 0..R {
                let q = stage_position(q0, e, &mu[j], &dq);
                let t = times[j];
                let (lq, lvj) = gradient_at(system, t, q, v[j]);
                (force[j], lv[j]) = (lq, lvj);
                if forced {
                    let f = generalized_force(system, t, q, v[j]);
                    for i in 0..N {
                        force[j][i] += f[i];
                    }
                }
            }
        }
        // P_i − ∂L/∂v = (p_k − ∂L/∂v) + (compensation + Σ_j μ_ij (h b_j G_j)),
        // the momentum increments `h b_j G_j` rounded once, as the update
        // rounds them (`stepper.rs`).
        let dp: [[T; N]; R] = core::array::from_fn(|l| force[l].map(|x| x * hb[l]));
        let mut residual = [[zero; N]; R];
        let mut residual_norm = 0.0f64;
        for (i, r) in residual.iter_mut().enumerate() {
            *r = core::array::from_fn(|c| {
                let mut x = pc[c];
                for (m, dl) in mu[i].iter().zip(&dp) {
                    x += *m * dl[c];
                }
                (p0[c] - lv[i][c]) + x
            });
            residual_norm = residual_norm.max(max_abs(r));
        }
        let correction: [[T; N]; R] = match coupled.as_deref() {
            // (`coupled` only where R = S.)
            Some(k) if with_k => solve_blocks::<N, S, R, T>(k.rows(), &residual),
            _ => core::array::from_fn(|i| {
                let m: &[[T; N]] = mass_inverse.unwrap_or(&m_inv[i]);
                core::array::from_fn(|c| {
                    let mut x = zero;
                    for (&a, &b) in m[c].iter().zip(&residual[i]) {
                        x += a * b;
                    }
                    x
                })
            }),
        };
        let size = max_abs(correction.as_flattened());
        for (vi, di) in v.iter_mut().zip(&correction) {
            for (x, d) in vi.iter_mut().zip(di) {
                *x += *d;
            }
        }
        if !all_finite(v.as_flattened()) {
            return fail(iteration, "non-finite stage velocities in the fixed-point iteration", with_k);
        }
        let scale = max_abs(v.as_flattened());
        let ratio = if size == 0.0 { 0.0 } else { size / scale };
        // Converged: a correction at round-off; one whose successor, at the
        // observed contraction `ratio / last`, would be (the iteration
        // contracts linearly, so the error left is about that successor);
        // or one near round-off that no longer decreases.
        let next = if iteration > 1 { ratio * ratio / last } else { f64::INFINITY };
        if ratio <= ROUND_OFF || next <= LEFT_OVER || (ratio >= last && ratio <= STALLED) {
            let Finished { d, point_forces, lagrangian_finite } = finish(system, g, &times, h, (q0, e), &v);
            return Ok(Converged {
                d,
                point_forces,
                lagrangian_finite,
                coupled: with_k,
                iterations: iteration,
                residual_norm,
                correction_norm: ratio,
            });
        }
        if iteration >= 2 && ratio > STALLED {
            match coupled.as_deref_mut() {
                // The block-diagonal iteration is slow (the coupling through
                // `∂²L/∂q∂v` is strong at this step): the rest of the step
                // solves with `K`, whose rounds gain about `h` more each.
                Some(k) if !with_k && ratio > SLOWEST_CONTRACTION * last => {
                    with_k = true;
                    if !form_k(k) {
                        return fail(iteration, "the coupled iteration matrix is singular or not finite", with_k);
                    }
                }
                _ if ratio > slowest * last => {
                    return fail(iteration, "the fixed-point iteration contracts too slowly", with_k);
                }
                _ => {}
            }
        }
        last = ratio;
    }
    fail(MAX_ITERATIONS, "the fixed-point iteration did not converge", with_k)
}

/// Column block `l` of the coupled iteration matrix, from the derivatives at
/// point `l` of the first guess (`vv = ∂²L/∂v²`, `qv = ∂²L/∂q∂v` and
/// `fv = ∂F/∂v` of the generalised force), into the flattened rows of `K`
/// (block `(i, l)` in rows `iN … iN + N − 1`, column block `l`).
///
/// The residual of stage `i` is `r_i = p_k + h Σ_j a_ij G_j − ∂L/∂v(Q_i, V_i)`
/// with `Q_i = q_k + h Σ_j a_ij V_j`. Its derivative in `V_l`, to first order
/// in `h`, is `−K_il` with
///
/// ```text
/// K_il = δ_il M_i + h a_il (X_i − Y_l − Φ_l),
/// M = ∂²L/∂v²,  X = ∂(∂L/∂v)/∂q = Yᵀ,  Y = ∂(∂L/∂q)/∂v,  Φ = ∂F/∂v,
/// ```
///
/// and the iteration `V ← V + K⁻¹ r` at the first guess leaves the `O(h²)`
/// terms (through `∂G/∂q`) and the change of `K` along the iteration. With
/// `M_i` alone (the block-diagonal iteration) it contracts like `h`: the
/// part of `X − Y` that is the same at every point is antisymmetric, the
/// gyroscopic (Coriolis) coupling `vᵀ ∂M/∂q` of a configuration-dependent
/// mass matrix, and `Φ` is the damping. With `K` it contracts like `h²`.
#[inline(always)]
fn coupled_columns<const N: usize, const S: usize, const R: usize, T: Real>(
    rows: &mut [[[T; N]; S]],
    ha: &[[T; R]; R],
    l: usize,
    vv: &[[T; N]; N],
    qv: &[[T; N]; N],
    fv: &[[T; N]; N],
) {
    // Point l's terms are added (the matrix starts at zero): the column
    // block `l` takes δ_il M_l − h a_il (Y_l + Φ_l), the row block `l` takes
    // h a_ln X_l. Rows are taken once each from the flattened storage
    // (indexing block by block through it cost more than the arithmetic).
    for i in 0..R {
        let a = ha[i][l];
        for (r, row) in rows[i * N..(i + 1) * N].iter_mut().enumerate() {
            let entries = &mut row[l];
            for c in 0..N {
                let diagonal = if i == l { vv[r][c] } else { T::zero() };
                entries[c] += diagonal - a * (qv[r][c] + fv[r][c]);
            }
        }
    }
    for (r, row) in rows[l * N..(l + 1) * N].iter_mut().enumerate() {
        for n in 0..R {
            let a = ha[l][n];
            for c in 0..N {
                row[n][c] += a * qv[c][r];
            }
        }
    }
}

/// Adds the terms of second order in `h` to the coupled iteration matrix
/// (its flattened rows, after [`coupled_columns`]): `− h² Σ_j a_ij a_jl W_j`
/// to block `(i, l)`, with `W_j = ∂G/∂q = ∂²L/∂q² + ∂F/∂q` at point `j` of
/// the first guess. With them `K` is the whole Jacobian of the stage
/// residuals in `V` at the first guess, and the iteration contracts with
/// the change of that Jacobian along the step. Without them it contracts
/// like `h² |a|² |W|`, which is not small where the step resolves a stiff
/// spring coarsely: on the report's sensor (`ω = 20`, `h = 0.059`,
/// `ωh = 1.18`) each round gained only 0.02 to 0.05, and a step took 9 to
/// 10 rounds (`s = 5`, 34 steps; with them 5).
#[inline(always)]
fn second_order_terms<const N: usize, const S: usize, const R: usize, T: Real>(
    rows: &mut [[[T; N]; S]],
    ha: &[[T; R]; R],
    w: &[[[T; N]; N]; R],
) {
    for i in 0..R {
        for l in 0..R {
            for (j, wj) in w.iter().enumerate() {
                let a = ha[i][j] * ha[j][l];
                for (r, wr) in wj.iter().enumerate() {
                    let entries = &mut rows[i * N + r][l];
                    for c in 0..N {
                        entries[c] -= a * wr[c];
                    }
                }
            }
        }
    }
}

/// Factors the coupled matrix (its `sN` flattened rows) in place by block
/// elimination without pivoting (`R = S` blocks of `N × N`): the diagonal
/// blocks are replaced by the inverses of the pivot blocks, the blocks below
/// by the multipliers `L_ip`, those above by `U_pj`. `K` is `∂²L/∂v²` per
/// point plus terms of order `h`, so its pivot blocks are those mass
/// matrices perturbed; where one is singular the factorisation fails
/// (`false`) and so does the iteration, for Newton to take over. Measured
/// with callgrind on the report's double pendulum (s = 4, 673 steps): the
/// partially pivoted LU of the Newton block (`linalg::Lu`) on this `8 × 8`
/// matrix took 2.7k instructions per step, more than the two rounds the
/// coupling saves.
#[inline(always)]
fn factor_blocks<const N: usize, const S: usize, const R: usize, T: Real>(rows: &mut [[[T; N]; S]]) -> bool {
    for p in 0..R {
        // The pivot rows (block row `p`) and the rows below them.
        let (head, tail) = rows.split_at_mut((p + 1) * N);
        let pivot_rows = &mut head[p * N..];
        let mut pivot: [[T; N]; N] = core::array::from_fn(|r| pivot_rows[r][p]);
        let mut inverse = [[T::zero(); N]; N];
        if !gauss_jordan_into(&mut pivot, &mut inverse, 0.0) {
            return false;
        }
        for (row, inv) in pivot_rows.iter_mut().zip(&inverse) {
            row[p] = *inv;
        }
        let pivot_rows = &*pivot_rows;
        for below in tail.chunks_exact_mut(N).take(R - p - 1) {
            let l: [[T; N]; N] = core::array::from_fn(|r| {
                core::array::from_fn(|c| {
                    let mut x = T::zero();
                    for m in 0..N {
                        x += below[r][p][m] * inverse[m][c];
                    }
                    x
                })
            });
            for (row, lr) in below.iter_mut().zip(&l) {
                row[p] = *lr;
                for j in p + 1..R {
                    for c in 0..N {
                        let mut x = row[j][c];
                        for m in 0..N {
                            x -= lr[m] * pivot_rows[m][j][c];
                        }
                        row[j][c] = x;
                    }
                }
            }
        }
    }
    true
}

/// `x` with `K x = b` from the factors [`factor_blocks`] left in the
/// flattened rows of `K`.
#[inline(always)]
fn solve_blocks<const N: usize, const S: usize, const R: usize, T: Real>(
    rows: &[[[T; N]; S]],
    b: &[[T; N]; R],
) -> [[T; N]; R] {
    let mut y = *b;
    for i in 1..R {
        for r in 0..N {
            let row = &rows[i * N + r];
            let mut x = y[i][r];
            for p in 0..i {
                for m in 0..N {
                    x -= row[p][m] * y[p][m];
                }
            }
            y[i][r] = x;
        }
    }
    let mut out = [[T::zero(); N]; R];
    for i in (0..R).rev() {
        let block_rows = &rows[i * N..(i + 1) * N];
        let mut z = y[i];
        for (zr, row) in z.iter_mut().zip(block_rows) {
            for j in i + 1..R {
                for m in 0..N {
                    *zr -= row[j][m] * out[j][m];
                }
            }
        }
        for (o, row) in out[i].iter_mut().zip(block_rows) {
            let mut x = T::zero();
            for m in 0..N {
                x += row[i][m] * z[m];
            }
            *o = x;
        }
    }
    out
}

/// A step finished from its stage velocities ([`finish`]).
pub(super) struct Finished<const N: usize, const S: usize, const R: usize, T> {
    /// The node increments of the step polynomial, the last one the update
    /// `Σ_j h b_j V_j`.
    pub(super) d: BlockVector<N, S, T>,
    /// `G_j = ∂L/∂q + F` at the stage values, for the momentum update
    /// `Σ_j h b_j G_j`.
    pub(super) point_forces: [[T; N]; R],
    /// Whether `L` is finite at every point.
    pub(super) lagrangian_finite: bool,
}

/// The step with stage velocities `v` at the points (times `times`) from
/// `q0 + e`: the node increments, the end one `Σ_j h b_j V_j`, and `G_j` at
/// the stage values `q_k + Σ_l μ_jl (h b_l V_l)` of the same rounded
/// coefficients, so that the update is the symplectic map of its
/// coefficients to the rounding of its arithmetic (see the module doc): the
/// gradients of the iteration's last round, evaluated before its
/// correction, are off by that correction, which points the same way step
/// after step (the first guess misses the same way), and stage values
/// rounded through the node increments (other tables) are off by a pattern
/// that repeats along an orbit. Either bias drifts the energy. `L` itself
/// comes with the gradients, for the update's check.
#[inline(always)]
pub(super) fn finish<Sys, T, const N: usize, const S: usize, const R: usize>(
    system: &Sys,
    g: &Galerkin<S, R, T>,
    times: &[T; R],
    h: T,
    (q0, e): (&[T; N], &[T; N]),
    v: &[[T; N]; R],
) -> Finished<N, S, R, T>
where
    Sys: Lagrangian<N> + ?Sized,
    T: Real,
{
    let hb: [T; R] = core::array::from_fn(|j| g.quadrature().weights()[j] * h);
    let dq: [[T; N]; R] = core::array::from_fn(|l| v[l].map(|x| x * hb[l]));
    let mut d = nodes_from(g, h, v);
    d[S - 1] = core::array::from_fn(|i| {
        let mut x = T::zero();
        for dl in &dq {
            x += dl[i];
        }
        x
    });
    let mut point_forces = [[T::zero(); N]; R];
    let mut lagrangian_finite = true;
    for j in 0..R {
        let q = stage_position(q0, e, &g.stage_ratio[j], &dq);
        let (l, lq, _) = value_gradient_at(system, times[j], q, v[j]);
        lagrangian_finite &= l.is_finite();
        point_forces[j] = lq;
        if Sys::HAS_FORCE || Sys::HAS_DISSIPATION {
            let f = generalized_force(system, times[j], q, v[j]);
            for i in 0..N {
                point_forces[j][i] += f[i];
            }
        }
    }
    Finished { d, point_forces, lagrangian_finite }
}

/// `Q_j = q_k + (e + Σ_l μ_jl (h b_l V_l))` from the increments `dq_l = h b_l V_l`
/// (`e`: the compensation of the Kahan-summed `q_k`).
#[inline(always)]
fn stage_position<const N: usize, const R: usize, T: Real>(
    q0: &[T; N],
    e: &[T; N],
    mu: &[T; R],
    dq: &[[T; N]; R],
) -> [T; N] {
    core::array::from_fn(|i| {
        let mut x = e[i];
        for (m, dl) in mu.iter().zip(dq) {
            x += *m * dl[i];
        }
        q0[i] + x
    })
}

/// The node increments `D_m = h Σ_j (∫_0^{τ_m} L_j) V_j` of the polynomial
/// with velocities `v` at the points.
#[inline(always)]
fn nodes_from<const N: usize, const S: usize, const R: usize, T: Real>(
    g: &Galerkin<S, R, T>,
    h: T,
    v: &[[T; N]; R],
) -> BlockVector<N, S, T> {
    let mut d = [[T::zero(); N]; S];
    for (dm, row) in d.iter_mut().zip(&g.node_from_stages) {
        for (&a, vj) in row.iter().zip(v) {
            for (x, &y) in dm.iter_mut().zip(vj) {
                *x += a * y;
            }
        }
        for x in dm.iter_mut() {
            *x *= h;
        }
    }
    d
}

/// The `N` rows of `M⁻¹ = (∂²L/∂v²)⁻¹` of a system whose mass matrix the
/// macro proves constant ([`Separability::ConstantMass`](crate::Separability)),
/// from [`velocity_derivatives`] at one point, to be kept for the whole run: the
/// fixed-point iteration then costs no Hessian at all. Measured with
/// callgrind on the FPU-β chain of 16 masses (s = 4, 40 steps of `h = 0.3`
/// from the start): 241·10⁶ instructions with the Hessian in `v` formed and
/// inverted at every point of every step (above 8 coordinates the whole
/// Hessian in `(q, v)` is formed for it), 5.5·10⁶ with `M⁻¹` kept. `None`
/// where `M` is singular or not finite (the iteration then fails as it
/// would without it).
pub(super) fn constant_mass_inverse<Sys, T, const N: usize>(
    system: &Sys,
    t: T,
    q: [T; N],
    v: [T; N],
) -> Option<Box<[[T; N]]>>
where
    Sys: Lagrangian<N> + ?Sized,
    T: Real,
{
    let (_, _, mut a) = velocity_derivatives(system, t, q, v);
    let mut rows = vec![[T::zero(); N]; N].into_boxed_slice();
    let inverse: &mut [[T; N]; N] = (&mut *rows).try_into().ok()?;
    gauss_jordan_into(&mut a, inverse, 0.0).then_some(rows)
}

/// The inverse of `a` (exactly singular or not finite: `None`).
#[inline(always)]
fn invert<const N: usize, T: Real>(mut a: [[T; N]; N]) -> Option<[[T; N]; N]> {
    let mut inv = [[T::zero(); N]; N];
    gauss_jordan_into(&mut a, &mut inv, 0.0).then_some(inv)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inverts_with_pivoting_and_refuses_singular_matrices() {
        let a = [[0.0, 2.0, 1.0], [1.0, 1.0, 0.0], [3.0, 0.0, 4.0]];
        let inv = invert(a).unwrap();
        for i in 0..3 {
            for k in 0..3 {
                let x: f64 = (0..3).map(|l| a[i][l] * inv[l][k]).sum();
                assert!((x - if i == k { 1.0 } else { 0.0 }).abs() < 1e-15, "{i} {k} {x}");
            }
        }
        assert!(invert([[1.0, 2.0], [2.0, 4.0]]).is_none());
        assert!(invert([[f64::NAN, 0.0], [0.0, 1.0]]).is_none());
    }

    #[test]
    fn block_elimination_solves_the_coupled_system() {
        // A 6 × 6 matrix of 3 × 3 blocks of 2 × 2, mass-matrix-like blocks on
        // the diagonal and order-one blocks off it, no symmetry.
        let entry = |i: usize, r: usize, l: usize, c: usize| {
            let x = ((7 * i + 3 * r + 5 * l + 11 * c) % 13) as f64 / 13.0 - 0.5;
            if i == l { x + if r == c { 3.0 } else { 0.5 } } else { x }
        };
        let a: [[[[f64; 2]; 3]; 2]; 3] = core::array::from_fn(|i| {
            core::array::from_fn(|r| core::array::from_fn(|l| core::array::from_fn(|c| entry(i, r, l, c))))
        });
        let mut k = BlockMatrix::<2, 3>::from_blocks(a);
        assert!(factor_blocks::<2, 3, 3, f64>(k.rows_mut()));
        let b = [[1.0, -2.0], [0.5, 0.25], [-1.5, 3.0]];
        let x = solve_blocks::<2, 3, 3, f64>(k.rows(), &b);
        for i in 0..3 {
            for r in 0..2 {
                let ax: f64 =
                    (0..3).flat_map(|l| (0..2).map(move |c| (l, c))).map(|(l, c)| a[i][r][l][c] * x[l][c]).sum();
                assert!((ax - b[i][r]).abs() < 1e-14, "{i} {r}: {ax} against {}", b[i][r]);
            }
        }
        // A singular pivot block fails.
        let mut k = BlockMatrix::<2, 3>::from_blocks([[[[0.0; 2]; 3]; 2]; 3]);
        assert!(!factor_blocks::<2, 3, 3, f64>(k.rows_mut()));
    }

    #[test]
    fn gauss_tables_are_the_collocation_matrix() {
        // Two-point Gauss: a = [[1/4, 1/4 − √3/6], [1/4 + √3/6, 1/4]].
        let g = Galerkin::<2, 2>::gauss();
        let r = 3f64.sqrt() / 6.0;
        let expected = [[0.25, 0.25 - r], [0.25 + r, 0.25]];
        for i in 0..2 {
            for j in 0..2 {
                assert!((g.stage_from_stages[i][j] - expected[i][j]).abs() < 1e-15);
            }
        }
        // The last node is the end of the step: its row is the weights.
        let g = Galerkin::<5, 5>::gauss();
        for j in 0..5 {
            assert!((g.node_from_stages[4][j] - g.quadrature().weights()[j]).abs() < 1e-15);
        }
        // Gauss: b_i a_ij + b_j a_ji = b_i b_j (symplecticity).
        let b = g.quadrature().weights();
        let a = g.stage_from_stages;
        for i in 0..5 {
            for j in 0..5 {
                assert!((b[i] * a[i][j] + b[j] * a[j][i] - b[i] * b[j]).abs() < 1e-15);
            }
        }
    }

    /// `μ_ij = a_ij / b_j` with `μ_ij + μ_ji = 1` exactly in `f64`, for every
    /// degree the report runs and beyond.
    #[test]
    fn the_stage_ratios_sum_to_one_exactly() {
        fn check<const S: usize>() {
            let g = Galerkin::<S, S>::gauss();
            let (a, b, mu) = (g.stage_from_stages, g.quadrature().weights(), g.stage_ratio);
            for i in 0..S {
                for j in 0..S {
                    assert_eq!(mu[i][j] + mu[j][i], 1.0, "s = {S}: {i} {j}");
                    assert!((mu[i][j] * b[j] - a[i][j]).abs() < 4e-16, "s = {S}: {i} {j}");
                }
            }
        }
        check::<1>();
        check::<2>();
        check::<3>();
        check::<4>();
        check::<5>();
        check::<6>();
        check::<7>();
        check::<8>();
        check::<12>();
    }
}
