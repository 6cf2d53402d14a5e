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

    /// The step action `A ≈ ∫_{t0}^{t0+h} L(t, q(t), q̇(t)) dt` of the step from
    /// `(t0, q0)` to `(t0 + h, q0 + dq)`.
    ///
    /// The step is given by its increments `h` and `dq` rather than by its end
    /// point: the secant velocity `dq/h` is then free of the cancellation in
    /// `q1 − q0`, which for a growing coordinate (an angle after many turns, the
    /// time itself) would put round-off of the size of `ulp(q)/h` into every
    /// momentum and break exact conservation laws.
    fn action<S, D, const N: usize>(&self, system: &S, t0: D, h: D, q0: [D; N], dq: [D; N]) -> D
    where
        S: Lagrangian<N> + ?Sized,
        D: Scalar;
}

/// `dq / h`, the constant velocity of the linear interpolant.
#[inline(always)]
pub(crate) fn secant_velocity<D: Scalar, const N: usize>(dq: &[D; N], h: D) -> [D; N] {
    let inv_h = h.recip();
    array(|i| dq[i] * inv_h)
}

/// `[f(0), …, f(N−1)]` by a plain loop. `core::array::from_fn` and
/// `array::map` build arrays of large elements (the array hyper-duals of
/// `crate::hyperdual`) through an out-of-line closure and `memcpy`; this
/// measured a fifth of a double-pendulum step.
#[inline(always)]
pub(crate) fn array<D: Scalar, const N: usize>(f: impl Fn(usize) -> D) -> [D; N] {
    let mut out = [D::zero(); N];
    for (i, x) in out.iter_mut().enumerate() {
        *x = f(i);
    }
    out
}
