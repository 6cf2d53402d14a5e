//! Heap-stored step matrices for large systems: a banded LU with partial
//! pivoting and a dense LU, behind one small interface.
//!
//! The Newton Jacobian of a step is an `N × N` matrix. For small `N` the
//! stepper keeps it on the stack as an `SMatrix`; that is `O(N³)` work per
//! factorisation and overflows the stack for `N` in the hundreds. This module
//! stores the matrix on the heap, in buffers allocated once by the
//! constructor and reused by every [`clear`](StepMatrix::clear) /
//! [`add`](StepMatrix::add) / [`factor`](StepMatrix::factor) /
//! [`solve`](StepMatrix::solve) cycle, so a warm Newton loop allocates
//! nothing:
//!
//! - [`BandedMatrix`]: lower and upper bandwidths `kl`, `ku` in LAPACK band
//!   storage, factored by partial pivoting in `O(n·kl·(kl + ku))` and solved
//!   in `O(n·(2kl + ku))` (the `gbtrf`/`gbtrs` algorithms of LAPACK: Anderson
//!   et al., *LAPACK Users' Guide*; Golub & Van Loan, *Matrix Computations*,
//!   §4.3);
//! - [`DenseMatrix`]: a column-major `n × n` LU with partial pivoting,
//!   `O(n³)`, for the general pattern (an `N`-link pendulum);
//! - [`StepSolver`]: one of the two, chosen from a [`Pattern`] by
//!   [`StepSolver::for_pattern`].
//!
//! # Failures
//!
//! Every failure is a [`LinearSolveError`], never a panic or a NaN solution:
//! a NaN or infinite entry or right-hand side is
//! [`NonFinite`](LinearSolveError::NonFinite), a zero pivot is
//! [`Singular`](LinearSolveError::Singular) with `rcond = 0` (what
//! `newton.rs` reports for an exactly singular Jacobian), and when
//! `min_rcond > 0` a reciprocal condition number estimated below it is
//! `Singular` with that estimate, which is what the Newton stepper's
//! `Breakdown::Singular(rcond)` carries.
//!
//! # Condition estimate
//!
//! The 1-norm condition number is estimated on the factors by Hager's method
//! with Higham's refinements (Higham, *FORTRAN codes for estimating the
//! one-norm of a real or complex matrix*, ACM TOMS 14, 1988; LAPACK's
//! `dlacn2`): a few solves with `A` and `Aᵀ` give a lower bound on `‖A⁻¹‖₁`
//! that is almost always exact. The cheaper ratio of smallest to largest
//! `|Uᵢᵢ|` ([`Factorization::pivot_ratio`]) is reported too, but it does not
//! suffice: the upper bidiagonal matrix with `1` on the diagonal and `−2`
//! above it has all pivots equal to 1 and condition number above `2ⁿ` (a test
//! checks both numbers on it).
//!
//! # Entries outside the band
//!
//! Reading an entry outside the band gives `0` (it is structurally zero).
//! Writing a non-zero value there is a typed error,
//! [`OutsideBand`](LinearSolveError::OutsideBand), not a debug assertion: the
//! band comes from a pattern the macro proved, and if that proof were ever
//! wrong, dropping the entry silently would give a wrong Newton matrix in
//! release builds, where debug assertions are off. Writing an exact zero
//! there is allowed, so an assembly may loop over a dense block. The check
//! is one comparison per entry.
//!
//! # Which to choose
//!
//! [`StepSolver::for_pattern`] takes the banded solver for a banded or
//! diagonal pattern when [`prefers_banded`] (`n ≥ 8 (bandwidth + 1)`, from
//! the measurement documented there), and the dense one for a general
//! pattern or a smaller matrix.

use crate::structure::Pattern;

/// Whether the banded solver is expected to beat the dense one on an
/// `n × n` matrix of (symmetric) bandwidth `bandwidth`: `n ≥ 8 (bandwidth + 1)`.
///
/// Measured with `cargo bench -p lagrangian-bench --bench banded` (one run
/// on the 2-core machine under a load of about 7, so ±15 % noise):
/// assembling, factoring and solving costs the same in both solvers at
/// about `n = 12…16` for bandwidth 1, `16…24` for 2, `24…32` for 4 and
/// `48` for 8; below that the dense loops' lower overhead wins by up to
/// 3.6× (bandwidth 8, `n = 16`), above it the banded solver's `O(n b²)`
/// work wins by a growing factor (bandwidth 1, `n = 256`: 9.5 against
/// 148 µs). The rule sits at or just above each measured crossing, where
/// the two differ by little.
pub const fn prefers_banded(n: usize, bandwidth: usize) -> bool {
    n >= 8 * (bandwidth + 1)
}

