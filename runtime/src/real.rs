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

/// The Kahan sum `a + b` with the compensation `c` of `a`: `(sum, carry)`.
/// Every compensated update of a state goes through it, so the slice, array
/// and scalar forms round identically.
#[inline(always)]
pub(crate) fn kahan_add<T: Real>(a: T, c: T, b: T) -> (T, T) {
    let u = c + b;
    let sum = a + u;
    (sum, u - (sum - a))
}

/// `a + (c + b)` summed with Kahan's compensation `c`: `(sum, new compensation)`.
#[inline(always)]
pub(crate) fn kahan<T: Real, const N: usize>(a: &[T; N], c: &[T; N], b: &[T; N]) -> ([T; N], [T; N]) {
    let mut sum = [T::zero(); N];
    let mut carry = [T::zero(); N];
    kahan_into(a, c, b, &mut sum, &mut carry);
    (sum, carry)
}

/// [`kahan`] on slices of one length, into `sum` and `carry`.
#[inline(always)]
pub(crate) fn kahan_into<T: Real>(a: &[T], c: &[T], b: &[T], sum: &mut [T], carry: &mut [T]) {
    for i in 0..a.len() {
        (sum[i], carry[i]) = kahan_add(a[i], c[i], b[i]);
    }
}

/// `max(m, |x|)` as `f64::max` takes it, NaN ignored (`m` is never NaN):
/// one `maxsd`, where `f64::max` also tests for NaN.
#[inline(always)]
pub(crate) fn max_abs_step(m: f64, x: f64) -> f64 {
    let a = x.abs();
    if a > m { a } else { m }
}

/// `max|x|`, the value [`max_abs`] returns: the maximum is exact and
/// ignores NaN in any order, so running maxima in several lanes (which
/// vectorise) combine to the same number as one. Four lanes for short
/// inputs; sixteen (eight vector registers, whose chains of dependent `max`
/// overlap) from 64 values, where four were bound by that latency (0.3 µs
/// for two passes at `N = 1000`). For a const `N` the choice is made at
/// compile time.
#[inline(always)]
pub(crate) fn fold_max_abs(x: &[f64]) -> f64 {
    if x.len() >= 64 { fold_max_abs_lanes::<16>(x) } else { fold_max_abs_lanes::<4>(x) }
}

/// [`fold_max_abs`] with `LANES` running maxima.
#[inline(always)]
fn fold_max_abs_lanes<const LANES: usize>(x: &[f64]) -> f64 {
    let mut lanes = [0.0; LANES];
    let (chunks, rest) = x.as_chunks::<LANES>();
    for chunk in chunks {
        for k in 0..LANES {
            lanes[k] = max_abs_step(lanes[k], chunk[k]);
        }
    }
    // Pairwise, as the lanes of the vector registers combine.
    let mut width = LANES;
    while width > 1 {
        width /= 2;
        for k in 0..width {
            lanes[k] = max_abs_step(lanes[k], lanes[k + width]);
        }
    }
    let mut m = lanes[0];
    for &v in rest {
        m = max_abs_step(m, v);
    }
    m
}

/// Zero exactly when `x` is finite (`x − x` is `+0` then, NaN otherwise):
/// OR-ed over a step's values, a finiteness test with no branch per value
/// that vectorises.
#[inline(always)]
#[allow(clippy::eq_op)]
pub(crate) fn nan_bits(x: f64) -> u64 {
    (x - x).to_bits()
}

/// Whether an OR of [`nan_bits`] saw a value that is not finite.
#[inline(always)]
pub(crate) fn is_non_finite(bits: u64) -> bool {
    bits != 0
}

/// Inverts `a` into `inv` by Gauss–Jordan elimination with partial
/// pivoting, destroying `a`; `false` where a pivot is NaN or at most
/// `tiny` times the largest entry of `a` (`tiny = 0`: exactly singular), or
/// the inverse is not finite. Callers choose the storage: the collocation
/// iteration's small blocks on the stack, the splitting's mass matrix on
/// the heap.
#[inline(always)]
pub(crate) fn gauss_jordan_into<T: Real, const N: usize>(
    a: &mut [[T; N]; N],
    inv: &mut [[T; N]; N],
    tiny: f64,
) -> bool {
    for (i, row) in inv.iter_mut().enumerate() {
        row.fill(T::zero());
        row[i] = T::one();
    }
    let scale = if tiny > 0.0 { a.iter().flatten().fold(0.0f64, |m, x| m.max(x.re().abs())) } else { 0.0 };
    if !scale.is_finite() {
        return false;
    }
    for col in 0..N {
        let Some(pivot) = (col..N).max_by(|&i, &j| a[i][col].re().abs().total_cmp(&a[j][col].re().abs())) else {
            return false;
        };
        let p = a[pivot][col];
        let size = p.re().abs();
        if size.is_nan() || size <= tiny * scale || !p.is_finite() {
            return false;
        }
        a.swap(col, pivot);
        inv.swap(col, pivot);
        let d = p.recip();
        for j in 0..N {
            a[col][j] *= d;
            inv[col][j] *= d;
        }
        for i in 0..N {
            if i != col {
                let f = a[i][col];
                for j in 0..N {
                    let (aj, ij) = (a[col][j], inv[col][j]);
                    a[i][j] -= f * aj;
                    inv[i][j] -= f * ij;
                }
            }
        }
    }
    inv.iter().flatten().all(|x| x.is_finite())
}

/// A xorshift stream of uniform numbers in `[−0.5, 0.5)` from `seed`, for
/// the randomised agreement tests of the step checks.
#[cfg(test)]
pub(crate) fn uniform_stream(mut seed: u64) -> impl FnMut() -> f64 {
    move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A xorshift stream of `f64`s over every exponent and sign, with
    /// zeros, subnormals, infinities and NaNs mixed in.
    fn awkward_values(n: usize) -> Vec<f64> {
        let mut seed = 0x9e37_79b9_7f4a_7c15_u64;
        (0..n)
            .map(|i| {
                seed ^= seed << 13;
                seed ^= seed >> 7;
                seed ^= seed << 17;
                match i % 11 {
                    0 => [0.0, -0.0, f64::INFINITY, f64::NEG_INFINITY, f64::NAN, f64::MIN_POSITIVE / 3.0]
                        [(seed % 6) as usize],
                    _ => f64::from_bits(seed),
                }
            })
            .collect()
    }

    #[test]
    fn the_lane_maximum_is_the_maximum_of_max_abs() {
        let values = awkward_values(4000);
        let mut nan_seen = false;
        // Every length around the lane counts, and long ones (sixteen lanes
        // from 64 values).
        for len in (0..=40).chain([63, 64, 65, 79, 80, 81, 200, 1001]) {
            for start in (0..values.len() - len).step_by(7) {
                let x = &values[start..start + len];
                nan_seen |= x.iter().any(|v| v.is_nan());
                assert_eq!(fold_max_abs(x).to_bits(), max_abs(x).to_bits(), "{x:?}");
            }
        }
        assert!(nan_seen, "the values exercised NaN");
    }

    #[test]
    fn nan_bits_are_zero_exactly_for_finite_values() {
        for x in awkward_values(4000) {
            assert_eq!(is_non_finite(nan_bits(x)), !x.is_finite(), "{x:e}");
        }
        let all = awkward_values(12);
        assert!(all.iter().any(|x| !x.is_finite()) && all.iter().any(|x| x.is_finite()));
    }
}
