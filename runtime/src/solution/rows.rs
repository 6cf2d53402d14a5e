//! The row table of a solution's `q`, `p` and `v`: rows of one width in
//! one flat buffer, so that a row costs no allocation of its own, whatever
//! the system's size (compile-time or run-time).

/// Rows of `width` values each, stored one after the other in one buffer.
///
/// Indexing gives a row as a slice (`rows[i][j]` is value `j` of row `i`),
/// and [`len`](Self::len), [`last`](Self::last), [`first`](Self::first),
/// [`get`](Self::get) and [`iter`](Self::iter) read it as a list of rows.
/// Pushing a row only grows the one buffer (amortised, as a `Vec` grows).
///
/// ```
/// use lagrangian_runtime::Rows;
///
/// let mut q = Rows::new(2);
/// q.push(&[1.0, 2.0]);
/// q.push(&[3.0, 4.0]);
/// assert_eq!((q.len(), q.width()), (2, 2));
/// assert_eq!(q[1][0], 3.0);
/// assert_eq!(q.last(), Some(&[3.0, 4.0][..]));
/// assert_eq!(q.iter().map(|row| row[1]).sum::<f64>(), 6.0);
/// ```
///
/// Two tables are equal when they hold the same rows: two empty tables are
/// equal whatever their widths (a table read back from a file without rows
/// has no width to read).
#[derive(Clone, Debug, Default)]
pub struct Rows {
    width: usize,
    rows: usize,
    values: Vec<f64>,
}

impl Rows {
    /// An empty table of rows of `width` values.
    pub fn new(width: usize) -> Self {
        Self { width, rows: 0, values: Vec::new() }
    }

    /// The number of values of a row.
    #[inline]
    pub fn width(&self) -> usize {
        self.width
    }

    /// The number of rows.
    #[inline]
    pub fn len(&self) -> usize {
        self.rows
    }

    /// `true` without rows.
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.rows == 0
    }

    /// Row `i`, if there is one.
    #[inline]
    pub fn get(&self, i: usize) -> Option<&[f64]> {
        (i < self.rows).then(|| &self.values[i * self.width..(i + 1) * self.width])
    }

    /// The first row.
    pub fn first(&self) -> Option<&[f64]> {
        self.get(0)
    }

    /// The last row.
    pub fn last(&self) -> Option<&[f64]> {
        self.rows.checked_sub(1).and_then(|i| self.get(i))
    }

    /// The rows in order.
    pub fn iter(&self) -> RowIter<'_> {
        RowIter { table: self, front: 0, back: self.rows }
    }

    /// Row `i` as an array, for a table whose width is the size `N` of a
    /// compile-time-sized system (`None` without row `i` or for another width).
    pub fn array<const N: usize>(&self, i: usize) -> Option<[f64; N]> {
        self.get(i)?.try_into().ok()
    }

    /// All values, row after row.
    pub fn as_flat(&self) -> &[f64] {
        &self.values
    }

    /// Appends a row.
    ///
    /// # Panics
    /// If `row` does not have [`width`](Self::width) values: a table holds
    /// rows of one width.
    #[inline]
    pub fn push(&mut self, row: &[f64]) {
        assert_eq!(row.len(), self.width, "a row of {} values in a table of width {}", row.len(), self.width);
        self.values.extend_from_slice(row);
        self.rows += 1;
    }

    /// Keeps the first `rows` rows.
    pub fn truncate(&mut self, rows: usize) {
        if rows < self.rows {
            self.rows = rows;
            self.values.truncate(rows * self.width);
        }
    }

    /// The table of `rows`, which must all have one width (`None` for
    /// rows of different widths; an empty list gives an empty table of width
    /// 0).
    pub fn from_rows<R: AsRef<[f64]>>(rows: impl IntoIterator<Item = R>) -> Option<Self> {
        let mut table: Option<Self> = None;
        for row in rows {
            let row = row.as_ref();
            let t = table.get_or_insert_with(|| Self::new(row.len()));
            if row.len() != t.width {
                return None;
            }
            t.push(row);
        }
        Some(table.unwrap_or_default())
    }
}

impl PartialEq for Rows {
    fn eq(&self, other: &Self) -> bool {
        self.rows == other.rows && (self.rows == 0 || (self.width == other.width && self.values == other.values))
    }
}

impl core::ops::Index<usize> for Rows {
    type Output = [f64];

    /// Row `i`.
    ///
    /// # Panics
    /// If there is no row `i`.
    #[inline]
    fn index(&self, i: usize) -> &[f64] {
        assert!(i < self.rows, "row {i} of a table of {} rows", self.rows);
        &self.values[i * self.width..(i + 1) * self.width]
    }
}

impl<'a> IntoIterator for &'a Rows {
    type Item = &'a [f64];
    type IntoIter = RowIter<'a>;

    fn into_iter(self) -> RowIter<'a> {
        self.iter()
    }
}

/// The rows of a [`Rows`] table in order ([`Rows::iter`]).
#[derive(Clone, Debug)]
pub struct RowIter<'a> {
    table: &'a Rows,
    front: usize,
    back: usize,
}

impl<'a> Iterator for RowIter<'a> {
    type Item = &'a [f64];

    fn next(&mut self) -> Option<&'a [f64]> {
        if self.front == self.back {
            return None;
        }
        self.front += 1;
        self.table.get(self.front - 1)
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        (self.back - self.front, Some(self.back - self.front))
    }
}

impl DoubleEndedIterator for RowIter<'_> {
    fn next_back(&mut self) -> Option<Self::Item> {
        if self.front == self.back {
            return None;
        }
        self.back -= 1;
        self.table.get(self.back)
    }
}

impl ExactSizeIterator for RowIter<'_> {}

/// A sequence of rows, each a sequence of numbers written as the solution's
/// other columns are (every `f64` bit for bit, the non-finite ones as
/// texts).
#[cfg(feature = "serde")]
impl serde::Serialize for Rows {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(self.iter().map(crate::serde_arrays::Seq))
    }
}

/// Reads what [`Serialize`](serde::Serialize) writes; rows of different
/// lengths are refused (the width is that of the first row).
#[cfg(feature = "serde")]
impl<'de> serde::Deserialize<'de> for Rows {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        use crate::serde_arrays::Float;
        use serde::de::Error;
        let rows = Vec::<Vec<Float>>::deserialize(d)?;
        let width = rows.first().map_or(0, Vec::len);
        let mut table = Self::new(width);
        table.values.reserve(width * rows.len());
        for (i, row) in rows.iter().enumerate() {
            if row.len() != width {
                return Err(D::Error::invalid_length(
                    row.len(),
                    &format!("{width} values in row {i}, as in row 0").as_str(),
                ));
            }
            table.values.extend(row.iter().map(|x| x.0));
            table.rows += 1;
        }
        Ok(table)
    }
}
