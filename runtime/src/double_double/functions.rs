//! Elementary functions in double-double: argument reduction to a small
//! interval, a series there, and reconstruction, each step accurate to a few
//! units of `2⁻¹⁰⁴` (Hida, Li and Bailey 2001 for the overall scheme).

use core::f64::consts;

use super::{DoubleDouble as DD, two_prod};

/// `π/2` as four non-overlapping `f64`: enough that `x − k·π/2` keeps full
/// relative accuracy even when it cancels to `10⁻¹⁶·|x|`.
const FRAC_PI_2_PARTS: [f64; 4] =
    [consts::FRAC_PI_2, 6.123233995736766e-17, -1.4973849048591698e-33, 5.562271104316826e-50];

/// `ln 2` as three non-overlapping `f64`, for the reduction of `exp`.
const LN_2_PARTS: [f64; 3] = [consts::LN_2, 2.3190468138462996e-17, 5.707708438416212e-34];

/// A series stops once its terms fall below this fraction of the sum (well under `2⁻¹⁰⁴`).
const SERIES_TOL: f64 = 1e-34;

/// Cap on the terms of any series: they all converge long before on their domains;
/// the cap only bounds the work for NaN arguments.
const MAX_TERMS: u32 = 80;

/// Binary powering of `|x|`; a negative power is the reciprocal of the
/// positive one, which is more accurate than powering the reciprocal. The
/// sign is applied last, so that an odd power of `−0` or of a negative
/// number whose power under- or overflows keeps it, as for `f64`.
pub(super) fn powi(x: DD, n: i32) -> DD {
    if n == 0 {
        return DD::ONE;
    }
    let negative = x.hi.is_sign_negative() && n % 2 != 0;
    let mut m = n.unsigned_abs();
    let mut base = x.abs();
    let mut acc = DD::ONE;
    loop {
        if m & 1 == 1 {
            acc *= base;
        }
        m >>= 1;
        if m == 0 {
            break;
        }
        base = base.square();
    }
    let v = if n < 0 { DD::ONE / acc } else { acc };
    if negative { -v } else { v }
}

/// `xⁿ` with the special values of `f64`'s `powf` (IEEE 754 `pow`):
/// through [`powi`] when `n` is an integer in `i32`, else `exp(n ln|x|)`
/// with the sign of an odd integer power of a negative `x`. `x⁰ = 1ⁿ = 1`
/// (NaN included), `|x|^{±∞}` is 1, 0 or ∞, zeros and infinities of
/// either sign give 0 or ∞, and a negative finite `x` with a non-integer
/// `n` gives NaN.
pub(super) fn powf(x: DD, n: f64) -> DD {
    if n == 0.0 || x == DD::ONE {
        return DD::ONE;
    }
    if x.is_nan() || n.is_nan() {
        return DD::NAN;
    }
    // `fract` of an infinity is NaN: not an integer.
    let integer = n.fract() == 0.0;
    if integer && n.abs() <= f64::from(i32::MAX) {
        return powi(x, n as i32);
    }
    let a = x.abs();
    if n.is_infinite() {
        return if a == DD::ONE {
            DD::ONE
        } else if (a.hi > 1.0) == (n > 0.0) {
            DD::INFINITY
        } else {
            DD::ZERO
        };
    }
    let zero_or_infinite = a.hi == 0.0 || !a.is_finite();
    if x.hi < 0.0 && !integer && !zero_or_infinite {
        return DD::NAN;
    }
    let magnitude = if zero_or_infinite {
        // 0ⁿ and ∞⁻ⁿ are 0 for n > 0; their reciprocals ∞.
        if (a.hi == 0.0) == (n > 0.0) { DD::ZERO } else { DD::INFINITY }
    } else {
        exp(ln(a).mul_f64(n))
    };
    // Beyond i32 an integer is odd only below 2⁵³ (every f64 above is even).
    let odd = integer && n % 2.0 != 0.0;
    if x.hi.is_sign_negative() && odd { -magnitude } else { magnitude }
}