/// What went wrong with a step matrix.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum LinearSolveError {
    /// An index at or beyond the dimension.
    #[error("entry ({i}, {j}) is outside the {n} × {n} matrix")]
    OutOfRange {
        /// Row.
        i: usize,
        /// Column.
        j: usize,
        /// Dimension.
        n: usize,
    },
    /// A non-zero value written outside the band.
    #[error("entry ({i}, {j}) = {value:e} lies outside the band (kl = {kl}, ku = {ku})")]
    OutsideBand {
        /// Row.
        i: usize,
        /// Column.
        j: usize,
        /// Lower bandwidth.
        kl: usize,
        /// Upper bandwidth.
        ku: usize,
        /// The value that was written.
        value: f64,
    },
    /// A NaN or an infinity: `quantity` is `matrix`, `factors` (overflow
    /// during elimination), `right-hand side` or `solution`.
    #[error("non-finite {quantity}")]
    NonFinite {
        /// Which value.
        quantity: &'static str,
    },
    /// A zero pivot (`rcond = 0`, `pivot` its column) or an estimated
    /// reciprocal condition number below the requested minimum (`pivot`
    /// `None`).
    #[error("singular or ill-conditioned matrix: reciprocal condition number {rcond:e}")]
    Singular {
        /// Estimated reciprocal condition number in the 1-norm (0 for a zero pivot).
        rcond: f64,
        /// The column of the zero pivot, if there was one.
        pivot: Option<usize>,
    },
    /// A vector whose length is not the dimension.
    #[error("vector of length {found} for a matrix of dimension {expected}")]
    DimensionMismatch {
        /// The dimension.
        expected: usize,
        /// The length given.
        found: usize,
    },
    /// `solve` before a successful `factor`.
    #[error("the matrix is not factored: `factor` it (successfully) before `solve`")]
    NotFactored,
    /// Reading or writing entries after `factor` (the storage holds the factors).
    #[error("the matrix holds its factors: `clear` it before assembling again")]
    Factored,
    /// The storage cannot be sized or allocated.
    #[error("cannot allocate a step matrix of dimension {n} with {per_column} stored entries per column")]
    TooLarge {
        /// Dimension.
        n: usize,
        /// Stored entries per column.
        per_column: usize,
    },
}

/// What a successful factorisation found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Factorization {
    /// `‖A‖₁`, the largest column sum of `|A|`.
    pub norm1: f64,
    /// Smallest `|Uᵢᵢ|` (the pivots of partial pivoting).
    pub min_pivot: f64,
    /// Largest `|Uᵢᵢ|`.
    pub max_pivot: f64,
    /// Estimated reciprocal condition number `1 / (‖A‖₁ ‖A⁻¹‖₁)`, when
    /// `factor` was asked for a positive `min_rcond` (`None` otherwise: the
    /// estimate costs a few solves).
    pub rcond: Option<f64>,
}

impl Factorization {
    /// `min |Uᵢᵢ| / max |Uᵢᵢ|` (1 for an empty matrix): free, but only a
    /// necessary sign of good conditioning (see the module documentation).
    pub fn pivot_ratio(&self) -> f64 {
        if self.max_pivot > 0.0 { self.min_pivot / self.max_pivot } else { 1.0 }
    }
}

/// A square matrix a Newton loop can assemble, factor and solve with,
/// reusing its storage: `clear`, `add` entries, `factor`, then `solve` any
/// number of right-hand sides.
pub trait StepMatrix {
    /// The dimension `n`.
    fn dim(&self) -> usize;
    /// Whether entry `(i, j)` is stored (inside the band; always for a dense matrix).
    fn may_couple(&self, i: usize, j: usize) -> bool;
    /// Sets every entry to zero and makes the matrix assemblable again.
    fn clear(&mut self);
    /// Adds `x` to entry `(i, j)`. Errors: an index out of range, a non-zero
    /// `x` outside the band, or a matrix holding its factors.
    fn add(&mut self, i: usize, j: usize, x: f64) -> Result<(), LinearSolveError>;
    /// LU factorisation with partial pivoting, in place. With
    /// `min_rcond > 0` the reciprocal condition number is estimated and a
    /// value below `min_rcond` is an error. After any error the storage
    /// holds neither the matrix nor usable factors: `clear` and assemble
    /// again.
    fn factor(&mut self, min_rcond: f64) -> Result<Factorization, LinearSolveError>;
    /// Overwrites `b` with `A⁻¹ b`; needs a successful `factor`.
    fn solve(&self, b: &mut [f64]) -> Result<(), LinearSolveError>;
    /// Overwrites `b` with `A⁻ᵀ b` (the same factors, transposed
    /// triangular solves: what a discrete adjoint needs); needs a
    /// successful `factor`.
    fn solve_transposed(&self, b: &mut [f64]) -> Result<(), LinearSolveError>;
}

