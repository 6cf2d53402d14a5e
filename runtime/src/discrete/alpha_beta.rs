//! The α-β family of discrete Lagrangians.
//!
//! ```text
//! A(t_k, q_k, t_{k+1}, q_{k+1}) = h · L(t_k + βh, α q_k + β q_{k+1}, (q_{k+1} − q_k)/h),   α + β = 1
//! ```
//!
//! Source: Luo, Guo, Li & Wu, Luo, Guo, Li & Wu, "case 2" (§III.B). Order 1 for
//! `α ≠ ½`, order 2 at `α = ½` (where it is [`Midpoint`](super::Midpoint)).
//! `α = 1` and `α = 0` are the two symplectic Euler methods.

use super::{DiscreteLagrangian, array, secant_velocity, secant_velocity_fixed};
use crate::system::{Lagrangian, Scalar};

/// The α-β discrete Lagrangian `A = h L(t_k + βh, α q_k + β q_{k+1}, v̂)`, `β = 1 − α`.
///
/// Order 1, or 2 when `α = ½`. Build it with [`AlphaBeta::new`], which checks
/// that `α` is finite.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AlphaBeta {
    alpha: f64,
}

impl AlphaBeta {
    /// The member with weight `alpha` on `q_k` (and `1 − alpha` on `q_{k+1}`).
    ///
    /// Returns `None` if `alpha` is not finite. Values outside `[0, 1]` are
    /// allowed (they are still variational integrators) but unusual.
    pub fn new(alpha: f64) -> Option<Self> {
        alpha.is_finite().then_some(Self { alpha })
    }

    /// `α = 1`: symplectic Euler with the potential taken at `q_k`.
    pub const EULER_A: Self = Self { alpha: 1.0 };

    /// `α = 0`: symplectic Euler with the potential taken at `q_{k+1}`.
    pub const EULER_B: Self = Self { alpha: 0.0 };

    /// The weight `α` on `q_k`.
    pub fn alpha(&self) -> f64 {
        self.alpha
    }
}

impl DiscreteLagrangian for AlphaBeta {
    fn order(&self) -> u32 {
        if self.alpha == 0.5 { 2 } else { 1 }
    }

    fn energy_error_kappa(&self) -> Option<f64> {
        // α = ½ is the midpoint rule.
        (self.alpha == 0.5).then_some(0.0)
    }

    fn galerkin_points(&self) -> Option<([f64; 2], usize)> {
        let beta = 1.0 - self.alpha;
        Some(([beta, beta], usize::from(self.alpha == 0.5)))
    }

    #[inline(always)]
    fn action<S, D, const N: usize>(&self, system: &S, t0: D, h: D, q0: [D; N], dq: [D; N]) -> D
    where
        S: Lagrangian<N> + ?Sized,
        D: Scalar,
    {
        let beta = 1.0 - self.alpha;
        let v = secant_velocity(&dq, h);
        // α q_k + β q_{k+1} = q_k + β dq
        let q = array(|i| q0[i] + dq[i] * beta);
        system.lagrangian(t0 + h * beta, q, v) * h
    }

    #[inline(always)]
    fn fixed_step_action<S, D, const N: usize>(&self, system: &S, t0: f64, h: f64, q0: [D; N], dq: [D; N]) -> D
    where
        S: Lagrangian<N> + ?Sized,
        D: Scalar,
    {
        let beta = 1.0 - self.alpha;
        let v = secant_velocity_fixed(&dq, h);
        let q = array(|i| q0[i] + dq[i] * beta);
        system.lagrangian(D::from(t0 + h * beta), q, v) * h
    }

    /// The same one-point rule for the forces: `F` at `(t_k + βh, α q_k + β q_{k+1}, v̂)`
    /// with `F_k^− = α h F` and `F_k^+ = β h F`, the weights the linear
    /// interpolant gives `δq_k` and `δq_{k+1}` at that point.
    #[inline(always)]
    fn forces<S, D, const N: usize>(&self, system: &S, t0: D, h: D, q0: [D; N], dq: [D; N]) -> ([D; N], [D; N])
    where
        S: Lagrangian<N> + ?Sized,
        D: Scalar,
    {
        let beta = 1.0 - self.alpha;
        let v = secant_velocity(&dq, h);
        let q = array(|i| q0[i] + dq[i] * beta);
        super::one_point(system, (t0 + h * beta, q, v), h, self.alpha)
    }
}