/// One Newton step `s + (x − s²)/(2s)` from the correctly rounded `f64` root.
pub(super) fn sqrt(x: DD) -> DD {
    if x.hi == 0.0 {
        return x;
    }
    if x.hi < 0.0 || !x.is_finite() {
        return DD::from(x.hi.sqrt());
    }
    // Outside 2^±900 the residual x − s² would under- or overflow: scale by an even power of two.
    let k = exponent(x.hi);
    if k.abs() > 900 {
        let half = k / 2;
        return sqrt(x.ldexp(-2 * half)).ldexp(half);
    }
    let s = x.hi.sqrt();
    let (p, e) = two_prod(s, s);
    let r = x - DD::new(p, e);
    DD::new(s, r.hi / (2.0 * s))
}

/// Two Newton steps `y + (x − y³)/(3y²)` from the `f64` cube root.
pub(super) fn cbrt(x: DD) -> DD {
    if x.hi == 0.0 || !x.is_finite() {
        return DD::from(x.hi.cbrt());
    }
    // Outside 2^±600 the residual x − y³ would under- or overflow: scale by a power of 2³.
    let k = exponent(x.hi);
    if k.abs() > 600 {
        let third = k / 3;
        return cbrt(x.ldexp(-3 * third)).ldexp(third);
    }
    let a = x.abs();
    let mut y = DD::from(a.hi.cbrt());
    for _ in 0..2 {
        let r = a - y.square() * y;
        y = y + DD::from(r.hi / (3.0 * y.hi * y.hi));
    }
    if x.hi < 0.0 { -y } else { y }
}

/// `eˢ − 1` for `|s| ≲ 1`: halve `s` until `|s| ≤ 2⁻⁵`, sum the Taylor
/// series, and undo the halvings with `e ↦ 2e + e²` (which is
/// `e^{2s} − 1` from `e^s − 1` without cancellation).
fn expm1_reduced(s: DD) -> DD {
    let mut s = s;
    let mut halvings = 0;
    while s.hi.abs() > 0.03125 && halvings < 60 {
        s = s.ldexp(-1);
        halvings += 1;
    }
    let mut term = s;
    let mut sum = s;
    let mut n = 1.0;
    while n < f64::from(MAX_TERMS) {
        n += 1.0;
        term = (term * s).div_f64(n);
        sum += term;
        if term.hi.abs() <= sum.hi.abs() * SERIES_TOL {
            break;
        }
    }
    for _ in 0..halvings {
        sum = sum.ldexp(1) + sum.square();
    }
    sum
}

/// `eˣ = 2ᵏ·e^r` with `k = round(x/ln 2)`, `r = x − k ln 2` (three-part
/// `ln 2`, so `r` is exact to the last bit for every `k` in range).
pub(super) fn exp(x: DD) -> DD {
    if x.is_nan() {
        return DD::NAN;
    }
    if x.hi > 709.8 {
        return DD::INFINITY;
    }
    if x.hi < -746.0 {
        return DD::ZERO;
    }
    if x.hi == 0.0 {
        return DD::ONE;
    }
    let k = (x.hi / LN_2_PARTS[0]).round();
    let r = x - DD::from(LN_2_PARTS[0]).mul_f64(k) - DD::from(LN_2_PARTS[1]).mul_f64(k) - DD::from(LN_2_PARTS[2] * k);
    (expm1_reduced(r) + 1.0).ldexp(k as i32)
}

/// `eˣ − 1`, accurate near 0 (no `1 −` cancellation for `|x| < 1`).
pub(super) fn exp_m1(x: DD) -> DD {
    if x.is_nan() {
        return DD::NAN;
    }
    if x.hi == 0.0 {
        // ±0, its sign kept.
        return x;
    }
    if x.hi.abs() < 1.0 { expm1_reduced(x) } else { exp(x) - 1.0 }
}

/// `2ˣ = 2ⁿ·e^{(x−n) ln 2}` with `n = round(x)`: exact at integers.
pub(super) fn exp2(x: DD) -> DD {
    if x.is_nan() {
        return DD::NAN;
    }
    if x.hi > 1025.0 {
        return DD::INFINITY;
    }
    if x.hi < -1080.0 {
        return DD::ZERO;
    }
    let n = x.round();
    let f = x - n;
    exp(f * DD::LN_2).ldexp(n.hi as i32)
}