/// Where a matrix is in its assemble–factor–solve cycle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Stage {
    Assembly,
    Factored,
    /// A factorisation failed part-way: the storage holds neither the matrix
    /// nor its factors.
    Spoiled,
}

/// A zeroed vector, allocated fallibly so that a huge `n` is an error, not an abort.
fn zeroed<T: Clone>(len: usize, zero: T, n: usize, per_column: usize) -> Result<Vec<T>, LinearSolveError> {
    let mut v = Vec::new();
    v.try_reserve_exact(len).map_err(|_| LinearSolveError::TooLarge { n, per_column })?;
    v.resize(len, zero);
    Ok(v)
}

/// Buffers of the condition estimate, allocated once.
#[derive(Clone, Debug)]
struct Workspace {
    x: Vec<f64>,
    sign: Vec<f64>,
    z: Vec<f64>,
}

impl Workspace {
    fn new(n: usize, per_column: usize) -> Result<Self, LinearSolveError> {
        Ok(Self {
            x: zeroed(n, 0.0, n, per_column)?,
            sign: zeroed(n, 0.0, n, per_column)?,
            z: zeroed(n, 0.0, n, per_column)?,
        })
    }
}

/// Triangular solves with the factors of `A`.
trait Factors {
    fn n(&self) -> usize;
    /// `b ← A⁻¹ b`.
    fn solve_plain(&self, b: &mut [f64]);
    /// `b ← A⁻ᵀ b`.
    fn solve_transposed(&self, b: &mut [f64]);
}

fn sign(x: f64) -> f64 {
    if x >= 0.0 { 1.0 } else { -1.0 }
}

fn norm1(x: &[f64]) -> f64 {
    x.iter().map(|v| v.abs()).sum()
}

/// Index of the largest `|x_i|` (the first one on ties).
fn argmax_abs(x: &[f64]) -> usize {
    let mut best = 0;
    let mut max = -1.0;
    for (i, v) in x.iter().enumerate() {
        if v.abs() > max {
            max = v.abs();
            best = i;
        }
    }
    best
}

/// Lower bound on `‖A⁻¹‖₁`, usually exact: Hager's iteration with Higham's
/// stopping rules and alternative estimate (the algorithm of `dlacn2`).
fn inverse_norm1<F: Factors>(f: &F, w: &mut Workspace) -> f64 {
    const MAX_ITERATIONS: usize = 5;
    let n = f.n();
    if n == 0 {
        return 0.0;
    }
    let (x, sign_x, z) = (&mut w.x[..n], &mut w.sign[..n], &mut w.z[..n]);
    x.fill(1.0 / n as f64);
    f.solve_plain(x);
    if n == 1 {
        return x[0].abs();
    }
    let mut estimate = norm1(x);
    for (s, v) in sign_x.iter_mut().zip(x.iter()) {
        *s = sign(*v);
    }
    z.copy_from_slice(sign_x);
    f.solve_transposed(z);
    let mut j = argmax_abs(z);
    for _ in 1..MAX_ITERATIONS {
        x.fill(0.0);
        x[j] = 1.0;
        f.solve_plain(x);
        let previous = estimate;
        estimate = norm1(x);
        let same_signs = x.iter().zip(sign_x.iter()).all(|(v, s)| sign(*v) == *s);
        if same_signs || estimate <= previous {
            // Converged (or cycling): keep the larger of the last two.
            estimate = estimate.max(previous);
            break;
        }
        for (s, v) in sign_x.iter_mut().zip(x.iter()) {
            *s = sign(*v);
        }
        z.copy_from_slice(sign_x);
        f.solve_transposed(z);
        let j_previous = j;
        j = argmax_abs(z);
        if z[j_previous].abs() == z[j].abs() {
            break;
        }
    }
    // Higham's alternative vector catches matrices that fool the iteration.
    for (i, v) in x.iter_mut().enumerate() {
        let magnitude = 1.0 + i as f64 / (n - 1) as f64;
        *v = if i % 2 == 0 { magnitude } else { -magnitude };
    }
    f.solve_plain(x);
    let alternative = 2.0 * norm1(x) / (3.0 * n as f64);
    estimate.max(alternative)
}

