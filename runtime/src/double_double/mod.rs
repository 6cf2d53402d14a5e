//! Double-double arithmetic: a real number held as the unevaluated sum of two
//! `f64`, for extended-precision reference runs.
//!
//! # What it is
//!
//! A [`DoubleDouble`] is `hi + lo` with `hi = fl(hi + lo)`, so
//! `|lo| ≤ ½ ulp(hi)`: about 106 significant bits, 32 decimal digits. The
//! basic operations `+ − × ÷ √` have a relative error of a few units of
//! [`DoubleDouble::EPSILON`] `= 2⁻¹⁰⁴ ≈ 4.9·10⁻³²`; the elementary functions
//! are built to the same level on their principal domains: against mpmath,
//! on 300 random arguments per function (`exp` on `±700`, `sin`/`cos`/`tan`
//! on `±10⁴`, logarithms and roots on `10^±300`, …), the worst relative
//! error was `1.2·2⁻¹⁰⁴` (the unit tests assert `10⁻³⁰ ≈ 20·2⁻¹⁰⁴` on fixed
//! tables). The exceptions are the spherical Bessel functions near their
//! zeros, whose closed forms cancel: there the error stays below 1% of the
//! function's own condition number times `2⁻¹⁰⁴`. The range is that of `f64`:
//! overflow and underflow happen where they happen for `hi`, and for
//! magnitudes below about `10⁻²⁹²` the low part becomes subnormal and
//! precision drops gradually (`exp(−700)` keeps about 100 bits).
//!
//! # Where the algorithms come from
//!
//! The error-free transformations are Knuth's two-sum, Dekker's fast two-sum
//! and a two-product through the fused multiply-add (Dekker 1971, "A
//! floating-point technique for extending the available precision"). Addition
//! is the accurate ("IEEE") variant, multiplication, division with a
//! correction step and the Newton iterations for `√`, `∛`, `ln` and `atan2`
//! follow Hida, Li and Bailey 2001, "Algorithms for quad-double precision
//! floating point arithmetic" (the QD library). Arguments of `sin`/`cos` are
//! reduced modulo `π/2` with a four-part `π/2`, so they keep full relative
//! accuracy far beyond `10⁴`; `exp` reduces by `ln 2` (three parts) and
//! halvings, then sums a Taylor series.
//!
//! # What it is for
//!
//! Verifying high-order integrators needs errors far below `f64`'s `10⁻¹⁶`:
//! convergence of order 16 is only visible down to `10⁻²⁶`. [`DoubleDouble`]
//! implements num-dual's [`DualNum`] with `Primitive = f64`, so it is a
//! [`Scalar`](crate::Scalar): a user Lagrangian, generic over `Scalar`, runs
//! on it unchanged, and num-dual's `Dual<DoubleDouble>` and
//! `HyperDual<DoubleDouble>` take its derivatives in double-double.
//!
//! ```
//! use lagrangian_runtime::{DoubleDouble, Scalar};
//!
//! // A generic function, as a user Lagrangian is written.
//! fn energy<D: Scalar>(q: D, v: D) -> D {
//!     v * v * 0.5 - q.cos()
//! }
//!
//! let q: DoubleDouble = "0.1".parse().unwrap();
//! let v: DoubleDouble = "0.3".parse().unwrap();
//! let e = energy(q, v);
//! // 0.045 − cos(0.1) to 40 digits (mpmath); f64 gets 16 of them right.
//! let reference: DoubleDouble = "-0.9500041652780257660955619878038702948386".parse().unwrap();
//! assert!(((e - reference) / reference).abs() < DoubleDouble::from(1e-31));
//! assert!((energy(0.1_f64, 0.3) - (-0.950_004_165_278_025_8)).abs() < 1e-15);
//! // Display prints 32 significant digits; the last may differ by one from the reference.
//! assert!(format!("{e}").starts_with("-9.500041652780257660955619878038"));
//! ```

use core::cmp::Ordering;
use core::f64::consts;
use core::fmt;
use core::iter::{Product, Sum};
use core::ops::{Add, AddAssign, Div, DivAssign, Mul, MulAssign, Neg, Rem, RemAssign, Sub, SubAssign};
use core::str::FromStr;

