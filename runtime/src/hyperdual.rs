//! `Copy` dual and hyper-dual numbers whose derivative parts are fixed-size
//! arrays: all first derivatives and a whole block of mixed second derivatives
//! from one evaluation.
//!
//! # Why
//!
//! Each Newton iteration of a step needs `∂A/∂q_k`, `∂A/∂q_{k+1}` and the
//! block `∂²A/∂q_k∂q_{k+1}` of the step action (docs/theory.md §4). With num-dual's
//! scalar [`HyperDual64`](num_dual::HyperDual64) that takes `N²` evaluations of
//! `A`, one per pair of seeds, and every `sin`/`cos` of the user's Lagrangian is
//! recomputed `N²` times. num-dual's vector hyper-duals would do it in one
//! evaluation but keep their parts in `Option<SMatrix>`, are not `Copy`, and
//! under cargo's default release profile are not inlined (measured 165–430 ns
//! for the double-pendulum block against 53 ns for four scalar evaluations).
//! The types here are plain structs of arrays, `Copy`, and every operation is
//! a loop over a constant-size array that LLVM unrolls.
//!
//! # The numbers
//!
//! [`HyperDualArray<E1, E2, T>`] is
//!
//! ```text
//! x = re + Σ_i eps1[i] ε1_i + Σ_j eps2[j] ε2_j + Σ_ij eps1eps2[i][j] ε1_i ε2_j,   ε1_i ε1_k = ε2_j ε2_l = 0.
//! ```
//!
//! Seeding
//! `ε1_i` on variable `a_i` and `ε2_j` on `b_j` and evaluating `f` gives `f`,
//! `∂f/∂a_i` (`eps1[i]`), `∂f/∂b_j` (`eps2[j]`) and `∂²f/∂a_i∂b_j`
//! (`eps1eps2[i][j]`). [`DualArray<E, T>`] is the first-order part alone.
//!
//! Every component is a [`Real`] `T`: `f64` (the default, so
//! `DualArray<[f64; N]>` is `DualArray<[f64; N], f64>`) or an extended
//! precision such as [`DoubleDouble`](crate::DoubleDouble). The parts are a
//! [`Vector`] of `T`: `[T; N]`; [`Timed<T, N>`] (`N` position slots and one
//! time slot, which stands in for the `[T; N + 1]` that const generics cannot
//! name) for the extended, variable-step map; or [`Pair<[T; N], [T; N]>`]
//! (the `2N` slots of `(q, v)`) for all first and second derivatives of a
//! Lagrangian at one point.
//!
//! Every unary function goes through one chain rule, with `f0, f1, f2` the
//! value and first two derivatives of the scalar function at `re`:
//!
//! ```text
//! re = f0,   eps1 = f1·eps1,   eps2 = f1·eps2,   eps1eps2 = f1·eps1eps2 + f2·(eps1 ⊗ eps2)
//! ```
//!
//! and products and quotients follow the product and quotient rules
//! component by component. The formulas and the order of the floating-point
//! operations are those of num-dual's scalar `HyperDual<T>` and `Dual<T>`
//! (including its `f64` constants, such as `ln 2` for `exp2`), so component
//! `(i, j)` of one evaluation is bit for bit the scalar hyper-dual evaluation
//! seeded on `(a_i, b_j)` (the tests check this for every function).
//!
//! Comparisons look at the real part only, as in num-dual, so generic code
//! takes the same branches as on `f64`. The remainder `x % y` is defined
//! (num-dual panics): `x − n·y` with the integer `n` held constant, which is
//! its derivative wherever it is differentiable.

use core::fmt;
use core::iter::{Product, Sum};
use core::ops::{Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Rem, RemAssign, Sub, SubAssign};

use num_dual::{DualNum, DualStruct, Mappable};
use num_traits::{FromPrimitive, Inv, Num, One, Signed, Zero};

use crate::real::Real;

/// Fixed-size storage of derivative components of type `T`, operated on
/// component by component.
pub trait Slots<T: Real = f64>: Copy + fmt::Debug + Send + Sync + 'static {
    /// Every component zero.
    const ZERO: Self;

    /// Applies `f` to every component.
    fn map(self, f: impl Fn(T) -> T + Copy) -> Self;

    /// Combines corresponding components of `self` and `other`.
    fn zip(self, other: Self, f: impl Fn(T, T) -> T + Copy) -> Self;
}

impl<T: Real> Slots<T> for T {
    const ZERO: Self = T::ZERO;

    #[inline(always)]
    fn map(self, f: impl Fn(T) -> T + Copy) -> Self {
        f(self)
    }

    #[inline(always)]
    fn zip(self, other: Self, f: impl Fn(T, T) -> T + Copy) -> Self {
        f(self, other)
    }
}

