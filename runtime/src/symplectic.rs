//! The tangent map of a step and its symplecticity defect (docs/theory.md §8).
//!
//! Differentiating `p_k + ∂A/∂q_k = 0`, `p_{k+1} = ∂A/∂q_{k+1}` by the
//! implicit function theorem, with `A11 = ∂²A/∂q_k²`, `A12 = ∂²A/∂q_k∂q_{k+1}`
//! and `A22 = ∂²A/∂q_{k+1}²`:
//!
//! ```text
//! ∂q_{k+1}/∂q_k = −A12⁻¹ A11      ∂q_{k+1}/∂p_k = −A12⁻¹
//! ∂p_{k+1}/∂q_k = A12ᵀ + A22 ∂q_{k+1}/∂q_k      ∂p_{k+1}/∂p_k = A22 ∂q_{k+1}/∂p_k
//! ```

use nalgebra::{DMatrix, SMatrix};

use crate::derivatives::{self, Segment};
use crate::discrete::DiscreteLagrangian;
use crate::system::Lagrangian;

/// The Jacobian `M = ∂(q_{k+1}, p_{k+1})/∂(q_k, p_k)` of one step, by blocks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TangentMap<const N: usize> {
    /// `∂q_{k+1}/∂q_k`.
    pub dq_dq: SMatrix<f64, N, N>,
    /// `∂q_{k+1}/∂p_k`.
    pub dq_dp: SMatrix<f64, N, N>,
    /// `∂p_{k+1}/∂q_k`.
    pub dp_dq: SMatrix<f64, N, N>,
    /// `∂p_{k+1}/∂p_k`.
    pub dp_dp: SMatrix<f64, N, N>,
}

impl<const N: usize> TangentMap<N> {
    /// `M` as a `2N × 2N` matrix, ordered `(q, p)`.
    pub fn matrix(&self) -> DMatrix<f64> {
        let mut m = DMatrix::zeros(2 * N, 2 * N);
        m.view_mut((0, 0), (N, N)).copy_from(&self.dq_dq);
        m.view_mut((0, N), (N, N)).copy_from(&self.dq_dp);
        m.view_mut((N, 0), (N, N)).copy_from(&self.dp_dq);
        m.view_mut((N, N), (N, N)).copy_from(&self.dp_dp);
        m
    }

    /// `max |Mᵀ𝕁M − 𝕁|` with `𝕁 = [[0, I], [−I, 0]]`: zero for a symplectic map.
    pub fn symplecticity_defect(&self) -> f64 {
        defect(&self.matrix()).unwrap_or(f64::NAN)
    }
}

/// The tangent map of the step over `seg`, or `None` where `A12` is singular.
pub fn tangent_map<S, M, const N: usize>(system: &S, method: &M, seg: &Segment<N>) -> Option<TangentMap<N>>
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
{
    let (a11, a12, a22) = derivatives::position_hessian(system, method, seg);
    let inv = a12.try_inverse()?;
    let dq_dq = -inv * a11;
    let dq_dp = -inv;
    Some(TangentMap { dq_dq, dq_dp, dp_dq: a12.transpose() + a22 * dq_dq, dp_dp: a22 * dq_dp })
}

/// The tangent map of a variable step in the extended phase space,
/// `∂(x_{k+1}, π_{k+1})/∂(x_k, π_k)` with `x = (t, q)` and `π = (−E, p)`,
/// as a `(2N+2)×(2N+2)` matrix ordered `(t, q, −E, p)`; `None` where the
/// extended mixed block `∂²A/∂x_k∂x_{k+1}` is singular.
///
/// A variable step solves `π_k + ∂A/∂x_k = 0`, `π_{k+1} = ∂A/∂x_{k+1}`
/// (docs/theory.md §3), the fixed-step equations one dimension up, so the same
/// implicit-function formulas apply to the `(N+1)`-dimensional blocks, and
/// the map preserves `dq∧dp − dt∧dE` (001 (3.17), 003 §3.2).
pub fn extended_tangent_map<S, M, const N: usize>(system: &S, method: &M, seg: &Segment<N>) -> Option<DMatrix<f64>>
where
    S: Lagrangian<N> + ?Sized,
    M: DiscreteLagrangian,
{
    let n = N + 1;
    let (a11, a12, a22) = derivatives::extended_hessian(system, method, seg);
    let inv = a12.clone().try_inverse()?;
    let dx_dx = -&inv * &a11;
    let dx_dp = -inv;
    let dp_dx = a12.transpose() + &a22 * &dx_dx;
    let dp_dp = &a22 * &dx_dp;
    let mut m = DMatrix::zeros(2 * n, 2 * n);
    m.view_mut((0, 0), (n, n)).copy_from(&dx_dx);
    m.view_mut((0, n), (n, n)).copy_from(&dx_dp);
    m.view_mut((n, 0), (n, n)).copy_from(&dp_dx);
    m.view_mut((n, n), (n, n)).copy_from(&dp_dp);
    Some(m)
}

/// `max |Mᵀ𝕁M − 𝕁|` of a square tangent map ordered `(positions, momenta)`,
/// or `None` for a matrix that is not square with an even size.
pub fn defect(m: &DMatrix<f64>) -> Option<f64> {
    if !m.is_square() || !m.nrows().is_multiple_of(2) {
        return None;
    }
    let n = m.nrows() / 2;
    let mut j = DMatrix::zeros(2 * n, 2 * n);
    for i in 0..n {
        j[(i, n + i)] = 1.0;
        j[(n + i, i)] = -1.0;
    }
    Some((m.transpose() * &j * m - j).amax())
}
