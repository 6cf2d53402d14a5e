//! The real number types an integrator can hold its state in.
//!
//! Everything the Galerkin integrator computes (quadrature nodes and weights,
//! the Lagrange basis, the Newton block, the state) is written once over a
//! [`Real`]: `f64` for ordinary runs, or a wider type such as
//! [`DoubleDouble`](crate::DoubleDouble) (about 32 digits) for
//! extended-precision reference runs and for verifying methods whose errors
//! fall below `f64` round-off (order 16 at errors of 1e-25). A user's
//! Lagrangian needs no change: it is generic over [`Scalar`], and the
//! hyper-duals the runtime evaluates it on are num-dual's, over the `Real`.

use crate::system::Scalar;

/// A real number type: `f64` itself, or an extended-precision type whose
/// `DualNum::re` rounds it to `f64`.
pub trait Real: Scalar + Send + Sync {
    /// The relative spacing of the type's numbers near 1 (`f64::EPSILON`
    /// for `f64`): Newton's round-off floors scale with it.
    const EPSILON: f64;

    /// Zero, as a constant (the zero derivative parts of the
    /// [array duals](crate::hyperdual)).
    const ZERO: Self;

    /// `true` when the number is neither infinite nor NaN.
    fn is_finite(self) -> bool;

    /// The nearest `f64` (for diagnostics, tolerances and error reports).
    #[inline(always)]
    fn to_f64(self) -> f64 {
        self.re()
    }
}

impl Real for f64 {
    const EPSILON: f64 = f64::EPSILON;
    const ZERO: Self = 0.0;

    #[inline(always)]
    fn is_finite(self) -> bool {
        f64::is_finite(self)
    }
}

impl Real for crate::DoubleDouble {
    /// `2^-104`: the double-double unit of its ≈ 106-bit significand.
    const EPSILON: f64 = crate::DoubleDouble::EPSILON.hi();
    const ZERO: Self = crate::DoubleDouble::ZERO;

    #[inline(always)]
    fn is_finite(self) -> bool {
        crate::DoubleDouble::is_finite(self)
    }
}

/// `max |x_i|` rounded to `f64`.
#[inline]
pub(crate) fn max_abs<T: Real>(x: &[T]) -> f64 {
    x.iter().fold(0.0, |m: f64, v| m.max(v.to_f64().abs()))
}

/// Every entry finite.
#[inline]
pub(crate) fn all_finite<T: Real>(x: &[T]) -> bool {
    x.iter().all(|v| v.is_finite())
}