use num_dual::{DualNum, DualStruct, Mappable};
use num_traits::{FromPrimitive, Inv, Num, One, Signed, Zero};

mod functions;
mod text;

#[cfg(test)]
mod tests;

pub use text::ParseDoubleDoubleError;

/// A real number `hi + lo` with `|lo| ≤ ½ ulp(hi)`: about 106 significant bits.
///
/// See the [module documentation](self) for the precision, the range and the
/// sources of the algorithms. The value is always normalised; non-finite
/// values keep `lo = 0`. Comparisons are those of the real number `hi + lo`.
///
/// The elementary functions (`sqrt`, `exp`, `sin`, `atan2`, …) are the methods
/// of num-dual's [`DualNum`] trait, so bring it into scope
/// (`use lagrangian_runtime::num_dual::DualNum;`) to call them on a
/// `DoubleDouble` directly; generic code bounded by [`Scalar`](crate::Scalar)
/// has them already. Invalid arguments give NaN and overflow gives `±∞`, as
/// for `f64`; nothing panics.
#[derive(Clone, Copy, Debug, Default)]
pub struct DoubleDouble {
    hi: f64,
    lo: f64,
}

/// `s + e = a + b` exactly, with `s = fl(a + b)` (Knuth's two-sum).
#[inline(always)]
fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    let bb = s - a;
    (s, (a - (s - bb)) + (b - bb))
}

/// `s + e = a + b` exactly when `|a| ≥ |b|` or `a = 0` (Dekker's fast two-sum).
#[inline(always)]
fn quick_two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    (s, b - (s - a))
}

/// `p + e = a·b` exactly (barring under- and overflow), through the fused multiply-add.
#[inline(always)]
fn two_prod(a: f64, b: f64) -> (f64, f64) {
    let p = a * b;
    (p, a.mul_add(b, -p))
}

impl DoubleDouble {
    /// `0`.
    pub const ZERO: Self = Self { hi: 0.0, lo: 0.0 };
    /// `1`.
    pub const ONE: Self = Self { hi: 1.0, lo: 0.0 };
    /// `2⁻¹⁰⁴ ≈ 4.93·10⁻³²`, the relative accuracy unit of double-double arithmetic.
    pub const EPSILON: Self = Self { hi: 4.930380657631324e-32, lo: 0.0 };
    /// Not a number.
    pub const NAN: Self = Self { hi: f64::NAN, lo: 0.0 };
    /// `+∞`.
    pub const INFINITY: Self = Self { hi: f64::INFINITY, lo: 0.0 };
    /// `−∞`.
    pub const NEG_INFINITY: Self = Self { hi: f64::NEG_INFINITY, lo: 0.0 };
    /// `π`.
    pub const PI: Self = Self { hi: consts::PI, lo: 1.2246467991473532e-16 };
    /// `2π`.
    pub const TAU: Self = Self { hi: consts::TAU, lo: 2.4492935982947064e-16 };
    /// `π/2`.
    pub const FRAC_PI_2: Self = Self { hi: consts::FRAC_PI_2, lo: 6.123233995736766e-17 };
    /// `π/4`.
    pub const FRAC_PI_4: Self = Self { hi: consts::FRAC_PI_4, lo: 3.061616997868383e-17 };
    /// Euler's number `e`.
    pub const E: Self = Self { hi: consts::E, lo: 1.4456468917292502e-16 };
    /// `ln 2`.
    pub const LN_2: Self = Self { hi: consts::LN_2, lo: 2.3190468138462996e-17 };
    /// `ln 10`.
    pub const LN_10: Self = Self { hi: consts::LN_10, lo: -2.1707562233822494e-16 };
    /// `√2`.
    pub const SQRT_2: Self = Self { hi: consts::SQRT_2, lo: -9.667293313452913e-17 };

    /// `hi + lo`, normalised (the arguments need not be).
    #[inline]
    pub fn new(hi: f64, lo: f64) -> Self {
        let (s, e) = two_sum(hi, lo);
        Self::finite_or(s, e)
    }

