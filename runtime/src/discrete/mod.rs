//! Discrete Lagrangians: the step action `A(t_k, q_k, t_{k+1}, q_{k+1}) ≈ ∫ L dt`.
//!
//! MATH.md §2 and §5. The runtime works with the action `A = h · L_d` rather
//! than with `L_d`, which removes every factor `h` from the discrete
//! Euler–Lagrange and energy equations. Each method lives in its own file whose
//! documentation gives its formula, source and order.

mod alpha_beta;
mod midpoint;
mod trapezoid;

pub use alpha_beta::AlphaBeta;
pub use midpoint::Midpoint;
pub use trapezoid::Trapezoid;

use crate::system::{Lagrangian, Scalar};

/// A discrete Lagrangian, given by its step action `A(x_k, x_{k+1})`, where
/// `x = (t, q)` is an extended point.
///
/// `action` is generic over the [`Scalar`] so that one evaluation on
/// hyper-dual numbers yields the residual, the next momentum and the Newton
/// Jacobian of the one-step map (MATH.md §4).
pub trait DiscreteLagrangian: Copy + core::fmt::Debug {
    /// Order of the one-step map for a regular Lagrangian.
    fn order(&self) -> u32;

    /// The step action `A(t0, q0, t1, q1) ≈ ∫_{t0}^{t1} L(t, q(t), q̇(t)) dt`.
    fn action<S, D, const N: usize>(&self, system: &S, t0: D, q0: [D; N], t1: D, q1: [D; N]) -> D
    where
        S: Lagrangian<N> + ?Sized,
        D: Scalar;
}

/// `(q1 − q0) / h`, the constant velocity of the linear interpolant.
#[inline(always)]
pub(crate) fn secant_velocity<D: Scalar, const N: usize>(
    q0: &[D; N],
    q1: &[D; N],
    inv_h: D,
) -> [D; N] {
    core::array::from_fn(|i| (q1[i] - q0[i]) * inv_h)
}