/// `2 atanh(s) = 2(s + s³/3 + s⁵/5 + …)` for `|s| ≤ 0.2`, which is `ln((1+s)/(1−s))`.
fn atanh_series(s: DD) -> DD {
    let s2 = s.square();
    let mut power = s;
    let mut sum = s;
    let mut k = 1.0;
    while k < f64::from(MAX_TERMS) {
        k += 2.0;
        power *= s2;
        let term = power.div_f64(k);
        sum += term;
        if term.hi.abs() <= sum.hi.abs() * SERIES_TOL {
            break;
        }
    }
    sum
}

/// The exponent `k` with `2ᵏ ≤ |h| < 2ᵏ⁺¹`, for finite non-zero `h`.
fn exponent(h: f64) -> i32 {
    let biased = ((h.to_bits() >> 52) & 0x7ff) as i32;
    if biased == 0 {
        // Subnormal: scale into the normal range first.
        exponent(h * 2f64.powi(54)) - 54
    } else {
        biased - 1023
    }
}

/// `x = 2ᵏ·m` with `m ∈ [1/√2, √2)` and `ln m = 2 atanh((m−1)/(m+1))`,
/// `|(m−1)/(m+1)| ≤ 0.172`. For positive finite `x`.
fn ln_split(x: DD) -> (i32, DD) {
    let mut k = exponent(x.hi);
    let mut m = x.ldexp(-k);
    if m.hi > consts::SQRT_2 {
        m = m.ldexp(-1);
        k += 1;
    }
    // m − 1 is exact (Sterbenz), so ln m keeps full relative accuracy near m = 1.
    let s = (m - 1.0) / (m + 1.0);
    (k, atanh_series(s).ldexp(1))
}

/// Natural logarithm: `k ln 2 + ln m` (see [`ln_split`]).
pub(super) fn ln(x: DD) -> DD {
    if x.is_nan() || x.hi < 0.0 {
        return DD::NAN;
    }
    if x.hi == 0.0 {
        return DD::NEG_INFINITY;
    }
    if !x.is_finite() {
        return x;
    }
    let (k, ln_m) = ln_split(x);
    if k == 0 { ln_m } else { DD::LN_2.mul_f64(f64::from(k)) + ln_m }
}

/// `log₂ x = k + ln m / ln 2`: exact for powers of two.
pub(super) fn log2(x: DD) -> DD {
    if x.is_nan() || x.hi <= 0.0 || !x.is_finite() {
        return DD::from(x.hi.log2());
    }
    let (k, ln_m) = ln_split(x);
    ln_m / DD::LN_2 + f64::from(k)
}

/// Below this `|x|`, `ln(1 + x) = x − x²/2` to far below `2⁻¹⁰⁴` (the next
/// term is `x³/3`), and `x/(2 + x)` of a subnormal `x` would round to zero.
const LN_1P_TINY: f64 = 1e-17;

/// `ln(1 + x)`, accurate near 0: `x − x²/2` for `|x| < 10⁻¹⁷` (±0 and
/// subnormals included, which the halving in `x/(2 + x)` would lose), the
/// series on `s = x/(2 + x)` for `x ∈ (−0.29, 0.41)` (where
/// `1 + x ∈ (1/√2, √2)`), else `ln(1 + x)`.
pub(super) fn ln_1p(x: DD) -> DD {
    if x.is_nan() {
        return DD::NAN;
    }
    if x.hi.abs() < LN_1P_TINY {
        return if x.hi == 0.0 { x } else { x - x.square().ldexp(-1) };
    }
    if x.hi > -0.29 && x.hi < 0.41 { atanh_series(x / (x + 2.0)).ldexp(1) } else { ln(x + 1.0) }
}

/// Above this `|x|` the quadrant is found by [`reduce_large`]: the rounded
/// `k = x·2/π` of the short reduction is no longer the nearest integer
/// (from `2^53·π/2` on it is not even an integer multiple of 1), and four
/// parts of `π/2` no longer cancel `x` to full accuracy.
const LARGE_ARGUMENT: f64 = 1_048_576.0; // 2^20