    /// `(s, e)` when `s` is finite, else `(s, 0)`: keeps `inf`/`NaN` out of the
    /// low part, where the error-free transformations would turn `inf` into `NaN`.
    #[inline(always)]
    fn finite_or(s: f64, e: f64) -> Self {
        if s.is_finite() { Self { hi: s, lo: e } } else { Self { hi: s, lo: 0.0 } }
    }

    /// `a + b` through `quick_two_sum` (so `|a| ≥ |b|`); an infinite or NaN
    /// `a` is kept as it is, since `b` is then meaningless.
    #[inline(always)]
    fn quick(a: f64, b: f64) -> Self {
        if !a.is_finite() {
            return Self { hi: a, lo: 0.0 };
        }
        let (s, e) = quick_two_sum(a, b);
        Self::finite_or(s, e)
    }

    /// The leading part, `fl(hi + lo)`.
    #[inline]
    pub const fn hi(self) -> f64 {
        self.hi
    }

    /// The trailing part, `|lo| ≤ ½ ulp(hi)`.
    #[inline]
    pub fn lo(self) -> f64 {
        self.lo
    }

    /// The nearest `f64` (which is `hi`).
    #[inline]
    pub fn to_f64(self) -> f64 {
        self.hi
    }

    /// `true` unless infinite or NaN.
    #[inline]
    pub fn is_finite(self) -> bool {
        self.hi.is_finite()
    }

    /// `true` for NaN.
    #[inline]
    pub fn is_nan(self) -> bool {
        self.hi.is_nan()
    }

    /// Absolute value.
    #[inline]
    pub fn abs(self) -> Self {
        if self.hi.is_sign_negative() { -self } else { self }
    }

    /// Largest integer not above `self`.
    pub fn floor(self) -> Self {
        let hi = self.hi.floor();
        if hi == self.hi {
            // `hi` is already an integer, so the fractional part is in `lo`.
            Self::quick(hi, self.lo.floor())
        } else {
            Self { hi, lo: 0.0 }
        }
    }

    /// Smallest integer not below `self`.
    pub fn ceil(self) -> Self {
        -(-self).floor()
    }

    /// Integer part, rounding toward zero.
    pub fn trunc(self) -> Self {
        if self.hi.is_sign_negative() { self.ceil() } else { self.floor() }
    }

    /// Nearest integer, ties away from zero (as [`f64::round`]).
    pub fn round(self) -> Self {
        let t = self.trunc();
        let frac = (self - t).abs();
        if frac >= Self::from(0.5) { if self.hi.is_sign_negative() { t - 1.0 } else { t + 1.0 } } else { t }
    }

    /// `self · 2ⁿ`, exact unless the result over- or underflows.
    pub fn ldexp(self, n: i32) -> Self {
        let (hi, lo) = (ldexp(self.hi, n), ldexp(self.lo, n));
        Self::finite_or(hi, lo)
    }

    /// `self²`, slightly cheaper than `self * self`.
    #[inline]
    pub fn square(self) -> Self {
        let (p, e) = two_prod(self.hi, self.hi);
        let e = e + 2.0 * self.hi * self.lo + self.lo * self.lo;
        Self::quick(p, e)
    }

    /// Product with an `f64`, more accurate and cheaper than converting it first.
    #[inline]
    pub fn mul_f64(self, b: f64) -> Self {
        let (p, e) = two_prod(self.hi, b);
        Self::quick(p, self.lo.mul_add(b, e))
    }

    /// Quotient by an `f64`, with one correction step.
    #[inline]
    pub fn div_f64(self, b: f64) -> Self {
        let q1 = self.hi / b;
        if !q1.is_finite() || q1 == 0.0 {
            return Self::from(q1);
        }
        // r = self − q1·b exactly in double-double, then the correction q2 = r/b.
        let (p, e) = two_prod(q1, b);
        let (s, t) = two_sum(self.hi, -p);
        let r = s + (t - e + self.lo);
        Self::quick(q1, r / b)
    }

    /// Sum with an `f64`.
    #[inline]
    pub fn add_f64(self, b: f64) -> Self {
        let (s, e) = two_sum(self.hi, b);
        if !s.is_finite() {
            return Self::from(s);
        }
        Self::quick(s, e + self.lo)
    }
}