/// Checks a right-hand side, solves with `A` (or `Aᵀ` when `transposed`),
/// and checks the solution.
fn checked_solve<F: Factors>(f: &F, stage: Stage, b: &mut [f64], transposed: bool) -> Result<(), LinearSolveError> {
    if stage != Stage::Factored {
        return Err(LinearSolveError::NotFactored);
    }
    if b.len() != f.n() {
        return Err(LinearSolveError::DimensionMismatch { expected: f.n(), found: b.len() });
    }
    if !b.iter().all(|v| v.is_finite()) {
        return Err(LinearSolveError::NonFinite { quantity: "right-hand side" });
    }
    if transposed {
        f.solve_transposed(b);
    } else {
        f.solve_plain(b);
    }
    // Finite factors with non-zero pivots can still overflow on a tiny pivot.
    if !b.iter().all(|v| v.is_finite()) {
        return Err(LinearSolveError::NonFinite { quantity: "solution" });
    }
    Ok(())
}

/// Runs the condition estimate when asked for and turns it into the result.
fn finish<F: Factors>(
    f: &F,
    w: &mut Workspace,
    mut report: Factorization,
    min_rcond: f64,
) -> Result<Factorization, LinearSolveError> {
    if min_rcond > 0.0 {
        let inverse = inverse_norm1(f, w);
        let rcond = if report.norm1 == 0.0 || inverse == 0.0 { 1.0 } else { 1.0 / (report.norm1 * inverse) };
        report.rcond = Some(rcond);
        if rcond.is_nan() || rcond < min_rcond {
            return Err(LinearSolveError::Singular { rcond, pivot: None });
        }
    }
    Ok(report)
}

/// The LU factors of a band matrix in LAPACK band storage.
#[derive(Clone, Debug)]
struct BandLu {
    n: usize,
    kl: usize,
    ku: usize,
    /// Rows per stored column: `2 kl + ku + 1`.
    ldab: usize,
    /// Column-major: entry `(i, j)` at `ab[kl + ku + i − j + j·ldab]`; the
    /// first `kl` rows of each column are the fill-in of row interchanges.
    ab: Vec<f64>,
    /// Row `j` was exchanged with row `ipiv[j]` at elimination step `j`.
    ipiv: Vec<usize>,
}

impl BandLu {
    #[inline]
    fn index(&self, i: usize, j: usize) -> usize {
        self.kl + self.ku + i - j + j * self.ldab
    }

    #[inline]
    fn in_band(&self, i: usize, j: usize) -> bool {
        i <= j + self.kl && j <= i + self.ku
    }

    /// `gbtf2`: right-looking elimination, one column at a time. Returns the
    /// smallest and largest pivot magnitudes.
    fn factor(&mut self) -> Result<(f64, f64), LinearSolveError> {
        let (n, kl, ldab) = (self.n, self.kl, self.ldab);
        let kv = self.kl + self.ku;
        let stride = ldab - 1; // along a row of the band storage
        let (mut min_pivot, mut max_pivot) = (f64::INFINITY, 0.0_f64);
        // Last column touched by the row interchanges so far.
        let mut ju = 0;
        for j in 0..n {
            let km = kl.min(n - 1 - j);
            let col = kv + j * ldab;
            let p = argmax_abs(&self.ab[col..=col + km]);
            self.ipiv[j] = j + p;
            let pivot = self.ab[col + p];
            if pivot == 0.0 {
                return Err(LinearSolveError::Singular { rcond: 0.0, pivot: Some(j) });
            }
            if !pivot.is_finite() {
                return Err(LinearSolveError::NonFinite { quantity: "factors" });
            }
            min_pivot = min_pivot.min(pivot.abs());
            max_pivot = max_pivot.max(pivot.abs());
            ju = ju.max((j + self.ku + p).min(n - 1));
            if p != 0 {
                for c in 0..=ju - j {
                    self.ab.swap(col + c * stride, col + p + c * stride);
                }
            }
            if km == 0 {
                continue;
            }
            for v in &mut self.ab[col + 1..=col + km] {
                *v /= pivot;
            }
            // Rank-one update of the rows below the pivot, columns j+1..=ju.
            let (left, right) = self.ab.split_at_mut((j + 1) * ldab);
            let multipliers = &left[col + 1..=col + km];
            for c in 1..=ju - j {
                // Entry (j, j + c) in `right`, then the rows below it.
                let top = kv - c + (c - 1) * ldab;
                let u = right[top];
                if u != 0.0 {
                    for (a, l) in right[top + 1..=top + km].iter_mut().zip(multipliers) {
                        *a -= l * u;
                    }
                }
            }
        }
        Ok((if n == 0 { 0.0 } else { min_pivot }, max_pivot))
    }
}

impl Factors for BandLu {
    fn n(&self) -> usize {
        self.n
    }

