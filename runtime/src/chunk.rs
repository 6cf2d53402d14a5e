//! The pieces of a long Lagrangian, evaluated once in `f64` and lifted to
//! any dual number by the chain rule.
//!
//! `#[lagrangian]` splits a long sum or product into chunks of a few
//! operands, each a non-inlined method. Generic over the [`Scalar`], one
//! chunk would be compiled once for every type the runtime evaluates `L`
//! on: `f64`, dual and hyper-dual numbers of several widths, tape
//! variables, and for a system of `N` coordinates the `N`-wide ones carry
//! `N` or `N²` parts through every operation. The compile time then grows
//! as terms × types × `N²`. Instead, a chunk reading `k` leaves (`t`, and
//! `q[i]`, `v[i]` at literal indices) is compiled at one fixed type only,
//! [`Column<k>`] over plain `f64`: its value, its gradient in the `k`
//! leaves and one column of its Hessian, whose width grows as `k`, not
//! `k²` ([`columns`] evaluates it once per column). Every dual number over
//! `f64` then takes its value from there: [`compose`] is the second-order Taylor polynomial of the chunk at
//! the real parts of its leaves, composed with the leaves' derivative
//! parts,
//!
//! ```text
//! c(x) = c + Σ_i g_i δ_i + ½ Σ_ij H_ij δ_i δ_j,   δ_i = x_i − re(x_i),
//! ```
//!
//! which has exactly the first and second derivatives of the chunk
//! wherever derivatives of order three and higher vanish (`δ` has a zero
//! real part, so products of three `δ`s are zero in any number with at most
//! second derivatives). Values stay bit for bit those of `f64`: the chunk
//! is evaluated with the previous partial result as its first operand,
//! and every `δ` term has a zero real part.
//!
//! Which scalars go this way is [`Scalar::FIRST_ORDER`] and
//! [`Scalar::SECOND_ORDER`]; everything else (`f64` itself,
//! [`DoubleDouble`](crate::DoubleDouble) and dual numbers over it, whose
//! values need the body at their own precision, and third-order numbers)
//! evaluates the chunk's generic body, which is then compiled only for
//! those types.

use crate::Scalar;
use crate::hyperdual::HyperDualArray;

/// A chunk's value, gradient and one column of its Hessian with respect
/// to its `K` leaves.
pub type Column<const K: usize> = HyperDualArray<[f64; K], [f64; 1]>;

/// A chunk's value, gradient (`eps1`) and Hessian (`eps1eps2`) with
/// respect to its `K` leaves, as [`columns`] assembles them.
pub type Hessian<const K: usize> = HyperDualArray<[f64; K], [f64; K]>;

/// The real part of `x`.
#[inline(always)]
pub fn real<D: Scalar>(x: D) -> f64 {
    x.re()
}

/// The real parts of `x`.
#[inline(always)]
pub fn reals<D: Scalar, const N: usize>(x: &[D; N]) -> [f64; N] {
    x.map(|x| x.re())
}

/// Every entry of `x` as a constant (zero derivative parts) of `D`.
#[inline(always)]
pub fn constants<D: Scalar, const N: usize>(x: &[f64; N]) -> [D; N] {
    x.map(D::from)
}

/// Leaf `i` of `K` at the value `x`: `ε1_i` seeded, and `ε2` too when `i`
/// is the column `column` being evaluated.
#[inline(always)]
pub fn leaf<const K: usize>(x: f64, i: usize, column: usize) -> Column<K> {
    let mut h = Column::from_re(x);
    h.eps1[i] = 1.0;
    if i == column {
        h.eps2[0] = 1.0;
    }
    h
}

/// The value, gradient and Hessian of a chunk from `column(j)`, its
/// evaluation with the second direction seeded on leaf `j`, for every `j`.
#[inline(always)]
pub fn columns<const K: usize>(mut column: impl FnMut(usize) -> Column<K>) -> Hessian<K> {
    let mut h = Hessian::<K>::from_re(0.0);
    for j in 0..K {
        let c = column(j);
        (h.re, h.eps1) = (c.re, c.eps1);
        for i in 0..K {
            h.eps1eps2[i][j] = c.eps1eps2[i][0];
        }
    }
    h
}

/// `previous + c(leaves)` on `D` from the chunk's value `value` (the
/// previous partial result included, as `f64`), its gradient and, for
/// second-order numbers, its Hessian (row-major, `k × k`, or empty), all at
/// the real parts of the leaves.
///
/// Not inlined: one copy per scalar type serves every chunk of every
/// system, whatever its number of leaves.
#[inline(never)]
pub fn compose<D: Scalar>(previous: D, leaves: &[D], value: f64, gradient: &[f64], hessian: &[f64]) -> D {
    let k = leaves.len();
    let delta = |i: usize| leaves[i] - D::from(leaves[i].re());
    let mut r = D::from(value) + (previous - D::from(previous.re()));
    for (i, &g) in gradient.iter().enumerate().take(k) {
        if g != 0.0 {
            r += delta(i) * g;
        }
    }
    if hessian.len() == k * k {
        for i in 0..k {
            let di = delta(i);
            let mut s = D::zero();
            let mut any = false;
            for j in i..k {
                let h = if i == j { 0.5 * hessian[i * k + i] } else { hessian[i * k + j] };
                if h != 0.0 {
                    s += if i == j { di } else { delta(j) } * h;
                    any = true;
                }
            }
            if any {
                r += di * s;
            }
        }
    }
    r
}