/// `(sin x, cos x)`: `x = k·π/2 + r` with `|r| ≲ π/4` (four-part `π/2` up to
/// 2^20, [`reduce_large`] beyond), the Taylor series of `sin r`,
/// `cos r = √(1 − sin² r)`, and the quadrant `k mod 4`.
pub(super) fn sin_cos(x: DD) -> (DD, DD) {
    if !x.is_finite() {
        return (DD::NAN, DD::NAN);
    }
    if x.hi == 0.0 {
        // sin(±0) = ±0.
        return (x, DD::ONE);
    }
    let (quadrant, r) = if x.hi.abs() < LARGE_ARGUMENT {
        let k = (x.hi * consts::FRAC_2_PI).round();
        let r = if k == 0.0 {
            x
        } else {
            let [p1, p2, p3, p4] = FRAC_PI_2_PARTS;
            x - DD::from(p1).mul_f64(k) - DD::from(p2).mul_f64(k) - DD::from(p3).mul_f64(k) - DD::from(p4 * k)
        };
        (k.rem_euclid(4.0) as u8, r)
    } else {
        reduce_large(x)
    };
    let r2 = r.square();
    let mut term = r;
    let mut s = r;
    let mut n = 1.0;
    while n < f64::from(MAX_TERMS) {
        term = (term * r2).div_f64(-(n + 1.0) * (n + 2.0));
        n += 2.0;
        s += term;
        if term.hi.abs() <= s.hi.abs() * SERIES_TOL {
            break;
        }
    }
    let c = sqrt((DD::ONE - s) * (DD::ONE + s));
    match quadrant {
        0 => (s, c),
        1 => (c, -s),
        2 => (-s, -c),
        _ => (-c, s),
    }
}

/// The first 1536 bits of `2/π`, most significant first: bit `p` of the
/// table is the coefficient of `2^−p`. Enough for any `f64`: an exponent of
/// up to `2^1023` skips its first ~970 bits and uses the next 256.
const FRAC_2_PI_BITS: [u64; 24] = [
    0xA2F9836E4E441529,
    0xFC2757D1F534DDC0,
    0xDB6295993C439041,
    0xFE5163ABDEBBC561,
    0xB7246E3A424DD2E0,
    0x06492EEA09D1921C,
    0xFE1DEB1CB129A73E,
    0xE88235F52EBB4484,
    0xE99C7026B45F7E41,
    0x3991D639835339F4,
    0x9C845F8BBDF9283B,
    0x1FF897FFDE05980F,
    0xEF2F118B5A0A6D1F,
    0x6D367ECF27CB09B7,
    0x4F463F669E5FEA2D,
    0x7527BAC7EBE5F17B,
    0x3D0739F78A5292EA,
    0x6BFB5FB11F8D5D08,
    0x56033046FC7B6BAB,
    0xF0CFBC209AF4361D,
    0xA9E391615EE61B08,
    0x6599855F14A06840,
    0x8DFFD8804D732731,
    0x06061556CA73A8C9,
];

/// A fixed-point number of quadrants, `x·2/π mod 4`: 256 bits, most
/// significant limb first, 2 integer bits and 254 fraction bits.
type Quadrants = [u64; 4];

/// Payne–Hanek reduction (Payne and Hanek, "Radian reduction for
/// trigonometric functions", 1983): `x = k·π/2 + r` with `|r| ≤ π/4` for any
/// finite `x`, as `(k mod 4, r)`.
///
/// Each part of `x = hi + lo` is an integer `m < 2^53` times `2^e`; only the
/// bits of `2/π` that can reach the last two integer bits and the fraction
/// of `m·2^e·2/π` matter, a 256-bit window, multiplied exactly in integers.
/// The two parts' products are added modulo 4, exactly; the tail of `2/π`
/// beyond the window adds under `2^−200` quadrants. The nearest quadrant is
/// then taken off and the remaining fraction (at least `2^−62` for any
/// double, Kahan and McDonald's worst case being near `2^−61`) is converted
/// with 128 significant bits and multiplied by `π/2`.
fn reduce_large(x: DD) -> (u8, DD) {
    let sum = add(quadrants(x.hi), quadrants(x.lo));
    // Round to the nearest quadrant: add one half, keep the integer bits.
    let k = (add(sum, [1 << 61, 0, 0, 0])[0] >> 62) as u8;
    let fraction = sub(sum, [u64::from(k) << 62, 0, 0, 0]);
    // Two's complement over 256 bits; |fraction| ≤ 1/2 quadrant.
    let negative = fraction[0] >> 63 == 1;
    let magnitude = if negative { sub([0; 4], fraction) } else { fraction };
    let r = to_dd(magnitude) * DD::FRAC_PI_2;
    (k, if negative { -r } else { r })
}