    /// `gbtrs` without transpose: `L` with the interchanges interleaved, then `U`.
    fn solve_plain(&self, b: &mut [f64]) {
        let (n, kl, ldab) = (self.n, self.kl, self.ldab);
        let kv = self.kl + self.ku;
        if kl > 0 {
            for j in 0..n.saturating_sub(1) {
                let km = kl.min(n - 1 - j);
                let p = self.ipiv[j];
                if p != j {
                    b.swap(j, p);
                }
                let bj = b[j];
                let col = kv + j * ldab;
                for (bi, l) in b[j + 1..=j + km].iter_mut().zip(&self.ab[col + 1..=col + km]) {
                    *bi -= l * bj;
                }
            }
        }
        // U has upper bandwidth kv.
        for j in (0..n).rev() {
            let col = kv + j * ldab;
            let bj = b[j] / self.ab[col];
            b[j] = bj;
            let top = j.saturating_sub(kv);
            let first = col - (j - top);
            for (bi, u) in b[top..j].iter_mut().zip(&self.ab[first..col]) {
                *bi -= u * bj;
            }
        }
    }

    /// `gbtrs` with transpose: `Uᵀ`, then `Lᵀ` with the interchanges in reverse.
    fn solve_transposed(&self, b: &mut [f64]) {
        let (n, kl, ldab) = (self.n, self.kl, self.ldab);
        let kv = self.kl + self.ku;
        for j in 0..n {
            let col = kv + j * ldab;
            let top = j.saturating_sub(kv);
            let first = col - (j - top);
            let dot: f64 = b[top..j].iter().zip(&self.ab[first..col]).map(|(x, u)| x * u).sum();
            b[j] = (b[j] - dot) / self.ab[col];
        }
        if kl > 0 {
            for j in (0..n.saturating_sub(1)).rev() {
                let km = kl.min(n - 1 - j);
                let col = kv + j * ldab;
                let dot: f64 = b[j + 1..=j + km].iter().zip(&self.ab[col + 1..=col + km]).map(|(x, l)| x * l).sum();
                b[j] -= dot;
                let p = self.ipiv[j];
                if p != j {
                    b.swap(j, p);
                }
            }
        }
    }
}

/// An `n × n` matrix with lower bandwidth `kl` and upper bandwidth `ku`
/// (entry `(i, j)` may be non-zero for `j − ku ≤ i ≤ j + kl`), on the heap,
/// with its LU factorisation by partial pivoting in the same storage.
///
/// Storage is LAPACK's `gbtrf` layout: `2 kl + ku + 1` numbers per column,
/// the extra `kl` rows holding the fill-in of row interchanges, so `U` has
/// upper bandwidth `kl + ku`. Memory: `(2 kl + ku + 4) n` numbers with the
/// pivots and the buffers of the condition estimate, all allocated by
/// [`new`](BandedMatrix::new).
#[derive(Clone, Debug)]
pub struct BandedMatrix {
    lu: BandLu,
    work: Workspace,
    stage: Stage,
    /// `max |aᵢⱼ|` of the matrix last factored, for the pivot growth.
    max_entry: f64,
}

impl BandedMatrix {
    /// A zero `n × n` matrix with bandwidths `kl` below and `ku` above the
    /// diagonal (each clamped to `n − 1`). A size whose storage cannot be
    /// allocated is [`LinearSolveError::TooLarge`], not an abort.
    pub fn new(n: usize, kl: usize, ku: usize) -> Result<Self, LinearSolveError> {
        let kl = kl.min(n.saturating_sub(1));
        let ku = ku.min(n.saturating_sub(1));
        let ldab = 2 * kl + ku + 1;
        let len = ldab.checked_mul(n).ok_or(LinearSolveError::TooLarge { n, per_column: ldab })?;
        let lu = BandLu { n, kl, ku, ldab, ab: zeroed(len, 0.0, n, ldab)?, ipiv: zeroed(n, 0, n, ldab)? };
        Ok(Self { lu, work: Workspace::new(n, ldab)?, stage: Stage::Assembly, max_entry: 0.0 })
    }

    /// A zero matrix for a symmetric [`Pattern`]: `kl = ku =` its bandwidth,
    /// `n − 1` for a general one.
    pub fn for_pattern(n: usize, pattern: Pattern) -> Result<Self, LinearSolveError> {
        let b = pattern.bandwidth().unwrap_or(n.saturating_sub(1));
        Self::new(n, b, b)
    }

    /// The lower bandwidth.
    pub fn kl(&self) -> usize {
        self.lu.kl
    }

    /// The upper bandwidth.
    pub fn ku(&self) -> usize {
        self.lu.ku
    }

    fn check(&self, i: usize, j: usize) -> Result<(), LinearSolveError> {
        if self.stage != Stage::Assembly {
            return Err(LinearSolveError::Factored);
        }
        let n = self.lu.n;
        if i >= n || j >= n {
            return Err(LinearSolveError::OutOfRange { i, j, n });
        }
        Ok(())
    }

