//! The dense linear algebra of a constrained step: the block elimination of
//! the saddle-point system and the condition estimates that tell a
//! singular step block from a rank-deficient constraint Jacobian.

use nalgebra::{SMatrix, SVector};

/// Which block of a saddle-point system is singular, with the reciprocal
/// condition number (1-norm) that gave it away.
#[derive(Clone, Copy, Debug)]
pub(super) enum Singular {
    /// The upper-left block `A` (the step Jacobian or `∂²L/∂v²`).
    Block(f64),
    /// The Schur complement `C A⁻¹ B`: the constraint Jacobians have lower
    /// rank than the number of constraints.
    Schur(f64),
}

/// The 1-norm of a matrix: its largest column sum.
pub(super) fn norm1<const R: usize, const C: usize>(m: &SMatrix<f64, R, C>) -> f64 {
    m.column_iter().map(|c| c.iter().map(|x| x.abs()).sum::<f64>()).fold(0.0, f64::max)
}

/// The inverse of `m` and its reciprocal condition number in the 1-norm,
/// `1 / (‖m‖₁ ‖m⁻¹‖₁)`; the rcond is 0 (and the inverse zero) where `m` is
/// exactly singular or not finite.
pub(super) fn inverse<const R: usize>(m: SMatrix<f64, R, R>) -> (SMatrix<f64, R, R>, f64) {
    match m.try_inverse() {
        Some(inv) if inv.iter().all(|x| x.is_finite()) => {
            let rcond = 1.0 / (norm1(&m) * norm1(&inv));
            (inv, if rcond.is_finite() { rcond } else { 0.0 })
        }
        _ => (SMatrix::zeros(), 0.0),
    }
}

/// Solves the saddle-point system `A x + B y = −r₁`, `C x = −r₂` by block
/// elimination: `(C A⁻¹ B) y = r₂ − C A⁻¹ r₁`, then `x = −A⁻¹ (r₁ + B y)`.
/// Either block with a reciprocal condition number below `min_rcond` is
/// reported instead of inverted, and so is a Schur complement that is not
/// negative definite (see below).
pub(super) fn solve_schur<const N: usize, const M: usize>(
    a: &SMatrix<f64, N, N>,
    b: &SMatrix<f64, N, M>,
    c: &SMatrix<f64, M, N>,
    r1: &SVector<f64, N>,
    r2: &SVector<f64, M>,
    min_rcond: f64,
) -> Result<(SVector<f64, N>, SVector<f64, M>), Singular> {
    let (a_inv, rcond) = inverse(*a);
    if rcond <= min_rcond {
        return Err(Singular::Block(rcond));
    }
    solve_schur_inverted(&a_inv, b, c, r1, r2, min_rcond)
}

/// [`solve_schur`] with `A⁻¹` given (the inverse of an earlier iterate's or
/// step's block, for a simplified iteration): the Schur complement with the
/// constraint Jacobians `B`, `C` of this iterate is formed and checked anew.
pub(super) fn solve_schur_inverted<const N: usize, const M: usize>(
    a_inv: &SMatrix<f64, N, N>,
    b: &SMatrix<f64, N, M>,
    c: &SMatrix<f64, M, N>,
    r1: &SVector<f64, N>,
    r2: &SVector<f64, M>,
    min_rcond: f64,
) -> Result<(SVector<f64, N>, SVector<f64, M>), Singular> {
    let a_inv_b = a_inv * b;
    let a_inv_r1 = a_inv * r1;
    let (s_inv, rcond) = inverse(c * a_inv_b);
    // A rank-deficient constraint Jacobian makes the Schur complement
    // singular up to round-off: a relative threshold far above `min_rcond`
    // (which guards Newton blocks) catches it before the multipliers blow up.
    if rcond <= SCHUR_MIN_RCOND.max(min_rcond) {
        return Err(Singular::Schur(rcond));
    }
    // For a regular Lagrangian and a small step both complements are
    // negative definite (`A ≈ −M/h`, `B = −Cᵀ`, or `A = ∂²L/∂v²`):
    // `C A⁻¹ B ≈ −h G M⁻¹ Gᵀ`. A complement that is not means the constraint
    // normals at the two ends of the step disagree: the step crosses a
    // singular configuration (a dead point) or jumps to another branch.
    let schur = c * a_inv_b;
    if (-(schur + schur.transpose()) * 0.5).cholesky().is_none() {
        return Err(Singular::Schur(rcond));
    }
    let y = s_inv * (r2 - c * a_inv_r1);
    let x = -(a_inv_r1 + a_inv_b * y);
    Ok((x, y))
}

/// The smallest reciprocal condition number of the Schur complement that a
/// step accepts: below it the constraint Jacobian is taken as rank-deficient.
pub(super) const SCHUR_MIN_RCOND: f64 = 1e-10;