/// `a·2/π mod 4` for one `f64`, exactly up to the truncation of `2/π`.
fn quadrants(a: f64) -> Quadrants {
    if a == 0.0 {
        return [0; 4];
    }
    let bits = a.abs().to_bits();
    let biased = (bits >> 52) as i32;
    let fraction = bits & ((1 << 52) - 1);
    // `|a| = m·2^e` with an integer `m`; subnormals have no hidden bit.
    let (m, e) = if biased == 0 { (fraction, -1074) } else { (fraction | 1 << 52, biased - 1075) };
    // Bits `p ≤ e − 2` of `2/π` make multiples of 4: skip them.
    let skip = (e - 2).max(0) as usize;
    let window = frac_2_pi_window(skip);
    // `m × window`, 5 limbs, most significant first.
    let mut product = [0u64; 5];
    let mut carry = 0u128;
    for i in (0..4).rev() {
        let t = u128::from(m) * u128::from(window[i]) + carry;
        product[i + 1] = t as u64;
        carry = t >> 64;
    }
    product[0] = carry as u64;
    // The product is worth `product·2^(e − skip − 256)`; in units of 2^−254
    // that is `product·2^(e − skip − 2)`: for `e ≥ 2` the low 256 bits, for
    // smaller `e` the product shifted right by `2 − e`.
    let shift = if e >= 2 { 0 } else { (2 - e) as usize };
    let shifted = shift_right(product, shift);
    let out = [shifted[1], shifted[2], shifted[3], shifted[4]];
    if a < 0.0 { sub([0; 4], out) } else { out }
}

/// Bits `skip + 1 ..= skip + 256` of `2/π`.
fn frac_2_pi_window(skip: usize) -> [u64; 4] {
    let (limb, bit) = (skip / 64, skip % 64);
    let at = |i: usize| FRAC_2_PI_BITS.get(i).copied().unwrap_or(0);
    core::array::from_fn(|i| if bit == 0 { at(limb + i) } else { at(limb + i) << bit | at(limb + i + 1) >> (64 - bit) })
}

/// A 320-bit number shifted right by `shift` bits.
fn shift_right(x: [u64; 5], shift: usize) -> [u64; 5] {
    let (limbs, bit) = (shift / 64, shift % 64);
    // Limb `j` of `x` lands in limb `j + limbs`; none outside `0..5`.
    let at = |i: usize| i.checked_sub(limbs).and_then(|j| x.get(j)).copied().unwrap_or(0);
    core::array::from_fn(|i| {
        if bit == 0 { at(i) } else { at(i) >> bit | i.checked_sub(1).map_or(0, |i| at(i) << (64 - bit)) }
    })
}

/// `a + b mod 2^256`.
fn add(a: Quadrants, b: Quadrants) -> Quadrants {
    let mut out = [0; 4];
    let mut carry = false;
    for i in (0..4).rev() {
        let (s, c1) = a[i].overflowing_add(b[i]);
        let (s, c2) = s.overflowing_add(u64::from(carry));
        out[i] = s;
        carry = c1 || c2;
    }
    out
}

/// `a − b mod 2^256`.
fn sub(a: Quadrants, b: Quadrants) -> Quadrants {
    let mut out = [0; 4];
    let mut borrow = false;
    for i in (0..4).rev() {
        let (d, b1) = a[i].overflowing_sub(b[i]);
        let (d, b2) = d.overflowing_sub(u64::from(borrow));
        out[i] = d;
        borrow = b1 || b2;
    }
    out
}

