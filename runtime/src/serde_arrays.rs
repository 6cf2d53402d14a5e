//! Serde for the `f64` values of solutions: single numbers, `Option<f64>`
//! and sequences of them (the columns, and the rows of
//! [`Rows`](crate::Rows)), with every `f64` kept bit for bit.
//!
//! In human-readable formats (JSON, CSV) a finite number is written as a
//! number and a non-finite one as a string (JSON has no literal for them,
//! and `serde_json` would write `null`):
//!
//! | value | text |
//! |---|---|
//! | `+∞`, `−∞` | `"inf"`, `"-inf"` |
//! | the quiet NaN `0x7ff8000000000000` | `"NaN"` |
//! | the quiet NaN with the sign bit set, `0xfff8000000000000` | `"-NaN"` |
//! | any other NaN | `"NaN:0x"` and its 16 hexadecimal digits, e.g. `"NaN:0x7ff0000000000001"` |
//!
//! [`parse`] reads these texts (and, for CSV, finite numbers); binary
//! formats carry the `f64` itself.

use serde::de::{self, Deserialize, Deserializer, Visitor};
use serde::ser::{Serialize, Serializer};

/// The quiet NaN without payload (what `f64::NAN` is).
const QUIET_NAN: u64 = 0x7ff8_0000_0000_0000;
/// The sign bit of an `f64`.
const SIGN: u64 = 0x8000_0000_0000_0000;
/// The prefix of a NaN written with its bits.
const NAN_BITS: &str = "NaN:0x";

/// The text of a non-finite value (`None` for a finite one).
pub(crate) fn non_finite_text(x: f64) -> Option<String> {
    if x.is_finite() {
        return None;
    }
    Some(match x.to_bits() {
        _ if x == f64::INFINITY => "inf".to_string(),
        _ if x == f64::NEG_INFINITY => "-inf".to_string(),
        QUIET_NAN => "NaN".to_string(),
        b if b == QUIET_NAN | SIGN => "-NaN".to_string(),
        b => format!("{NAN_BITS}{b:016x}"),
    })
}

/// The value of a non-finite text written by [`non_finite_text`].
fn non_finite_value(text: &str) -> Option<f64> {
    match text {
        "inf" => Some(f64::INFINITY),
        "-inf" => Some(f64::NEG_INFINITY),
        "NaN" => Some(f64::from_bits(QUIET_NAN)),
        "-NaN" => Some(f64::from_bits(QUIET_NAN | SIGN)),
        _ => {
            let hex = text.strip_prefix(NAN_BITS)?;
            if hex.len() != 16 || !hex.bytes().all(|b| b.is_ascii_hexdigit()) {
                return None;
            }
            let x = f64::from_bits(u64::from_str_radix(hex, 16).ok()?);
            x.is_nan().then_some(x)
        }
    }
}

/// The value of a CSV field: a finite number (as Rust's `f64` parser reads
/// it) or one of the non-finite texts; `None` for anything else (among
/// them numbers that overflow to an infinity and other spellings of NaN).
pub(crate) fn parse(text: &str) -> Option<f64> {
    non_finite_value(text).or_else(|| text.parse::<f64>().ok().filter(|x| x.is_finite()))
}

/// One `f64`, written as the module docs say.
#[derive(Clone, Copy)]
pub(crate) struct Float(pub(crate) f64);

impl Serialize for Float {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match non_finite_text(self.0) {
            Some(text) if s.is_human_readable() => s.serialize_str(&text),
            _ => s.serialize_f64(self.0),
        }
    }
}

/// A slice of `f64` as a sequence of [`Float`]s.
pub(crate) struct Seq<'a>(pub(crate) &'a [f64]);

impl Serialize for Seq<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(self.0.iter().map(|&x| Float(x)))
    }
}

/// Reads a number or a non-finite text.
struct FloatVisitor;

impl Visitor<'_> for FloatVisitor {
    type Value = f64;

    fn expecting(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.write_str(r#"a number, or "inf", "-inf", "NaN", "-NaN" or "NaN:0x" and 16 hexadecimal digits"#)
    }

    fn visit_f64<E: de::Error>(self, x: f64) -> Result<f64, E> {
        Ok(x)
    }

    fn visit_i64<E: de::Error>(self, x: i64) -> Result<f64, E> {
        Ok(x as f64)
    }

    fn visit_u64<E: de::Error>(self, x: u64) -> Result<f64, E> {
        Ok(x as f64)
    }

    fn visit_str<E: de::Error>(self, text: &str) -> Result<f64, E> {
        non_finite_value(text).ok_or_else(|| E::invalid_value(de::Unexpected::Str(text), &self))
    }
}

impl<'de> Deserialize<'de> for Float {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        if d.is_human_readable() { d.deserialize_any(FloatVisitor).map(Float) } else { f64::deserialize(d).map(Float) }
    }
}

/// `f64` (for `#[serde(with = "…")]`).
pub(crate) mod float {
    use super::Float;
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    pub(crate) fn serialize<S: Serializer>(x: &f64, s: S) -> Result<S::Ok, S::Error> {
        Float(*x).serialize(s)
    }

    pub(crate) fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        Float::deserialize(d).map(|x| x.0)
    }
}

/// `Option<f64>`.
pub(crate) mod option {
    use super::Float;
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    pub(crate) fn serialize<S: Serializer>(x: &Option<f64>, s: S) -> Result<S::Ok, S::Error> {
        x.map(Float).serialize(s)
    }

    pub(crate) fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Option<f64>, D::Error> {
        Ok(Option::<Float>::deserialize(d)?.map(|x| x.0))
    }
}

/// `Vec<f64>` as a sequence.
pub(crate) mod column {
    use super::{Float, Seq};
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    pub(crate) fn serialize<S: Serializer>(x: &[f64], s: S) -> Result<S::Ok, S::Error> {
        Seq(x).serialize(s)
    }

    pub(crate) fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<f64>, D::Error> {
        Ok(Vec::<Float>::deserialize(d)?.into_iter().map(|x| x.0).collect())
    }
}