impl<T: Real, S: Slots<T>, const N: usize> Slots<T> for [S; N] {
    const ZERO: Self = [S::ZERO; N];

    #[inline(always)]
    fn map(mut self, f: impl Fn(T) -> T + Copy) -> Self {
        for x in &mut self {
            *x = x.map(f);
        }
        self
    }

    #[inline(always)]
    fn zip(mut self, other: Self, f: impl Fn(T, T) -> T + Copy) -> Self {
        for i in 0..N {
            self[i] = self[i].zip(other[i], f);
        }
        self
    }
}

/// `N` position slots and one time slot: the derivative parts of the extended
/// (variable-step) map, where the variables of a node are `(q, t)`.
///
/// As a [`Vector`] its slot `i < N` is `q[i]` and slot `N` is `t`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Timed<T, const N: usize> {
    /// The position slots.
    pub q: [T; N],
    /// The time slot.
    pub t: T,
}

impl<T: Real, S: Slots<T>, const N: usize> Slots<T> for Timed<S, N> {
    const ZERO: Self = Self { q: [S::ZERO; N], t: S::ZERO };

    #[inline(always)]
    fn map(self, f: impl Fn(T) -> T + Copy) -> Self {
        Self { q: Slots::map(self.q, f), t: self.t.map(f) }
    }

    #[inline(always)]
    fn zip(self, other: Self, f: impl Fn(T, T) -> T + Copy) -> Self {
        Self { q: self.q.zip(other.q, f), t: self.t.zip(other.t, f) }
    }
}

/// Two vectors side by side: the slots of `a`, then those of `b`.
///
/// `Pair<[T; N], [T; N]>` holds the `2N` variables `(q, v)` of a Lagrangian
/// (slot `i < N` is `q[i]`, slot `N + i` is `v[i]`), which `[T; 2N]` cannot
/// name with const generics: seeded on both infinitesimals of a
/// [`HyperDualArray`], one evaluation of `L` gives its value, gradient and
/// whole Hessian in `(q, v)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pair<A, B> {
    /// The first slots.
    pub a: A,
    /// The slots after those of `a`.
    pub b: B,
}

impl<T: Real, A: Slots<T>, B: Slots<T>> Slots<T> for Pair<A, B> {
    const ZERO: Self = Self { a: A::ZERO, b: B::ZERO };

    #[inline(always)]
    fn map(self, f: impl Fn(T) -> T + Copy) -> Self {
        Self { a: self.a.map(f), b: self.b.map(f) }
    }

    #[inline(always)]
    fn zip(self, other: Self, f: impl Fn(T, T) -> T + Copy) -> Self {
        Self { a: self.a.zip(other.a, f), b: self.b.zip(other.b, f) }
    }
}

/// The derivative part of one infinitesimal: `LEN` indexed slots of `T`, and
/// the shape of its outer product with another such part.
pub trait Vector<T: Real = f64>: Slots<T> {
    /// The number of slots.
    const LEN: usize;

    /// The outer product `self ⊗ Q`: one `Q` per slot of `self`.
    type Outer<Q: Vector<T>>: Slots<T>;

    /// Slot `i`.
    fn get(&self, i: usize) -> T;

    /// Slot `i`, to write.
    fn get_mut(&mut self, i: usize) -> &mut T;

    /// Replaces entry `(i, j)` of `m` by `f(i, j, m_ij, other_ij)`.
    fn outer_zip<Q: Vector<T>>(
        m: Self::Outer<Q>,
        other: &Self::Outer<Q>,
        f: impl Fn(usize, usize, T, T) -> T,
    ) -> Self::Outer<Q>;

    /// Entry `(i, j)` of an outer product.
    fn outer_get<Q: Vector<T>>(m: &Self::Outer<Q>, i: usize, j: usize) -> T;
}

impl<T: Real, const N: usize> Vector<T> for [T; N] {
    const LEN: usize = N;
    type Outer<Q: Vector<T>> = [Q; N];

    #[inline(always)]
    fn get(&self, i: usize) -> T {
        self[i]
    }

    #[inline(always)]
    fn get_mut(&mut self, i: usize) -> &mut T {
        &mut self[i]
    }

    #[inline(always)]
    fn outer_zip<Q: Vector<T>>(mut m: [Q; N], other: &[Q; N], f: impl Fn(usize, usize, T, T) -> T) -> [Q; N] {
        for i in 0..N {
            for j in 0..Q::LEN {
                let x = m[i].get_mut(j);
                *x = f(i, j, *x, other[i].get(j));
            }
        }
        m
    }

    #[inline(always)]
    fn outer_get<Q: Vector<T>>(m: &[Q; N], i: usize, j: usize) -> T {
        m[i].get(j)
    }
}

impl<T: Real, const N: usize> Vector<T> for Timed<T, N> {
    const LEN: usize = N + 1;
    type Outer<Q: Vector<T>> = Timed<Q, N>;