/// A non-negative fixed-point number of quadrants (254 fraction bits) as a
/// double-double, from its leading 128 bits: 53 exact ones in `hi`, the
/// next 75 rounded into `lo` (relative error below `2^−127`).
fn to_dd(x: Quadrants) -> DD {
    let high = u128::from(x[0]) << 64 | u128::from(x[1]);
    let low = u128::from(x[2]) << 64 | u128::from(x[3]);
    // `top` holds the leading 128 bits; its last bit weighs `2^weight`.
    let (top, weight) = match (high, low) {
        (0, 0) => return DD::ZERO,
        (0, low) => {
            let lead = low.leading_zeros();
            (low << lead, -254 - lead as i32)
        }
        (high, low) => {
            let lead = high.leading_zeros();
            let top = if lead == 0 { high } else { high << lead | low >> (128 - lead) };
            (top, 128 - 254 - lead as i32)
        }
    };
    let hi = (top >> 75) as f64;
    let lo = (top & ((1 << 75) - 1)) as f64;
    DD::new(hi * 2f64.powi(weight + 75), lo * 2f64.powi(weight))
}

/// `atan2(y, x)`: special cases as for `f64`, then one Newton step on
/// `sin z = y/r` (or `cos z = x/r`, whichever is better conditioned) from the
/// `f64` angle.
pub(super) fn atan2(y: DD, x: DD) -> DD {
    if x.is_nan() || y.is_nan() {
        return DD::NAN;
    }
    let with_sign = |v: DD| if y.hi.is_sign_negative() { -v } else { v };
    if !x.is_finite() || !y.is_finite() {
        return match (x.is_finite(), y.is_finite()) {
            (false, false) => with_sign(if x.hi > 0.0 { DD::FRAC_PI_4 } else { DD::FRAC_PI_4.mul_f64(3.0) }),
            (true, false) => with_sign(DD::FRAC_PI_2),
            _ => with_sign(if x.hi > 0.0 { DD::ZERO } else { DD::PI }),
        };
    }
    if y.hi == 0.0 {
        return with_sign(if x.hi.is_sign_negative() { DD::PI } else { DD::ZERO });
    }
    if x.hi == 0.0 {
        return with_sign(DD::FRAC_PI_2);
    }
    // Scale both by the same power of two so that x² + y² neither over- nor underflows.
    let scale = exponent(x.hi.abs().max(y.hi.abs()));
    let (x, y) = (x.ldexp(-scale), y.ldexp(-scale));
    let r = sqrt(x.square() + y.square());
    let (xr, yr) = (x / r, y / r);
    let z = DD::from(y.hi.atan2(x.hi));
    let (s, c) = sin_cos(z);
    let v = if xr.hi.abs() > yr.hi.abs() { z + (yr - s) / c } else { z - (xr - c) / s };
    // An angle that underflows to zero keeps the sign of `y`, as for `f64`.
    if v.hi == 0.0 { with_sign(DD::ZERO) } else { v }
}

/// `√((1 − x)(1 + x))`: `1 − x²` without cancellation near `|x| = 1`.
fn sqrt_one_minus_square(x: DD) -> DD {
    sqrt((DD::ONE - x) * (DD::ONE + x))
}

/// `asin x = atan2(x, √(1 − x²))`.
pub(super) fn asin(x: DD) -> DD {
    if x.is_nan() || x.hi.abs() > 1.0 {
        return DD::NAN;
    }
    atan2(x, sqrt_one_minus_square(x))
}

/// `acos x = atan2(√(1 − x²), x)`.
pub(super) fn acos(x: DD) -> DD {
    if x.is_nan() || x.hi.abs() > 1.0 {
        return DD::NAN;
    }
    atan2(sqrt_one_minus_square(x), x)
}

/// Beyond this `|x|`, `e^{−|x|}` is below `10⁻³⁴` of `e^{|x|}` and is dropped.
const HYPERBOLIC_LARGE: f64 = 40.0;

/// `e^a/2` for large `a`: halving after `exp` is exact, and only where `e^a`
/// itself would overflow is `ln 2` subtracted first (which costs `a·2⁻¹⁰⁴`).
fn half_exp(a: DD) -> DD {
    if a.hi < 709.0 { exp(a).ldexp(-1) } else { exp(a - DD::LN_2) }
}

/// `sinh x = (e + e/(e + 1))/2` with `e = eˣ − 1`: no cancellation near 0.
pub(super) fn sinh(x: DD) -> DD {
    if x.is_nan() {
        return DD::NAN;
    }
    let a = x.abs();
    let v = if a.hi > HYPERBOLIC_LARGE {
        half_exp(a)
    } else {
        let e = exp_m1(a);
        (e + e / (e + 1.0)).ldexp(-1)
    };
    if x.hi.is_sign_negative() { -v } else { v }
}