/// `x · 2ⁿ` for an `f64`, in two exact steps so that neither intermediate
/// power of two over- or underflows.
fn ldexp(x: f64, n: i32) -> f64 {
    fn pow2(k: i32) -> f64 {
        // k in [-1022, 1023]: a normal power of two built from its exponent bits.
        f64::from_bits(((k + 1023) as u64) << 52)
    }
    let n = n.clamp(-2200, 2200);
    if (-1022..=1023).contains(&n) {
        x * pow2(n)
    } else {
        let half = n / 2;
        let rest = n - half;
        let (a, b) = (half.clamp(-1022, 1023), rest.clamp(-1022, 1023));
        x * pow2(a) * pow2(b)
    }
}

impl From<f64> for DoubleDouble {
    #[inline]
    fn from(x: f64) -> Self {
        Self { hi: x, lo: 0.0 }
    }
}

impl From<f32> for DoubleDouble {
    #[inline]
    fn from(x: f32) -> Self {
        Self::from(f64::from(x))
    }
}

impl From<i32> for DoubleDouble {
    #[inline]
    fn from(x: i32) -> Self {
        Self::from(f64::from(x))
    }
}

impl Neg for DoubleDouble {
    type Output = Self;
    #[inline]
    fn neg(self) -> Self {
        Self { hi: -self.hi, lo: -self.lo }
    }
}

impl Neg for &DoubleDouble {
    type Output = DoubleDouble;
    #[inline]
    fn neg(self) -> DoubleDouble {
        -*self
    }
}

/// The accurate ("IEEE") addition of QD: both pairs of parts are summed
/// error-free, so cancellation of the leading parts loses nothing.
impl Add for DoubleDouble {
    type Output = Self;
    #[inline]
    fn add(self, b: Self) -> Self {
        let (s1, s2) = two_sum(self.hi, b.hi);
        if !s1.is_finite() {
            return Self::from(s1);
        }
        let (t1, t2) = two_sum(self.lo, b.lo);
        let (s1, s2) = quick_two_sum(s1, s2 + t1);
        Self::quick(s1, s2 + t2)
    }
}

impl Sub for DoubleDouble {
    type Output = Self;
    #[inline]
    fn sub(self, b: Self) -> Self {
        self + (-b)
    }
}

impl Mul for DoubleDouble {
    type Output = Self;
    #[inline]
    fn mul(self, b: Self) -> Self {
        let (p, e) = two_prod(self.hi, b.hi);
        if !p.is_finite() {
            return Self::from(p);
        }
        let e = e + self.hi.mul_add(b.lo, self.lo * b.hi);
        Self::quick(p, e)
    }
}

/// Long division with one correction step (QD's accurate division): three
/// `f64` quotient digits, the last two from the exact remainders.
impl Div for DoubleDouble {
    type Output = Self;
    #[inline]
    fn div(self, b: Self) -> Self {
        let q1 = self.hi / b.hi;
        if !q1.is_finite() || q1 == 0.0 {
            // Division by zero, by infinity, of infinity, or NaN: as f64.
            return Self::from(q1);
        }
        let r = self - b.mul_f64(q1);
        let q2 = r.hi / b.hi;
        let r = r - b.mul_f64(q2);
        let q3 = r.hi / b.hi;
        Self::quick(q1, q2).add_f64(q3)
    }
}

/// `x − trunc(x/y)·y`, with the sign of `x`, like `f64`'s `%`.
impl Rem for DoubleDouble {
    type Output = Self;
    #[inline]
    fn rem(self, b: Self) -> Self {
        if !self.is_finite() || b.hi == 0.0 || b.is_nan() {
            return Self::NAN;
        }
        if !b.is_finite() {
            return self;
        }
        let n = (self / b).trunc();
        // An integer quotient below 2⁵³ multiplies exactly in its leading part.
        let r = if n.lo == 0.0 { self - b.mul_f64(n.hi) } else { self - n * b };
        // The quotient may round to the next integer; bring the remainder back into (−|b|, |b|).
        if r.hi != 0.0 && r.hi.is_sign_negative() != self.hi.is_sign_negative() {
            if (r.hi < 0.0) == (b.hi < 0.0) { r - b } else { r + b }
        } else {
            r
        }
    }
}