    fn outside(&self, i: usize, j: usize, value: f64) -> LinearSolveError {
        LinearSolveError::OutsideBand { i, j, kl: self.lu.kl, ku: self.lu.ku, value }
    }

    /// Entry `(i, j)`: `0` outside the band.
    pub fn get(&self, i: usize, j: usize) -> Result<f64, LinearSolveError> {
        self.check(i, j)?;
        Ok(if self.lu.in_band(i, j) { self.lu.ab[self.lu.index(i, j)] } else { 0.0 })
    }

    /// Sets entry `(i, j)`; a non-zero `x` outside the band is an error.
    pub fn set(&mut self, i: usize, j: usize, x: f64) -> Result<(), LinearSolveError> {
        self.check(i, j)?;
        if self.lu.in_band(i, j) {
            let k = self.lu.index(i, j);
            self.lu.ab[k] = x;
        } else if x != 0.0 {
            return Err(self.outside(i, j, x));
        }
        Ok(())
    }

    /// `y ← A x` (before factoring).
    pub fn mul_vec(&self, x: &[f64], y: &mut [f64]) -> Result<(), LinearSolveError> {
        if self.stage != Stage::Assembly {
            return Err(LinearSolveError::Factored);
        }
        let n = self.lu.n;
        for len in [x.len(), y.len()] {
            if len != n {
                return Err(LinearSolveError::DimensionMismatch { expected: n, found: len });
            }
        }
        y.fill(0.0);
        for j in 0..n {
            let top = j.saturating_sub(self.lu.ku);
            let bottom = (j + self.lu.kl).min(n - 1);
            let first = self.lu.index(top, j);
            let xj = x[j];
            for (yi, a) in y[top..=bottom].iter_mut().zip(&self.lu.ab[first..=first + bottom - top]) {
                *yi += a * xj;
            }
        }
        Ok(())
    }

    /// Pivot growth `max |uᵢⱼ| / max |aᵢⱼ|` of the last successful
    /// factorisation (`None` before one): large values mean the factors lost
    /// accuracy. Bounded by `2^(2kl+ku)` for a band matrix and usually
    /// below 10. Costs one pass over the factors.
    pub fn pivot_growth(&self) -> Option<f64> {
        if self.stage != Stage::Factored {
            return None;
        }
        let lu = &self.lu;
        let kv = lu.kl + lu.ku;
        let mut max_u = 0.0_f64;
        for j in 0..lu.n {
            let top = j.saturating_sub(kv);
            let col = kv + j * lu.ldab;
            for u in &lu.ab[col - (j - top)..=col] {
                max_u = max_u.max(u.abs());
            }
        }
        Some(if self.max_entry > 0.0 { max_u / self.max_entry } else { 1.0 })
    }
}

impl StepMatrix for BandedMatrix {
    fn dim(&self) -> usize {
        self.lu.n
    }

    fn may_couple(&self, i: usize, j: usize) -> bool {
        i < self.lu.n && j < self.lu.n && self.lu.in_band(i, j)
    }

    fn clear(&mut self) {
        self.lu.ab.fill(0.0);
        self.stage = Stage::Assembly;
    }

    #[inline]
    fn add(&mut self, i: usize, j: usize, x: f64) -> Result<(), LinearSolveError> {
        self.check(i, j)?;
        if self.lu.in_band(i, j) {
            let k = self.lu.index(i, j);
            self.lu.ab[k] += x;
        } else if x != 0.0 {
            return Err(self.outside(i, j, x));
        }
        Ok(())
    }

    fn factor(&mut self, min_rcond: f64) -> Result<Factorization, LinearSolveError> {
        if self.stage != Stage::Assembly {
            return Err(LinearSolveError::Factored);
        }
        let lu = &self.lu;
        let (n, kl, ku) = (lu.n, lu.kl, lu.ku);
        // One pass over the band: finiteness, ‖A‖₁ and max |aᵢⱼ|.
        let (mut norm, mut max_entry) = (0.0_f64, 0.0_f64);
        for j in 0..n {
            let first = lu.index(j.saturating_sub(ku), j);
            let last = lu.index((j + kl).min(n - 1), j);
            let mut sum = 0.0;
            for a in &lu.ab[first..=last] {
                sum += a.abs();
                max_entry = max_entry.max(a.abs());
            }
            if !sum.is_finite() {
                self.stage = Stage::Spoiled;
                return Err(LinearSolveError::NonFinite { quantity: "matrix" });
            }
            norm = norm.max(sum);
        }
        self.max_entry = max_entry;
        self.stage = Stage::Spoiled;
        let (min_pivot, max_pivot) = self.lu.factor()?;
        let report = Factorization { norm1: norm, min_pivot, max_pivot, rcond: None };
        let report = finish(&self.lu, &mut self.work, report, min_rcond)?;
        self.stage = Stage::Factored;
        Ok(report)
    }

