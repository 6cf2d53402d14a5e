//! Serde for `[f64; N]` and `Vec<[f64; N]>` with any `N` (serde implements
//! arrays only up to a fixed length).

/// `Vec<[f64; N]>` as a sequence of sequences (serde implements arrays only
/// up to a fixed length, not for every `N`).
pub(crate) mod rows {
    use serde::{Deserialize, Deserializer, Serializer, de::Error};

    pub(crate) fn serialize<S: Serializer, const N: usize>(rows: &[[f64; N]], s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(rows.iter().map(|r| r.as_slice()))
    }

    pub(crate) fn deserialize<'de, D: Deserializer<'de>, const N: usize>(d: D) -> Result<Vec<[f64; N]>, D::Error> {
        Vec::<Vec<f64>>::deserialize(d)?
            .into_iter()
            .map(|r| r.try_into().map_err(|r: Vec<f64>| D::Error::invalid_length(r.len(), &"N values")))
            .collect()
    }
}

/// `[f64; N]` as a sequence.
pub(crate) mod array {
    use serde::{Deserialize, Deserializer, Serializer, de::Error};

    pub(crate) fn serialize<S: Serializer, const N: usize>(x: &[f64; N], s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(x.iter())
    }

    pub(crate) fn deserialize<'de, D: Deserializer<'de>, const N: usize>(d: D) -> Result<[f64; N], D::Error> {
        Vec::<f64>::deserialize(d)?.try_into().map_err(|r: Vec<f64>| D::Error::invalid_length(r.len(), &"N values"))
    }
}
