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
//! `q[i]`, `v[i]` at literal indices) has a [`Jet`]: a non-generic method
//! that returns its value, gradient and Hessian in `f64` from its body on
//! [`HyperDual64`] (one leaf or one pair of leaves seeded at a time,
//! [`seeded`]), a number of four parts whatever `k` and `N`. Every dual number over `f64` then takes its value
//! from there through [`lift`], one copy per scalar type for all chunks:
//! the second-order Taylor polynomial of the chunk at the real parts of its
//! leaves, composed with the leaves' derivative parts,
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
//! [`Scalar::SECOND_ORDER`]: every number whose parts are all `f64` and
//! whose derivatives stop at the second order, nested ones included
//! (`Dual<DualArray<_>>`, on which the runtime takes Hessian-vector
//! products of `L` forward over forward). Everything else (`f64` itself,
//! [`DoubleDouble`](crate::DoubleDouble) and dual numbers over it, whose
//! values need the body at their own precision, and third-order numbers)
//! evaluates the chunk's generic body, which is then compiled only for
//! those types.

use crate::Scalar;
use num_dual::HyperDual64;

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

/// `previous + c(leaves)` on `D` from the chunk's value `value` (the
/// previous partial result included, as `f64`), its gradient and, for
/// second-order numbers, its Hessian (row-major, `k × k`, or empty), all at
/// the real parts of the leaves.
///
/// Not inlined: one copy per scalar type serves every chunk of every
/// system, whatever its number of leaves.
#[inline(never)]
pub fn compose<D: Scalar>(previous: D, leaves: &[D], value: f64, gradient: &[f64], hessian: &[f64]) -> D {
    taylor(previous, leaves.len(), |i| leaves[i], value, gradient, hessian)
}