macro_rules! forward_binop {
    ($op:ident, $method:ident, $assign:ident, $assign_method:ident) => {
        impl<'a> $op<&'a DoubleDouble> for DoubleDouble {
            type Output = DoubleDouble;
            #[inline]
            fn $method(self, b: &'a DoubleDouble) -> DoubleDouble {
                $op::$method(self, *b)
            }
        }

        impl<'a> $op<DoubleDouble> for &'a DoubleDouble {
            type Output = DoubleDouble;
            #[inline]
            fn $method(self, b: DoubleDouble) -> DoubleDouble {
                $op::$method(*self, b)
            }
        }

        impl<'a, 'b> $op<&'b DoubleDouble> for &'a DoubleDouble {
            type Output = DoubleDouble;
            #[inline]
            fn $method(self, b: &'b DoubleDouble) -> DoubleDouble {
                $op::$method(*self, *b)
            }
        }

        impl $assign for DoubleDouble {
            #[inline]
            fn $assign_method(&mut self, b: DoubleDouble) {
                *self = $op::$method(*self, b);
            }
        }

        impl<'a> $assign<&'a DoubleDouble> for DoubleDouble {
            #[inline]
            fn $assign_method(&mut self, b: &'a DoubleDouble) {
                *self = $op::$method(*self, *b);
            }
        }

        impl $assign<f64> for DoubleDouble {
            #[inline]
            fn $assign_method(&mut self, b: f64) {
                *self = $op::$method(*self, b);
            }
        }

        impl $op<DoubleDouble> for f64 {
            type Output = DoubleDouble;
            #[inline]
            fn $method(self, b: DoubleDouble) -> DoubleDouble {
                $op::$method(DoubleDouble::from(self), b)
            }
        }
    };
}

forward_binop!(Add, add, AddAssign, add_assign);
forward_binop!(Sub, sub, SubAssign, sub_assign);
forward_binop!(Mul, mul, MulAssign, mul_assign);
forward_binop!(Div, div, DivAssign, div_assign);
forward_binop!(Rem, rem, RemAssign, rem_assign);

impl Add<f64> for DoubleDouble {
    type Output = Self;
    #[inline]
    fn add(self, b: f64) -> Self {
        self.add_f64(b)
    }
}

impl Sub<f64> for DoubleDouble {
    type Output = Self;
    #[inline]
    fn sub(self, b: f64) -> Self {
        self.add_f64(-b)
    }
}

impl Mul<f64> for DoubleDouble {
    type Output = Self;
    #[inline]
    fn mul(self, b: f64) -> Self {
        if !b.is_finite() {
            return self * Self::from(b);
        }
        self.mul_f64(b)
    }
}

impl Div<f64> for DoubleDouble {
    type Output = Self;
    #[inline]
    fn div(self, b: f64) -> Self {
        self.div_f64(b)
    }
}

impl Rem<f64> for DoubleDouble {
    type Output = Self;
    #[inline]
    fn rem(self, b: f64) -> Self {
        self % Self::from(b)
    }
}

impl Inv for DoubleDouble {
    type Output = Self;
    #[inline]
    fn inv(self) -> Self {
        Self::ONE / self
    }
}

impl Zero for DoubleDouble {
    #[inline]
    fn zero() -> Self {
        Self::ZERO
    }

    #[inline]
    fn is_zero(&self) -> bool {
        self.hi == 0.0
    }
}

impl One for DoubleDouble {
    #[inline]
    fn one() -> Self {
        Self::ONE
    }

    #[inline]
    fn is_one(&self) -> bool {
        self.hi == 1.0 && self.lo == 0.0
    }
}

impl Num for DoubleDouble {
    type FromStrRadixErr = ParseDoubleDoubleError;

    /// Parses digits in `radix` (2 to 36) with an optional sign and fraction;
    /// in radix 10 also an exponent, `inf` and `NaN` (see [`FromStr`]).
    fn from_str_radix(s: &str, radix: u32) -> Result<Self, Self::FromStrRadixErr> {
        text::parse(s, radix)
    }
}

impl FromStr for DoubleDouble {
    type Err = ParseDoubleDoubleError;