    #[inline(always)]
    fn get(&self, i: usize) -> T {
        if i < N { self.q[i] } else { self.t }
    }

    #[inline(always)]
    fn get_mut(&mut self, i: usize) -> &mut T {
        if i < N { &mut self.q[i] } else { &mut self.t }
    }

    #[inline(always)]
    fn outer_zip<Q: Vector<T>>(
        m: Timed<Q, N>,
        other: &Timed<Q, N>,
        f: impl Fn(usize, usize, T, T) -> T,
    ) -> Timed<Q, N> {
        let q = <[T; N]>::outer_zip(m.q, &other.q, &f);
        let mut t = m.t;
        for j in 0..Q::LEN {
            let x = t.get_mut(j);
            *x = f(N, j, *x, other.t.get(j));
        }
        Timed { q, t }
    }

    #[inline(always)]
    fn outer_get<Q: Vector<T>>(m: &Timed<Q, N>, i: usize, j: usize) -> T {
        if i < N { m.q[i].get(j) } else { m.t.get(j) }
    }
}

impl<T: Real, A: Vector<T>, B: Vector<T>> Vector<T> for Pair<A, B> {
    const LEN: usize = A::LEN + B::LEN;
    type Outer<Q: Vector<T>> = Pair<A::Outer<Q>, B::Outer<Q>>;

    #[inline(always)]
    fn get(&self, i: usize) -> T {
        if i < A::LEN { self.a.get(i) } else { self.b.get(i - A::LEN) }
    }

    #[inline(always)]
    fn get_mut(&mut self, i: usize) -> &mut T {
        if i < A::LEN { self.a.get_mut(i) } else { self.b.get_mut(i - A::LEN) }
    }

    #[inline(always)]
    fn outer_zip<Q: Vector<T>>(
        m: Self::Outer<Q>,
        other: &Self::Outer<Q>,
        f: impl Fn(usize, usize, T, T) -> T,
    ) -> Self::Outer<Q> {
        let a = A::outer_zip(m.a, &other.a, &f);
        let b = B::outer_zip(m.b, &other.b, |i, j, x, y| f(A::LEN + i, j, x, y));
        Pair { a, b }
    }

    #[inline(always)]
    fn outer_get<Q: Vector<T>>(m: &Self::Outer<Q>, i: usize, j: usize) -> T {
        if i < A::LEN { A::outer_get(&m.a, i, j) } else { B::outer_get(&m.b, i - A::LEN, j) }
    }
}

/// A dual number `re + Σ_i eps[i] ε_i` with `ε_i ε_j = 0`: the value and
/// gradient of a function of the variables seeded in `eps`.
#[derive(Clone, Copy, Debug)]
pub struct DualArray<E: Vector<T>, T: Real = f64> {
    /// The value.
    pub re: T,
    /// The first derivatives.
    pub eps: E,
}

impl<E: Vector<T>, T: Real> DualArray<E, T> {
    /// The number with the given parts.
    #[inline(always)]
    pub const fn new(re: T, eps: E) -> Self {
        Self { re, eps }
    }

    /// A constant: `re` with zero derivatives.
    #[inline(always)]
    pub const fn from_re(re: T) -> Self {
        Self { re, eps: E::ZERO }
    }

    /// The variable `i`: `re` with `eps[i] = 1`.
    #[inline]
    pub fn variable(re: T, i: usize) -> Self {
        let mut x = Self::from_re(re);
        *x.eps.get_mut(i) = T::one();
        x
    }

    /// `f(re) + f'(re)·eps` for `f0 = f(re)`, `f1 = f'(re)` (`f2` is unused).
    #[inline(always)]
    fn chain(&self, f0: T, f1: T, _f2: T) -> Self {
        Self { re: f0, eps: self.eps.map(|x| x * f1) }
    }

    #[inline(always)]
    fn map_parts(self, f: impl Fn(T) -> T + Copy) -> Self {
        Self { re: f(self.re), eps: self.eps.map(f) }
    }

    #[inline(always)]
    fn zip_parts(self, other: Self, f: impl Fn(T, T) -> T + Copy) -> Self {
        Self { re: f(self.re, other.re), eps: self.eps.zip(other.eps, f) }
    }

    /// Product rule.
    #[inline(always)]
    fn mul_dual(&self, other: &Self) -> Self {
        let (a, b) = (self.re, other.re);
        Self { re: a * b, eps: self.eps.zip(other.eps, |x, y| x * b + y * a) }
    }

    /// Quotient rule.
    #[inline(always)]
    fn div_dual(&self, other: &Self) -> Self {
        let (a, b) = (self.re, other.re);
        let inv = b.recip();
        Self { re: a * inv, eps: self.eps.zip(other.eps, |x, y| (x * b - y * a) * inv * inv) }
    }
}

