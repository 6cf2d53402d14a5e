//! [`Parametric::NAMES`](crate::Parametric::NAMES) of a system with array
//! parameters: `m`, `u[0]`, `u[1]`, … built at compile time.
//!
//! `#[lagrangian(parameters(m, u: [f64; K]))]` knows `K` only as a constant
//! expression (a `const` item), so the macro cannot spell the entries'
//! names; these `const fn`s do, in three steps a constant item can hold:
//! the byte count of all names ([`len`]), the names written one after the
//! other into an array of that size ([`bytes`]), and that array cut into
//! `&'static str`s ([`split`]). A field is `(name, None)` for a scalar and
//! `(name, Some(K))` for an array.

/// A field of `parameters(...)`: its name, and its length if it is an array.
pub type Field<'a> = (&'a str, Option<usize>);

/// The number of decimal digits of `i`.
const fn digits(mut i: usize) -> usize {
    let mut n = 1;
    while i >= 10 {
        i /= 10;
        n += 1;
    }
    n
}

/// The bytes of the names of `fields`, one after the other.
pub const fn len(fields: &[Field<'_>]) -> usize {
    let mut total = 0;
    let mut f = 0;
    while f < fields.len() {
        let (name, entries) = fields[f];
        match entries {
            None => total += name.len(),
            Some(k) => {
                let mut i = 0;
                while i < k {
                    // `name[i]`
                    total += name.len() + 2 + digits(i);
                    i += 1;
                }
            }
        }
        f += 1;
    }
    total
}

/// The names of `fields` written one after the other; `B` is [`len`].
pub const fn bytes<const B: usize>(fields: &[Field<'_>]) -> [u8; B] {
    let mut out = [0u8; B];
    let mut at = 0;
    let mut f = 0;
    while f < fields.len() {
        let (name, entries) = fields[f];
        match entries {
            None => at = put(&mut out, at, name.as_bytes()),
            Some(k) => {
                let mut i = 0;
                while i < k {
                    at = put(&mut out, at, name.as_bytes());
                    at = put(&mut out, at, b"[");
                    let mut d = digits(i);
                    let mut rest = i;
                    while d > 0 {
                        d -= 1;
                        out[at + d] = b'0' + (rest % 10) as u8;
                        rest /= 10;
                    }
                    at += digits(i);
                    at = put(&mut out, at, b"]");
                    i += 1;
                }
            }
        }
        f += 1;
    }
    out
}

/// Copies `src` into `out` at `at`; returns the end.
const fn put(out: &mut [u8], at: usize, src: &[u8]) -> usize {
    let mut i = 0;
    while i < src.len() {
        out[at + i] = src[i];
        i += 1;
    }
    at + src.len()
}

/// `bytes`, written by [`bytes`] for `fields`, cut into the `P` names.
pub const fn split<const P: usize>(mut bytes: &'static [u8], fields: &[Field<'_>]) -> [&'static str; P] {
    let mut out = [""; P];
    let mut j = 0;
    let mut f = 0;
    while f < fields.len() {
        let (name, entries) = fields[f];
        let (count, mut i) = match entries {
            None => (1, 0),
            Some(k) => (k, 0),
        };
        while i < count {
            let n = match entries {
                None => name.len(),
                Some(_) => name.len() + 2 + digits(i),
            };
            let (head, tail) = bytes.split_at(n);
            out[j] = match core::str::from_utf8(head) {
                Ok(name) => name,
                // The bytes are field names (UTF-8), brackets and digits.
                Err(_) => panic!("parameter names are UTF-8"),
            };
            bytes = tail;
            j += 1;
            i += 1;
        }
        f += 1;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    const FIELDS: &[Field<'_>] = &[("m", None), ("u", Some(12)), ("g", None)];
    const BYTES: [u8; len(FIELDS)] = bytes(FIELDS);
    const NAMES: [&str; 14] = split(&BYTES, FIELDS);

    #[test]
    fn scalars_keep_their_name_and_array_entries_are_indexed() {
        let expected: Vec<String> = std::iter::once("m".to_string())
            .chain((0..12).map(|i| format!("u[{i}]")))
            .chain(std::iter::once("g".to_string()))
            .collect();
        assert_eq!(NAMES.to_vec(), expected);
        assert_eq!(len(&[("x", Some(0))]), 0);
        assert_eq!(digits(0), 1);
        assert_eq!(digits(9), 1);
        assert_eq!(digits(10), 2);
        assert_eq!(digits(1000), 4);
    }
}