/// The second-order Taylor polynomial of [`compose`], with leaf `i` read
/// by `leaf(i)` for `i < k` (no copy of the leaves).
#[inline(always)]
fn taylor<D: Scalar>(
    previous: D,
    k: usize,
    leaf: impl Fn(usize) -> D,
    value: f64,
    gradient: &[f64],
    hessian: &[f64],
) -> D {
    let delta = |i: usize| {
        let x = leaf(i);
        x - D::from(x.re())
    };
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

/// The most leaves a chunk lowered to `f64` reads (the macro's bound):
/// [`lift`] keeps its gradient and Hessian on the stack.
pub const MAX_LEAVES: usize = 16;

/// The real parts of a chunk's inputs: the previous partial result (zero
/// for the first chunk), `t` (zero when the method takes none), `q` and `v`
/// (`q` again when the method takes no `v`).
#[derive(Clone, Copy, Debug)]
pub struct Reals<const N: usize> {
    /// The previous partial result.
    pub previous: f64,
    /// The time.
    pub t: f64,
    /// The coordinates.
    pub q: [f64; N],
    /// The velocities.
    pub v: [f64; N],
}

/// A chunk lowered to `f64`: from the real parts of its inputs it returns
/// its value (bit for bit that of `f64`), and writes its gradient in its
/// `k` leaves into the first slice and, when the flag is set, the upper
/// triangle of its Hessian (row-major, `k × k`) into the second, whose
/// other entries it leaves alone. The macro prints one per chunk, non
/// generic: the chunk's body is compiled for [`HyperDual64`] (one or two
/// directions, the Hessian an entry at a time, see [`seeded`]) instead of
/// for every scalar type.
pub type Jet<S, const N: usize> = fn(&S, &Reals<N>, bool, &mut [f64], &mut [f64]) -> f64;

/// `previous + c(leaves)` on `D`, for a chunk lowered to `f64` as `jet`:
/// leaf `i` is `q[l]` for `l = leaves[i] < N`, `v[l − N]` below `2N` and
/// `t` at `2N`. The chunk's value, gradient and (for second-order numbers)
/// Hessian at the real parts, composed by the chain rule as [`compose`]
/// does.
///
/// Not inlined, and generic over the scalar but not over the chunk (which
/// `jet` is): one copy per scalar type and system serves all its chunks,
/// so that a chunk adds one small dispatch per scalar type, not a copy of
/// its body.
#[inline(never)]
#[allow(clippy::too_many_arguments)]
pub fn lift<S, D: Scalar, const N: usize>(
    system: &S,
    previous: D,
    t: D,
    q: &[D; N],
    v: &[D; N],
    leaves: &[usize],
    jet: Jet<S, N>,
) -> D {
    let k = leaves.len().min(MAX_LEAVES);
    let inputs = Reals { previous: previous.re(), t: t.re(), q: reals(q), v: reals(v) };
    let (mut gradient, mut hessian) = ([0.0; MAX_LEAVES], [0.0; MAX_LEAVES * MAX_LEAVES]);
    let second = D::SECOND_ORDER;
    let value = jet(system, &inputs, second, &mut gradient[..k], &mut hessian[..k * k]);
    let leaf = |i: usize| match leaves[i] {
        l if l < N => q[l],
        l if l < 2 * N => v[l - N],
        _ => t,
    };
    let hessian = if second { &hessian[..k * k] } else { &[] };
    taylor(previous, k, leaf, value, &gradient[..k], hessian)
}

/// The inputs of a chunk on [`HyperDual64`] at `x`: every one a constant
/// but leaf `a` (numbered as in [`lift`]), which carries `ε1`, and leaf
/// `b`, which carries `ε2`. The chunk's value there has its derivative in
/// leaf `a` as `ε1` and `∂²c/∂a∂b` as `ε1ε2`: one Hessian entry per
/// evaluation, on a number of four parts whatever the number of leaves.
#[inline]
pub fn seeded<const N: usize>(x: &Reals<N>, a: usize, b: usize) -> (HyperDual64, [HyperDual64; N], [HyperDual64; N]) {
    seed(x, a, Some(b))
}

/// [`seeded`], with `ε2` on leaf `b` when there is one.
#[inline]
fn seed<const N: usize>(x: &Reals<N>, a: usize, b: Option<usize>) -> (HyperDual64, [HyperDual64; N], [HyperDual64; N]) {
    let (mut t, mut q, mut v) = (HyperDual64::from(x.t), x.q.map(HyperDual64::from), x.v.map(HyperDual64::from));
    for (l, second) in [(Some(a), false), (b, true)] {
        let Some(l) = l else { continue };
        let x = match l {
            l if l < N => &mut q[l],
            l if l < 2 * N => &mut v[l - N],
            _ => &mut t,
        };
        if second { x.eps2 = 1.0 } else { x.eps1 = 1.0 }
    }
    (t, q, v)
}

/// A chunk's body on [`HyperDual64`], as its [`Jet`] passes it to
/// [`second_order`]: the previous partial result, `t`, `q` and `v`.
pub type HyperBody<S, const N: usize> =
    fn(&S, HyperDual64, HyperDual64, &[HyperDual64; N], &[HyperDual64; N]) -> HyperDual64;

/// The gradient and the upper triangle of the Hessian of a chunk in its
/// `leaves` (numbered as in [`lift`]) at `x`, from `body` evaluated once
/// per pair `(a, b)` of `pairs` (positions in `leaves`, `a ≤ b`, the
/// diagonal included): `gradient[a]` from `(a, a)`, `hessian[a·k + b]`
/// from `(a, b)`. Pairs left out keep their entry.
///
/// Not inlined, and one copy per system: a chunk's [`Jet`] is a call,
/// not a loop the optimiser unrolls over the chunk's pairs.
#[inline(never)]
pub fn second_order<S, const N: usize>(
    system: &S,
    x: &Reals<N>,
    leaves: &[usize],
    pairs: &[(usize, usize)],
    body: HyperBody<S, N>,
    gradient: &mut [f64],
    hessian: &mut [f64],
) {
    let k = leaves.len();
    for &(a, b) in pairs {
        let (t, q, v) = seeded(x, leaves[a], leaves[b]);
        let c = body(system, HyperDual64::from(x.previous), t, &q, &v);
        if a == b {
            gradient[a] = c.eps1;
        }
        hessian[a * k + b] = c.eps1eps2;
    }
}

/// The gradient of a chunk in its `leaves` (numbered as in [`lift`]) at
/// `x`, from `body` evaluated once per leaf with only `ε1` seeded (the
/// body on [`HyperDual64`] serves both orders, so that it is the one
/// derivative type a chunk is compiled for). Not inlined, as
/// [`second_order`].
#[inline(never)]
pub fn first_order<S, const N: usize>(
    system: &S,
    x: &Reals<N>,
    leaves: &[usize],
    body: HyperBody<S, N>,
    gradient: &mut [f64],
) {
    for (a, &leaf) in leaves.iter().enumerate() {
        let (t, q, v) = seed(x, leaf, None);
        gradient[a] = body(system, HyperDual64::from(x.previous), t, &q, &v).eps1;
    }
}