impl<E: Vector<T>, T: Real> fmt::Display for DualArray<E, T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} + {:?}ε", self.re, self.eps)
    }
}

/// A hyper-dual number with array parts: the value, the gradients with
/// respect to two sets of variables (seeded in `eps1` and `eps2`) and the
/// block of mixed second derivatives between them.
///
/// See the [module documentation](self) for the algebra.
#[derive(Clone, Copy, Debug)]
pub struct HyperDualArray<E1: Vector<T>, E2: Vector<T>, T: Real = f64> {
    /// The value.
    pub re: T,
    /// First derivatives with respect to the variables of `ε1`.
    pub eps1: E1,
    /// First derivatives with respect to the variables of `ε2`.
    pub eps2: E2,
    /// Mixed second derivatives: entry `(i, j)` is `∂²f/∂a_i∂b_j`.
    pub eps1eps2: E1::Outer<E2>,
}

impl<E1: Vector<T>, E2: Vector<T>, T: Real> HyperDualArray<E1, E2, T> {
    /// The number with the given parts.
    #[inline(always)]
    pub const fn new(re: T, eps1: E1, eps2: E2, eps1eps2: E1::Outer<E2>) -> Self {
        Self { re, eps1, eps2, eps1eps2 }
    }

    /// A constant: `re` with zero derivatives.
    #[inline(always)]
    pub const fn from_re(re: T) -> Self {
        Self { re, eps1: E1::ZERO, eps2: E2::ZERO, eps1eps2: <E1::Outer<E2> as Slots<T>>::ZERO }
    }

    /// Entry `(i, j)` of the mixed block, `∂²f/∂a_i∂b_j`.
    #[inline(always)]
    pub fn mixed(&self, i: usize, j: usize) -> T {
        E1::outer_get::<E2>(&self.eps1eps2, i, j)
    }

    /// The chain rule for `f0 = f(re)`, `f1 = f'(re)`, `f2 = f''(re)`.
    #[inline(always)]
    fn chain(&self, f0: T, f1: T, f2: T) -> Self {
        let (a, b) = (&self.eps1, &self.eps2);
        Self {
            re: f0,
            eps1: a.map(|x| x * f1),
            eps2: b.map(|x| x * f1),
            eps1eps2: E1::outer_zip(self.eps1eps2, &self.eps1eps2, |i, j, x, _| x * f1 + a.get(i) * b.get(j) * f2),
        }
    }

    #[inline(always)]
    fn map_parts(self, f: impl Fn(T) -> T + Copy) -> Self {
        Self { re: f(self.re), eps1: self.eps1.map(f), eps2: self.eps2.map(f), eps1eps2: self.eps1eps2.map(f) }
    }

    #[inline(always)]
    fn zip_parts(self, other: Self, f: impl Fn(T, T) -> T + Copy) -> Self {
        Self {
            re: f(self.re, other.re),
            eps1: self.eps1.zip(other.eps1, f),
            eps2: self.eps2.zip(other.eps2, f),
            eps1eps2: self.eps1eps2.zip(other.eps1eps2, f),
        }
    }

    /// Product rule.
    #[inline(always)]
    fn mul_dual(&self, other: &Self) -> Self {
        let (a, b) = (self.re, other.re);
        let (x1, x2, y1, y2) = (&self.eps1, &self.eps2, &other.eps1, &other.eps2);
        Self {
            re: a * b,
            eps1: x1.zip(*y1, |x, y| y * a + x * b),
            eps2: x2.zip(*y2, |x, y| y * a + x * b),
            eps1eps2: E1::outer_zip(self.eps1eps2, &other.eps1eps2, |i, j, x, y| {
                y * a + x1.get(i) * y2.get(j) + y1.get(i) * x2.get(j) + x * b
            }),
        }
    }

    /// Quotient rule.
    #[inline(always)]
    fn div_dual(&self, other: &Self) -> Self {
        let (a, b) = (self.re, other.re);
        let (x1, x2, y1, y2) = (&self.eps1, &self.eps2, &other.eps1, &other.eps2);
        let inv = b.recip();
        let inv2 = inv * inv;
        let c = a * 2.0 * inv2 * inv;
        Self {
            re: a * inv,
            eps1: x1.zip(*y1, |x, y| (x * b - y * a) * inv2),
            eps2: x2.zip(*y2, |x, y| (x * b - y * a) * inv2),
            eps1eps2: E1::outer_zip(self.eps1eps2, &other.eps1eps2, |i, j, x, y| {
                x * inv - (y * a + x1.get(i) * y2.get(j) + y1.get(i) * x2.get(j)) * inv2 + y1.get(i) * y2.get(j) * c
            }),
        }
    }
}