    /// Parses a decimal number such as `-3.14159265358979323846264338327950288e0`
    /// to double-double accuracy (a few units of [`DoubleDouble::EPSILON`]);
    /// also `inf`, `infinity` and `nan`, in any case.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        text::parse(s, 10)
    }
}

impl Signed for DoubleDouble {
    #[inline]
    fn abs(&self) -> Self {
        DoubleDouble::abs(*self)
    }

    #[inline]
    fn abs_sub(&self, other: &Self) -> Self {
        if *self > *other { *self - *other } else { Self::ZERO }
    }

    #[inline]
    fn signum(&self) -> Self {
        if self.is_nan() {
            Self::NAN
        } else if self.hi > 0.0 {
            Self::ONE
        } else if self.hi < 0.0 {
            -Self::ONE
        } else {
            Self::ZERO
        }
    }

    #[inline]
    fn is_positive(&self) -> bool {
        self.hi > 0.0
    }

    #[inline]
    fn is_negative(&self) -> bool {
        self.hi < 0.0
    }
}

impl Sum for DoubleDouble {
    fn sum<I: Iterator<Item = Self>>(iter: I) -> Self {
        iter.fold(Self::ZERO, |acc, x| acc + x)
    }
}

impl<'a> Sum<&'a DoubleDouble> for DoubleDouble {
    fn sum<I: Iterator<Item = &'a DoubleDouble>>(iter: I) -> Self {
        iter.fold(Self::ZERO, |acc, x| acc + *x)
    }
}

impl Product for DoubleDouble {
    fn product<I: Iterator<Item = Self>>(iter: I) -> Self {
        iter.fold(Self::ONE, |acc, x| acc * x)
    }
}

impl<'a> Product<&'a DoubleDouble> for DoubleDouble {
    fn product<I: Iterator<Item = &'a DoubleDouble>>(iter: I) -> Self {
        iter.fold(Self::ONE, |acc, x| acc * *x)
    }
}

/// Integers up to 106 bits are converted exactly (`hi` the rounded value, `lo` the rest).
impl FromPrimitive for DoubleDouble {
    fn from_i64(n: i64) -> Option<Self> {
        Self::from_i128(i128::from(n))
    }

    fn from_u64(n: u64) -> Option<Self> {
        Self::from_i128(i128::from(n))
    }

    fn from_i128(n: i128) -> Option<Self> {
        let hi = n as f64;
        // `hi as i128` saturates only at ±2¹²⁷, where the neglected unit is far below `lo`'s precision.
        let lo = n.wrapping_sub(hi as i128) as f64;
        Some(Self::new(hi, lo))
    }

    fn from_u128(n: u128) -> Option<Self> {
        let hi = n as f64;
        let lo = (n.wrapping_sub(hi as u128) as i128) as f64;
        Some(Self::new(hi, lo))
    }

    fn from_f32(x: f32) -> Option<Self> {
        Some(Self::from(x))
    }

    fn from_f64(x: f64) -> Option<Self> {
        Some(Self::from(x))
    }
}

/// Equal when the real numbers `hi + lo` are (the representation is normalised).
impl PartialEq for DoubleDouble {
    #[inline]
    fn eq(&self, other: &Self) -> bool {
        self.hi == other.hi && self.lo == other.lo
    }
}

impl PartialEq<f64> for DoubleDouble {
    #[inline]
    fn eq(&self, other: &f64) -> bool {
        self.hi == *other && self.lo == 0.0
    }
}

/// The order of the real numbers: `(hi, lo)` compared lexicographically.
impl PartialOrd for DoubleDouble {
    #[inline]
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        match self.hi.partial_cmp(&other.hi)? {
            Ordering::Equal => self.lo.partial_cmp(&other.lo),
            ord => Some(ord),
        }
    }
}

impl PartialOrd<f64> for DoubleDouble {
    #[inline]
    fn partial_cmp(&self, other: &f64) -> Option<Ordering> {
        self.partial_cmp(&Self::from(*other))
    }
}

impl PartialEq<DoubleDouble> for f64 {
    #[inline]
    fn eq(&self, other: &DoubleDouble) -> bool {
        other == self
    }
}

impl PartialOrd<DoubleDouble> for f64 {
    #[inline]
    fn partial_cmp(&self, other: &DoubleDouble) -> Option<Ordering> {
        DoubleDouble::from(*self).partial_cmp(other)
    }
}