    fn solve(&self, b: &mut [f64]) -> Result<(), LinearSolveError> {
        checked_solve(&self.lu, self.stage, b, false)
    }

    fn solve_transposed(&self, b: &mut [f64]) -> Result<(), LinearSolveError> {
        checked_solve(&self.lu, self.stage, b, true)
    }
}

/// Column-major dense LU factors.
#[derive(Clone, Debug)]
struct DenseLu {
    n: usize,
    /// Entry `(i, j)` at `a[i + j n]`.
    a: Vec<f64>,
    ipiv: Vec<usize>,
}

impl DenseLu {
    /// `getf2`: right-looking elimination with whole-row interchanges, so
    /// that `P A = L U`.
    fn factor(&mut self) -> Result<(f64, f64), LinearSolveError> {
        let n = self.n;
        let (mut min_pivot, mut max_pivot) = (f64::INFINITY, 0.0_f64);
        for j in 0..n {
            let col = j * n;
            let p = j + argmax_abs(&self.a[col + j..col + n]);
            self.ipiv[j] = p;
            let pivot = self.a[col + p];
            if pivot == 0.0 {
                return Err(LinearSolveError::Singular { rcond: 0.0, pivot: Some(j) });
            }
            if !pivot.is_finite() {
                return Err(LinearSolveError::NonFinite { quantity: "factors" });
            }
            min_pivot = min_pivot.min(pivot.abs());
            max_pivot = max_pivot.max(pivot.abs());
            if p != j {
                for c in 0..n {
                    self.a.swap(j + c * n, p + c * n);
                }
            }
            for v in &mut self.a[col + j + 1..col + n] {
                *v /= pivot;
            }
            let (left, right) = self.a.split_at_mut((j + 1) * n);
            let multipliers = &left[col + j + 1..col + n];
            for column in right.chunks_exact_mut(n) {
                let u = column[j];
                if u != 0.0 {
                    for (a, l) in column[j + 1..].iter_mut().zip(multipliers) {
                        *a -= l * u;
                    }
                }
            }
        }
        Ok((if n == 0 { 0.0 } else { min_pivot }, max_pivot))
    }
}

impl Factors for DenseLu {
    fn n(&self) -> usize {
        self.n
    }

    fn solve_plain(&self, b: &mut [f64]) {
        let n = self.n;
        for j in 0..n {
            b.swap(j, self.ipiv[j]);
        }
        for j in 0..n {
            let bj = b[j];
            for (bi, l) in b[j + 1..].iter_mut().zip(&self.a[j * n + j + 1..(j + 1) * n]) {
                *bi -= l * bj;
            }
        }
        for j in (0..n).rev() {
            let bj = b[j] / self.a[j * n + j];
            b[j] = bj;
            for (bi, u) in b[..j].iter_mut().zip(&self.a[j * n..j * n + j]) {
                *bi -= u * bj;
            }
        }
    }

    fn solve_transposed(&self, b: &mut [f64]) {
        let n = self.n;
        for j in 0..n {
            let dot: f64 = b[..j].iter().zip(&self.a[j * n..j * n + j]).map(|(x, u)| x * u).sum();
            b[j] = (b[j] - dot) / self.a[j * n + j];
        }
        for j in (0..n).rev() {
            let dot: f64 = b[j + 1..].iter().zip(&self.a[j * n + j + 1..(j + 1) * n]).map(|(x, l)| x * l).sum();
            b[j] -= dot;
        }
        for j in (0..n).rev() {
            b.swap(j, self.ipiv[j]);
        }
    }
}

/// A dense `n × n` matrix on the heap with its LU factorisation by partial
/// pivoting in the same storage (`n² + 4n` numbers, allocated by
/// [`new`](DenseMatrix::new)).
#[derive(Clone, Debug)]
pub struct DenseMatrix {
    lu: DenseLu,
    work: Workspace,
    stage: Stage,
}

impl DenseMatrix {
    /// A zero `n × n` matrix; a size whose storage cannot be allocated is
    /// [`LinearSolveError::TooLarge`], not an abort.
    pub fn new(n: usize) -> Result<Self, LinearSolveError> {
        let len = n.checked_mul(n).ok_or(LinearSolveError::TooLarge { n, per_column: n })?;
        let lu = DenseLu { n, a: zeroed(len, 0.0, n, n)?, ipiv: zeroed(n, 0, n, n)? };
        Ok(Self { lu, work: Workspace::new(n, n)?, stage: Stage::Assembly })
    }

    fn check(&self, i: usize, j: usize) -> Result<usize, LinearSolveError> {
        if self.stage != Stage::Assembly {
            return Err(LinearSolveError::Factored);
        }
        let n = self.lu.n;
        if i >= n || j >= n {
            return Err(LinearSolveError::OutOfRange { i, j, n });
        }
        Ok(i + j * n)
    }