impl<E1: Vector<T>, E2: Vector<T>, T: Real> fmt::Display for HyperDualArray<E1, E2, T> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} + {:?}ε1 + {:?}ε2 + {:?}ε1ε2", self.re, self.eps1, self.eps2, self.eps1eps2)
    }
}

/// Everything `num_dual::DualNum<Primitive = f64>` asks of a type over the
/// [`Real`] `T` with inherent `from_re`, `chain`, `map_parts`, `zip_parts`,
/// `mul_dual` and `div_dual`.
///
/// Everything is `#[inline(always)]`: with plain `#[inline]` LLVM kept the
/// product of two `(q, v)` hyper-duals (25 components at `N = 2`) out of line
/// and copied its arguments through memory (Galerkin s = 6 on Kepler:
/// 2.82 µs per step out of line, 2.36 µs inlined).
macro_rules! impl_dual_num {
    ([$($gen:tt)*] $ty:ty, $nderiv:expr) => {
        impl<$($gen)*> From<f64> for $ty {
            #[inline(always)]
            fn from(re: f64) -> Self {
                Self::from_re(T::from(re))
            }
        }

        impl<$($gen)*> Zero for $ty {
            #[inline(always)]
            fn zero() -> Self {
                Self::from_re(T::zero())
            }

            #[inline(always)]
            fn is_zero(&self) -> bool {
                self.re.is_zero()
            }
        }

        impl<$($gen)*> One for $ty {
            #[inline(always)]
            fn one() -> Self {
                Self::from_re(T::one())
            }

            #[inline(always)]
            fn is_one(&self) -> bool {
                self.re.is_one()
            }
        }

        impl<$($gen)*> Neg for $ty {
            type Output = Self;
            #[inline(always)]
            fn neg(self) -> Self {
                self.map_parts(|x| -x)
            }
        }

        impl<$($gen)*> Neg for &$ty {
            type Output = $ty;
            #[inline(always)]
            fn neg(self) -> $ty {
                -*self
            }
        }

        impl<$($gen)*> Add for $ty {
            type Output = Self;
            #[inline(always)]
            fn add(self, other: Self) -> Self {
                self.zip_parts(other, |x, y| x + y)
            }
        }

        impl<$($gen)*> Sub for $ty {
            type Output = Self;
            #[inline(always)]
            fn sub(self, other: Self) -> Self {
                self.zip_parts(other, |x, y| x - y)
            }
        }

        impl<$($gen)*> Mul for $ty {
            type Output = Self;
            #[inline(always)]
            fn mul(self, other: Self) -> Self {
                self.mul_dual(&other)
            }
        }

        impl<$($gen)*> Div for $ty {
            type Output = Self;
            #[inline(always)]
            fn div(self, other: Self) -> Self {
                self.div_dual(&other)
            }
        }

        /// `x − n·y` with `n = (x − x % y)/y` an integer held constant: the
        /// value is `x.re % y.re` and the derivatives are those of `x − n·y`.
        impl<$($gen)*> Rem for $ty {
            type Output = Self;
            #[inline(always)]
            fn rem(self, other: Self) -> Self {
                let r = self.re % other.re;
                // Rounded to f64: an integer quotient, exact below 2^53.
                let n = DualStruct::re(&((self.re - r) / other.re)).round();
                let mut out = self - other * n;
                out.re = r;
                out
            }
        }

        impl_dual_num!(@forward [$($gen)*] $ty, Add, add, AddAssign, add_assign);
        impl_dual_num!(@forward [$($gen)*] $ty, Sub, sub, SubAssign, sub_assign);
        impl_dual_num!(@forward [$($gen)*] $ty, Mul, mul, MulAssign, mul_assign);
        impl_dual_num!(@forward [$($gen)*] $ty, Div, div, DivAssign, div_assign);
        impl_dual_num!(@forward [$($gen)*] $ty, Rem, rem, RemAssign, rem_assign);

        impl<$($gen)*> Mul<f64> for $ty {
            type Output = Self;
            #[inline(always)]
            fn mul(self, c: f64) -> Self {
                self.map_parts(|x| x * c)
            }
        }

        impl<$($gen)*> Div<f64> for $ty {
            type Output = Self;
            #[inline(always)]
            fn div(self, c: f64) -> Self {
                self.map_parts(|x| x / c)
            }
        }

        impl<$($gen)*> Add<f64> for $ty {
            type Output = Self;
            #[inline(always)]
            fn add(mut self, c: f64) -> Self {
                self.re += c;
                self
            }
        }

        impl<$($gen)*> Sub<f64> for $ty {
            type Output = Self;
            #[inline(always)]
            fn sub(mut self, c: f64) -> Self {
                self.re -= c;
                self
            }
        }

        /// `x % c` for a constant `c`: the derivatives of `x` are unchanged.
        impl<$($gen)*> Rem<f64> for $ty {
            type Output = Self;
            #[inline(always)]
            fn rem(mut self, c: f64) -> Self {
                self.re %= c;
                self
            }
        }

        impl_dual_num!(@assign_f64 [$($gen)*] $ty, Add, add, AddAssign, add_assign);
        impl_dual_num!(@assign_f64 [$($gen)*] $ty, Sub, sub, SubAssign, sub_assign);
        impl_dual_num!(@assign_f64 [$($gen)*] $ty, Mul, mul, MulAssign, mul_assign);
        impl_dual_num!(@assign_f64 [$($gen)*] $ty, Div, div, DivAssign, div_assign);
        impl_dual_num!(@assign_f64 [$($gen)*] $ty, Rem, rem, RemAssign, rem_assign);

        impl<$($gen)*> Inv for $ty {
            type Output = Self;
            #[inline(always)]
            fn inv(self) -> Self {
                self.recip()
            }
        }

        impl<$($gen)*> Sum for $ty {
            #[inline(always)]
            fn sum<I: Iterator<Item = Self>>(iter: I) -> Self {
                iter.fold(Self::zero(), |acc, x| acc + x)
            }
        }

        impl<'a, $($gen)*> Sum<&'a $ty> for $ty {
            #[inline(always)]
            fn sum<I: Iterator<Item = &'a $ty>>(iter: I) -> Self {
                iter.fold(Self::zero(), |acc, x| acc + x)
            }
        }

        impl<$($gen)*> Product for $ty {
            #[inline(always)]
            fn product<I: Iterator<Item = Self>>(iter: I) -> Self {
                iter.fold(Self::one(), |acc, x| acc * x)
            }
        }

        impl<'a, $($gen)*> Product<&'a $ty> for $ty {
            #[inline(always)]
            fn product<I: Iterator<Item = &'a $ty>>(iter: I) -> Self {
                iter.fold(Self::one(), |acc, x| acc * x)
            }
        }

        impl<$($gen)*> FromPrimitive for $ty {
            impl_dual_num!(@from_primitive from_isize isize, from_i8 i8, from_i16 i16, from_i32 i32,
                from_i64 i64, from_i128 i128, from_usize usize, from_u8 u8, from_u16 u16, from_u32 u32,
                from_u64 u64, from_u128 u128, from_f32 f32, from_f64 f64);
        }

        impl<$($gen)*> Num for $ty {
            type FromStrRadixErr = <T as Num>::FromStrRadixErr;
            /// Parses a real number (zero derivatives).
            #[inline(always)]
            fn from_str_radix(s: &str, radix: u32) -> Result<Self, Self::FromStrRadixErr> {
                <T as Num>::from_str_radix(s, radix).map(Self::from_re)
            }
        }

        impl<$($gen)*> Signed for $ty {
            #[inline(always)]
            fn abs(&self) -> Self {
                if self.is_positive() { *self } else { -self }
            }

            #[inline(always)]
            fn abs_sub(&self, other: &Self) -> Self {
                if self.re > other.re { self - other } else { Self::zero() }
            }

            #[inline(always)]
            fn signum(&self) -> Self {
                if self.is_positive() {
                    Self::one()
                } else if self.is_zero() {
                    Self::zero()
                } else {
                    -Self::one()
                }
            }

            #[inline(always)]
            fn is_positive(&self) -> bool {
                Signed::is_positive(&self.re)
            }

            #[inline(always)]
            fn is_negative(&self) -> bool {
                Signed::is_negative(&self.re)
            }
        }

        impl<$($gen)*> DualStruct for $ty {
            type Real = f64;
            type Inner = T;

            #[inline(always)]
            fn re(&self) -> f64 {
                self.re.re()
            }

            #[inline(always)]
            fn from_inner(inner: &T) -> Self {
                Self::from_re(*inner)
            }
        }

        impl<$($gen)*> Mappable<Self> for $ty {
            type Output<O> = O;

            #[inline(always)]
            fn map_dual<M: Fn(Self) -> O, O>(self, f: M) -> O {
                f(self)
            }
        }

        /// Equal when the real parts are (as in num-dual), so generic code
        /// branches as it would on `f64`.
        impl<$($gen)*> PartialEq for $ty {
            #[inline(always)]
            fn eq(&self, other: &Self) -> bool {
                self.re == other.re
            }
        }

        impl<$($gen)*> PartialEq<f64> for $ty {
            #[inline(always)]
            fn eq(&self, other: &f64) -> bool {
                self.re == *other
            }
        }

        /// Ordered by the real parts (as in num-dual).
        impl<$($gen)*> PartialOrd for $ty {
            #[inline(always)]
            fn partial_cmp(&self, other: &Self) -> Option<core::cmp::Ordering> {
                self.re.partial_cmp(&other.re)
            }
        }

        impl<$($gen)*> PartialOrd<f64> for $ty {
            #[inline(always)]
            fn partial_cmp(&self, other: &f64) -> Option<core::cmp::Ordering> {
                self.re.partial_cmp(other)
            }
        }

        impl<$($gen)*> DualNum for $ty {
            type Primitive = f64;
            const NDERIV: usize = T::NDERIV + $nderiv;
            type InnerDual = T;

            #[inline(always)]
            fn from_re(re: T) -> Self {
                Self::from_re(re)
            }

            #[inline(always)]
            fn scale(self, factor: &T) -> Self {
                self.map_parts(|x| x * *factor)
            }

            #[inline(always)]
            fn recip(&self) -> Self {
                let rec = self.re.recip();
                let f1 = -rec * rec;
                self.chain(rec, f1, -f1 * rec * 2.0)
            }

            #[inline(always)]
            fn powi(&self, n: i32) -> Self {
                match n {
                    0 => Self::one(),
                    1 => *self,
                    2 => self * self,
                    _ => {
                        let x = self.re;
                        let pow3 = x.powi(n - 3);
                        let n1 = n as f64;
                        let n2 = (i64::from(n) * (i64::from(n) - 1)) as f64;
                        self.chain(pow3 * x * x * x, pow3 * x * x * n1, pow3 * x * n2)
                    }
                }
            }

            #[inline(always)]
            fn powf(&self, n: f64) -> Self {
                if n == 0.0 {
                    Self::one()
                } else if n == 1.0 {
                    *self
                } else if (n - 1.0 - 1.0).abs() < f64::EPSILON {
                    self * self
                } else {
                    let x = self.re;
                    let n1 = n - 1.0;
                    let pow3 = x.powf(n1 - 1.0 - 1.0);
                    self.chain(pow3 * x * x * x, pow3 * x * x * n, pow3 * x * n * n1)
                }
            }

            #[inline(always)]
            fn sqrt(&self) -> Self {
                let rec = self.re.recip();
                let f0 = self.re.sqrt();
                let f1 = f0 * rec * 0.5;
                self.chain(f0, f1, -f1 * rec * 0.5)
            }

            #[inline(always)]
            fn cbrt(&self) -> Self {
                const THIRD: f64 = 1.0 / 3.0;
                let rec = self.re.recip();
                let f0 = self.re.cbrt();
                let f1 = f0 * rec * THIRD;
                self.chain(f0, f1, f1 * rec * (THIRD - 1.0))
            }

            #[inline(always)]
            fn exp(&self) -> Self {
                let f = self.re.exp();
                self.chain(f, f, f)
            }

            #[inline(always)]
            fn exp2(&self) -> Self {
                let ln2 = 2.0f64.ln();
                let f0 = self.re.exp2();
                let f1 = f0 * ln2;
                self.chain(f0, f1, f1 * ln2)
            }

            #[inline(always)]
            fn exp_m1(&self) -> Self {
                let f1 = self.re.exp();
                self.chain(self.re.exp_m1(), f1, f1)
            }

            #[inline(always)]
            fn ln(&self) -> Self {
                let rec = self.re.recip();
                self.chain(self.re.ln(), rec, -rec * rec)
            }

            #[inline(always)]
            fn log(&self, base: f64) -> Self {
                let rec = self.re.recip();
                let f1 = rec / base.ln();
                self.chain(self.re.log(base), f1, -f1 * rec)
            }

            #[inline(always)]
            fn log2(&self) -> Self {
                let rec = self.re.recip();
                let f1 = rec / 2.0f64.ln();
                self.chain(self.re.log2(), f1, -f1 * rec)
            }

            #[inline(always)]
            fn log10(&self) -> Self {
                let rec = self.re.recip();
                let f1 = rec / core::f64::consts::LN_10;
                self.chain(self.re.log10(), f1, -f1 * rec)
            }

            #[inline(always)]
            fn ln_1p(&self) -> Self {
                let rec = (self.re + 1.0).recip();
                self.chain(self.re.ln_1p(), rec, -rec * rec)
            }

            #[inline(always)]
            fn sin(&self) -> Self {
                let (s, c) = self.re.sin_cos();
                self.chain(s, c, -s)
            }

            #[inline(always)]
            fn cos(&self) -> Self {
                let (s, c) = self.re.sin_cos();
                self.chain(c, -s, -c)
            }

            #[inline(always)]
            fn sin_cos(&self) -> (Self, Self) {
                let (s, c) = self.re.sin_cos();
                (self.chain(s, c, -s), self.chain(c, -s, -c))
            }

            #[inline(always)]
            fn tan(&self) -> Self {
                let (s, c) = self.sin_cos();
                s / c
            }

            #[inline(always)]
            fn asin(&self) -> Self {
                let x = self.re;
                let rec = (T::one() - x * x).recip();
                let f1 = rec.sqrt();
                self.chain(x.asin(), f1, x * f1 * rec)
            }

            #[inline(always)]
            fn acos(&self) -> Self {
                let x = self.re;
                let rec = (T::one() - x * x).recip();
                let f1 = -rec.sqrt();
                self.chain(x.acos(), f1, x * f1 * rec)
            }

            #[inline(always)]
            fn atan(&self) -> Self {
                let x = self.re;
                let rec = (T::one() + x * x).recip();
                self.chain(x.atan(), rec, -x * rec * rec * 2.0)
            }

            #[inline(always)]
            fn atan2(&self, other: Self) -> Self {
                let mut out = (self / other).atan();
                out.re = self.re.atan2(other.re);
                out
            }

            #[inline(always)]
            fn sinh(&self) -> Self {
                let (s, c) = (self.re.sinh(), self.re.cosh());
                self.chain(s, c, s)
            }

            #[inline(always)]
            fn cosh(&self) -> Self {
                let (s, c) = (self.re.sinh(), self.re.cosh());
                self.chain(c, s, c)
            }

            #[inline(always)]
            fn tanh(&self) -> Self {
                self.sinh() / self.cosh()
            }

            #[inline(always)]
            fn asinh(&self) -> Self {
                let x = self.re;
                let rec = (T::one() + x * x).recip();
                let f1 = rec.sqrt();
                self.chain(x.asinh(), f1, -x * f1 * rec)
            }

            #[inline(always)]
            fn acosh(&self) -> Self {
                let x = self.re;
                let rec = (x * x - 1.0).recip();
                let f1 = rec.sqrt();
                self.chain(x.acosh(), f1, -x * f1 * rec)
            }

            #[inline(always)]
            fn atanh(&self) -> Self {
                let x = self.re;
                let rec = (T::one() - x * x).recip();
                self.chain(x.atanh(), rec, x * rec * rec * 2.0)
            }

            #[inline(always)]
            fn sph_j0(&self) -> Self {
                if self.re.abs() < f64::EPSILON { Self::one() - self * self / 6.0 } else { self.sin() / self }
            }

            #[inline(always)]
            fn sph_j1(&self) -> Self {
                if self.re.abs() < f64::EPSILON {
                    *self / 3.0
                } else {
                    let (s, c) = self.sin_cos();
                    (s - self * c) / (self * self)
                }
            }

            #[inline(always)]
            fn sph_j2(&self) -> Self {
                if self.re.abs() < f64::EPSILON {
                    self * self / 15.0
                } else {
                    let (s, c) = self.sin_cos();
                    let s2 = self * self;
                    ((s - self * c) * 3.0 - s2 * s) / (s2 * self)
                }
            }
        }
    };

    // `T op T`, `T op &T`, `&T op T`, `&T op &T` and `T op= T` from `T op T`.
    (@forward [$($gen:tt)*] $ty:ty, $op:ident, $method:ident, $assign:ident, $assign_method:ident) => {
        impl<'a, $($gen)*> $op<&'a $ty> for $ty {
            type Output = $ty;
            #[inline(always)]
            fn $method(self, other: &'a $ty) -> $ty {
                $op::$method(self, *other)
            }
        }

        impl<'a, $($gen)*> $op<$ty> for &'a $ty {
            type Output = $ty;
            #[inline(always)]
            fn $method(self, other: $ty) -> $ty {
                $op::$method(*self, other)
            }
        }

        impl<'a, 'b, $($gen)*> $op<&'b $ty> for &'a $ty {
            type Output = $ty;
            #[inline(always)]
            fn $method(self, other: &'b $ty) -> $ty {
                $op::$method(*self, *other)
            }
        }

        impl<$($gen)*> $assign for $ty {
            #[inline(always)]
            fn $assign_method(&mut self, other: $ty) {
                *self = $op::$method(*self, other);
            }
        }
    };

    (@assign_f64 [$($gen:tt)*] $ty:ty, $op:ident, $method:ident, $assign:ident, $assign_method:ident) => {
        impl<$($gen)*> $assign<f64> for $ty {
            #[inline(always)]
            fn $assign_method(&mut self, c: f64) {
                *self = $op::$method(*self, c);
            }
        }
    };

    (@from_primitive $($method:ident $prim:ty),*) => {
        $(
            #[inline(always)]
            fn $method(n: $prim) -> Option<Self> {
                T::$method(n).map(Self::from_re)
            }
        )*
    };
}

impl_dual_num!([E: Vector<T>, T: Real] DualArray<E, T>, 1);
impl_dual_num!([E1: Vector<T>, E2: Vector<T>, T: Real] HyperDualArray<E1, E2, T>, 2);

#[cfg(test)]
mod tests;