impl DualStruct for DoubleDouble {
    type Real = f64;
    type Inner = Self;

    #[inline]
    fn re(&self) -> f64 {
        self.hi
    }

    #[inline]
    fn from_inner(inner: &Self) -> Self {
        *inner
    }
}

impl Mappable<Self> for DoubleDouble {
    type Output<O> = O;

    #[inline]
    fn map_dual<M: Fn(Self) -> O, O>(self, f: M) -> O {
        f(self)
    }
}

/// Scientific notation with 32 significant digits, or `precision` digits
/// after the point when one is given (`{:.40}`); `{:e}` is the same.
impl fmt::Display for DoubleDouble {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        text::write_scientific(*self, f)
    }
}

impl fmt::LowerExp for DoubleDouble {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        text::write_scientific(*self, f)
    }
}

/// Every function to double-double accuracy; the derivative-free base of
/// `Dual<DoubleDouble>` and `HyperDual<DoubleDouble>`.
impl DualNum for DoubleDouble {
    type Primitive = f64;
    const NDERIV: usize = 0;
    type InnerDual = Self;

    #[inline]
    fn from_re(re: Self) -> Self {
        re
    }

    #[inline]
    fn scale(self, factor: &Self) -> Self {
        self * *factor
    }

    #[inline]
    fn recip(&self) -> Self {
        Self::ONE / *self
    }

    fn powi(&self, n: i32) -> Self {
        functions::powi(*self, n)
    }

    fn powf(&self, n: f64) -> Self {
        functions::powf(*self, n)
    }

    fn sqrt(&self) -> Self {
        functions::sqrt(*self)
    }

    fn cbrt(&self) -> Self {
        functions::cbrt(*self)
    }

    fn exp(&self) -> Self {
        functions::exp(*self)
    }

    fn exp2(&self) -> Self {
        functions::exp2(*self)
    }

    fn exp_m1(&self) -> Self {
        functions::exp_m1(*self)
    }

    fn ln(&self) -> Self {
        functions::ln(*self)
    }

    fn log(&self, base: f64) -> Self {
        functions::ln(*self) / functions::ln(Self::from(base))
    }

    fn log2(&self) -> Self {
        functions::log2(*self)
    }

    fn log10(&self) -> Self {
        functions::ln(*self) / Self::LN_10
    }

    fn ln_1p(&self) -> Self {
        functions::ln_1p(*self)
    }

    fn sin(&self) -> Self {
        functions::sin_cos(*self).0
    }

    fn cos(&self) -> Self {
        functions::sin_cos(*self).1
    }

    fn tan(&self) -> Self {
        let (s, c) = functions::sin_cos(*self);
        s / c
    }

    fn sin_cos(&self) -> (Self, Self) {
        functions::sin_cos(*self)
    }

    fn asin(&self) -> Self {
        functions::asin(*self)
    }

    fn acos(&self) -> Self {
        functions::acos(*self)
    }

    fn atan(&self) -> Self {
        functions::atan2(*self, Self::ONE)
    }

    fn atan2(&self, other: Self) -> Self {
        functions::atan2(*self, other)
    }

    fn sinh(&self) -> Self {
        functions::sinh(*self)
    }

    fn cosh(&self) -> Self {
        functions::cosh(*self)
    }

    fn tanh(&self) -> Self {
        functions::tanh(*self)
    }

    fn asinh(&self) -> Self {
        functions::asinh(*self)
    }

    fn acosh(&self) -> Self {
        functions::acosh(*self)
    }

    fn atanh(&self) -> Self {
        functions::atanh(*self)
    }

    fn sph_j0(&self) -> Self {
        functions::sph_j(*self, 0)
    }

    fn sph_j1(&self) -> Self {
        functions::sph_j(*self, 1)
    }

    fn sph_j2(&self) -> Self {
        functions::sph_j(*self, 2)
    }

    #[inline]
    fn mul_add(&self, a: Self, b: Self) -> Self {
        *self * a + b
    }

    fn powd(&self, exp: Self) -> Self {
        functions::exp(functions::ln(*self) * exp)
    }
}