/// `cosh x = (eˣ + e⁻ˣ)/2`.
pub(super) fn cosh(x: DD) -> DD {
    if x.is_nan() {
        return DD::NAN;
    }
    let a = x.abs();
    if a.hi > HYPERBOLIC_LARGE {
        half_exp(a)
    } else {
        let e = exp(a);
        (e + DD::ONE / e).ldexp(-1)
    }
}

/// `tanh x = e/(e + 2)` with `e = e^{2x} − 1`: no cancellation near 0.
pub(super) fn tanh(x: DD) -> DD {
    if x.is_nan() {
        return DD::NAN;
    }
    let a = x.abs();
    let v = if a.hi > HYPERBOLIC_LARGE {
        DD::ONE
    } else {
        let e = exp_m1(a.ldexp(1));
        e / (e + 2.0)
    };
    if x.hi.is_sign_negative() { -v } else { v }
}

/// Beyond this, `√(x² ± 1) = x` to far below `2⁻¹⁰⁴` and `x²` could overflow.
const INVERSE_HYPERBOLIC_LARGE: f64 = 1e18;

/// `asinh x = ln(1 + a + a²/(1 + √(1 + a²)))`, `a = |x|`: accurate near 0.
pub(super) fn asinh(x: DD) -> DD {
    if x.is_nan() {
        return DD::NAN;
    }
    let a = x.abs();
    let v = if a.hi > INVERSE_HYPERBOLIC_LARGE {
        ln(a) + DD::LN_2
    } else {
        let a2 = a.square();
        ln_1p(a + a2 / (sqrt(a2 + 1.0) + 1.0))
    };
    if x.hi.is_sign_negative() { -v } else { v }
}

/// `acosh x = ln(1 + t + √(t(t + 2)))`, `t = x − 1`: accurate near 1.
pub(super) fn acosh(x: DD) -> DD {
    if x.is_nan() || x.hi < 1.0 {
        return DD::NAN;
    }
    if x.hi > INVERSE_HYPERBOLIC_LARGE {
        return ln(x) + DD::LN_2;
    }
    let t = x - 1.0;
    ln_1p(t + sqrt(t * (t + 2.0)))
}

/// `atanh x`: its series for `|x| < 0.2`, else `ln((1 + x)/(1 − x))/2`.
pub(super) fn atanh(x: DD) -> DD {
    if x.is_nan() || x.hi.abs() > 1.0 {
        return DD::NAN;
    }
    if x.hi == 0.0 {
        // ±0, its sign kept (the series would add a `+0`).
        return x;
    }
    if x.hi.abs() < 0.2 { atanh_series(x) } else { ln_1p(x.ldexp(1) / (DD::ONE - x)).ldexp(-1) }
}

/// Spherical Bessel function `jₙ(x)`, `n ≤ 2`: for `|x| < 2` the series
/// `xⁿ Σₖ (−x²/2)ᵏ / (k! (2n + 2k + 1)!!)`, which avoids the cancellation of
/// the closed forms near 0; beyond, the closed forms in `sin` and `cos`.
pub(super) fn sph_j(x: DD, n: u32) -> DD {
    if x.is_nan() {
        return DD::NAN;
    }
    if x.hi.abs() < 2.0 {
        let x2 = x.square();
        let double_factorial = [1.0, 3.0, 15.0][n.min(2) as usize];
        let mut term = powi(x, n as i32).div_f64(double_factorial);
        let mut sum = term;
        for k in 0..MAX_TERMS {
            let k = f64::from(k);
            term = (term * x2).div_f64(-2.0 * (k + 1.0) * (2.0 * f64::from(n) + 2.0 * k + 3.0));
            sum += term;
            if term.hi.abs() <= sum.hi.abs() * SERIES_TOL {
                break;
            }
        }
        return sum;
    }
    let (s, c) = sin_cos(x);
    let inv = DD::ONE / x;
    match n {
        0 => s * inv,
        1 => (s * inv - c) * inv,
        _ => ((inv.square().mul_f64(3.0) - 1.0) * s - c.mul_f64(3.0) * inv) * inv,
    }
}