    /// Entry `(i, j)`.
    pub fn get(&self, i: usize, j: usize) -> Result<f64, LinearSolveError> {
        let k = self.check(i, j)?;
        Ok(self.lu.a[k])
    }

    /// Sets entry `(i, j)`.
    pub fn set(&mut self, i: usize, j: usize, x: f64) -> Result<(), LinearSolveError> {
        let k = self.check(i, j)?;
        self.lu.a[k] = x;
        Ok(())
    }
}

impl StepMatrix for DenseMatrix {
    fn dim(&self) -> usize {
        self.lu.n
    }

    fn may_couple(&self, i: usize, j: usize) -> bool {
        i < self.lu.n && j < self.lu.n
    }

    fn clear(&mut self) {
        self.lu.a.fill(0.0);
        self.stage = Stage::Assembly;
    }

    #[inline]
    fn add(&mut self, i: usize, j: usize, x: f64) -> Result<(), LinearSolveError> {
        let k = self.check(i, j)?;
        self.lu.a[k] += x;
        Ok(())
    }

    fn factor(&mut self, min_rcond: f64) -> Result<Factorization, LinearSolveError> {
        if self.stage != Stage::Assembly {
            return Err(LinearSolveError::Factored);
        }
        let n = self.lu.n;
        let mut norm = 0.0_f64;
        for column in self.lu.a.chunks_exact(n.max(1)) {
            let sum: f64 = column.iter().map(|a| a.abs()).sum();
            if !sum.is_finite() {
                self.stage = Stage::Spoiled;
                return Err(LinearSolveError::NonFinite { quantity: "matrix" });
            }
            norm = norm.max(sum);
        }
        self.stage = Stage::Spoiled;
        let (min_pivot, max_pivot) = self.lu.factor()?;
        let report = Factorization { norm1: norm, min_pivot, max_pivot, rcond: None };
        let report = finish(&self.lu, &mut self.work, report, min_rcond)?;
        self.stage = Stage::Factored;
        Ok(report)
    }

    fn solve(&self, b: &mut [f64]) -> Result<(), LinearSolveError> {
        checked_solve(&self.lu, self.stage, b, false)
    }

    fn solve_transposed(&self, b: &mut [f64]) -> Result<(), LinearSolveError> {
        checked_solve(&self.lu, self.stage, b, true)
    }
}

/// The step matrix chosen for a pattern: banded or dense.
#[derive(Clone, Debug)]
pub enum StepSolver {
    /// For a banded or diagonal pattern where [`prefers_banded`].
    Banded(BandedMatrix),
    /// For a general pattern, or a small matrix.
    Dense(DenseMatrix),
}

impl StepSolver {
    /// The banded solver when `pattern` has a bandwidth and
    /// [`prefers_banded`] says so, else the dense one.
    pub fn for_pattern(n: usize, pattern: Pattern) -> Result<Self, LinearSolveError> {
        match pattern.bandwidth() {
            Some(b) if prefers_banded(n, b) => Ok(StepSolver::Banded(BandedMatrix::new(n, b, b)?)),
            _ => Ok(StepSolver::Dense(DenseMatrix::new(n)?)),
        }
    }

    fn inner(&self) -> &dyn StepMatrix {
        match self {
            StepSolver::Banded(m) => m,
            StepSolver::Dense(m) => m,
        }
    }

    fn inner_mut(&mut self) -> &mut dyn StepMatrix {
        match self {
            StepSolver::Banded(m) => m,
            StepSolver::Dense(m) => m,
        }
    }
}

impl StepMatrix for StepSolver {
    fn dim(&self) -> usize {
        self.inner().dim()
    }

    fn may_couple(&self, i: usize, j: usize) -> bool {
        self.inner().may_couple(i, j)
    }

    fn clear(&mut self) {
        self.inner_mut().clear()
    }

    #[inline]
    fn add(&mut self, i: usize, j: usize, x: f64) -> Result<(), LinearSolveError> {
        match self {
            StepSolver::Banded(m) => m.add(i, j, x),
            StepSolver::Dense(m) => m.add(i, j, x),
        }
    }

    fn factor(&mut self, min_rcond: f64) -> Result<Factorization, LinearSolveError> {
        self.inner_mut().factor(min_rcond)
    }

    fn solve(&self, b: &mut [f64]) -> Result<(), LinearSolveError> {
        self.inner().solve(b)
    }

    fn solve_transposed(&self, b: &mut [f64]) -> Result<(), LinearSolveError> {
        self.inner().solve_transposed(b)
    }
}

#[cfg(test)]
mod tests;
