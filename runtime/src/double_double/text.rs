//! Decimal (and other radix) parsing and scientific-notation printing.

use core::fmt;

use super::DoubleDouble as DD;
use super::functions::powi;

/// The error of parsing a [`DoubleDouble`](super::DoubleDouble) from a string
/// that is not a number in the expected form (or a radix outside `2..=36`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ParseDoubleDoubleError {
    _private: (),
}

const INVALID: ParseDoubleDoubleError = ParseDoubleDoubleError { _private: () };

impl fmt::Display for ParseDoubleDoubleError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("invalid double-double literal")
    }
}

impl std::error::Error for ParseDoubleDoubleError {}

/// `v · radixᵉ`, in steps that keep every power of the radix finite.
fn scale_by_power(v: DD, radix: u32, e: i64) -> DD {
    if v.hi == 0.0 || !v.is_finite() {
        return v;
    }
    let base = DD::from(f64::from(radix));
    // Largest step with radix^step < 10³⁰⁰.
    let step = (300.0 / f64::from(radix).log10()).floor() as i64;
    let mut v = v;
    let mut e = e;
    while e > step && v.is_finite() {
        v *= powi(base, step as i32);
        e -= step;
    }
    while e < -step && v.hi != 0.0 {
        v /= powi(base, step as i32);
        e += step;
    }
    let e = e.clamp(-step, step) as i32;
    if e >= 0 { v * powi(base, e) } else { v / powi(base, -e) }
}

/// Parses `[+-]digits[.digits][e[+-]digits]` (exponent in radix 10 only),
/// plus `inf`, `infinity` and `nan` in radix 10.
///
/// Digits are gathered in chunks that are exact `f64` integers and folded in
/// with one double-double multiply-add each, so the mantissa of up to 32
/// digits is exact; the power of ten is applied by one multiplication or
/// division. Digits past the 40th significant one are below `2⁻¹²⁰` and dropped.
pub(super) fn parse(s: &str, radix: u32) -> Result<DD, ParseDoubleDoubleError> {
    if !(2..=36).contains(&radix) {
        return Err(INVALID);
    }
    let (negative, body) = match s.as_bytes().first() {
        Some(b'-') => (true, &s[1..]),
        Some(b'+') => (false, &s[1..]),
        _ => (false, s),
    };
    let signed = |v: DD| if negative { -v } else { v };
    if radix == 10 {
        if body.eq_ignore_ascii_case("inf") || body.eq_ignore_ascii_case("infinity") {
            return Ok(signed(DD::INFINITY));
        }
        if body.eq_ignore_ascii_case("nan") {
            return Ok(DD::NAN);
        }
    }

    let max_significant = (120.0 / f64::from(radix).log2()).ceil() as u32;
    let chunk_limit = 2f64.powi(53) / f64::from(radix);
    let mut value = DD::ZERO;
    let mut chunk = 0.0;
    let mut chunk_scale = 1.0;
    let mut significant = 0;
    let mut exponent: i64 = 0;
    let mut any_digit = false;
    let mut seen_point = false;
    let bytes = body.as_bytes();
    let mut i = 0;
    while i < bytes.len() {
        let b = bytes[i];
        if b == b'.' && !seen_point {
            seen_point = true;
            i += 1;
            continue;
        }
        let Some(d) = char::from(b).to_digit(radix) else { break };
        any_digit = true;
        i += 1;
        if significant == 0 && d == 0 {
            // Leading zero: only shifts the exponent when after the point.
            if seen_point {
                exponent -= 1;
            }
            continue;
        }
        if significant < max_significant {
            chunk = chunk * f64::from(radix) + f64::from(d);
            chunk_scale *= f64::from(radix);
            significant += 1;
            if seen_point {
                exponent -= 1;
            }
            if chunk_scale > chunk_limit {
                value = value.mul_f64(chunk_scale) + chunk;
                chunk = 0.0;
                chunk_scale = 1.0;
            }
        } else if !seen_point {
            // A dropped integer digit still counts for the magnitude.
            exponent += 1;
        }
    }
    if !any_digit {
        return Err(INVALID);
    }
    value = value.mul_f64(chunk_scale) + chunk;

    if i < bytes.len() {
        if radix != 10 || !(bytes[i] == b'e' || bytes[i] == b'E') {
            return Err(INVALID);
        }
        i += 1;
        let exp_negative = match bytes.get(i) {
            Some(b'-') => {
                i += 1;
                true
            }
            Some(b'+') => {
                i += 1;
                false
            }
            _ => false,
        };
        if i >= bytes.len() {
            return Err(INVALID);
        }
        let mut e: i64 = 0;
        for &b in &bytes[i..] {
            let d = char::from(b).to_digit(10).ok_or(INVALID)?;
            // Saturate: anything this large over- or underflows anyway.
            e = (e * 10 + i64::from(d)).min(1_000_000);
        }
        exponent += if exp_negative { -e } else { e };
    }
    Ok(signed(scale_by_power(value, radix, exponent)))
}

/// Writes `x` as `d.ddd…e±n`: 32 significant digits, or `precision` digits
/// after the point (at most 60, far beyond the ~32 that are meaningful).
pub(super) fn write_scientific(x: DD, f: &mut fmt::Formatter<'_>) -> fmt::Result {
    if x.is_nan() {
        return f.write_str("NaN");
    }
    if x.hi.is_sign_negative() {
        f.write_str("-")?;
    }
    if x.hi.is_infinite() {
        return f.write_str("inf");
    }
    let after_point = f.precision().unwrap_or(31).min(60);
    // One extra digit decides the rounding.
    let mut digits = [0u8; 62];
    let n = after_point + 1;
    let mut e10 = 0;
    if x.hi != 0.0 {
        let a = x.abs();
        e10 = a.hi.log10().floor() as i64;
        let mut y = scale_by_power(a, 10, -e10);
        if y.hi >= 10.0 {
            y /= 10.0;
            e10 += 1;
        } else if y.hi < 1.0 {
            y *= 10.0;
            e10 -= 1;
        }
        for d in digits.iter_mut().take(n + 1) {
            let digit = y.floor().hi.clamp(0.0, 9.0);
            *d = digit as u8;
            y = (y - digit) * 10.0;
        }
        if digits[n] >= 5 {
            let mut i = n;
            loop {
                if i == 0 {
                    // 9.99…9 rounded up to 10.00…0.
                    digits[0] = 1;
                    e10 += 1;
                    break;
                }
                i -= 1;
                if digits[i] == 9 {
                    digits[i] = 0;
                } else {
                    digits[i] += 1;
                    break;
                }
            }
        }
    }
    let mut text = [0u8; 64];
    text[0] = b'0' + digits[0];
    let mut len = 1;
    if after_point > 0 {
        text[1] = b'.';
        len = 2;
        for &d in &digits[1..n] {
            text[len] = b'0' + d;
            len += 1;
        }
    }
    f.write_str(core::str::from_utf8(&text[..len]).map_err(|_| fmt::Error)?)?;
    write!(f, "e{e10}")
}
