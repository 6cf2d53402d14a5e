//! The saddle-point (KKT) system of a constrained step of a large system,
//! solved in `O(N)` when it is banded:
//!
//! ```text
//! [ A   σ Bᵀ ] [ x ]     [ r₁ ]
//! [ C   0    ] [ y ] = − [ r₂ ]
//! ```
//!
//! with `A` the `N × N` step Jacobian (or `∂²L/∂v²`) of bandwidth `b`, `B`
//! and `C` constraint Jacobians `M × N` whose row `r` is non-zero only in
//! the columns `lo_r ..= hi_r`, and `σ = ±1`. Ordered as `(x, y)` the
//! matrix has a dense-looking border; ordered with each multiplier `y_r`
//! right after the coordinate in the middle of its row's columns, every
//! entry lies within a band whose width depends on `b` and the rows'
//! widths, not on `N` (for a chain of planar links: `b = 0`, rows of 4
//! columns, bandwidth 5). The interleaved matrix is factored by the banded
//! LU with partial pivoting of `banded.rs` (the KKT matrix is indefinite,
//! so pivoting is needed), in `O((N + M) w²)` for bandwidth `w`, in storage
//! allocated once.
//!
//! A singular factorisation is told apart as the small path does
//! (`linear.rs`): if `A` alone factors, the constraint Jacobians are rank
//! deficient (redundant constraints, a singular configuration).

use crate::banded::{LinearSolveError, StepMatrix, StepSolver};
use crate::structure::Pattern;

/// Which block made the saddle-point system singular, with the reciprocal
/// condition number (1-norm) that gave it away.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum KktFailure {
    /// The upper-left block `A` alone is singular or ill-conditioned.
    Block(f64),
    /// `A` is regular but the whole system is not: the constraint
    /// Jacobians have lower rank than the number of constraints.
    Constraints(f64),
    /// A NaN or an infinity in the matrix or the solution.
    NonFinite(&'static str),
    /// The storage could not be allocated or an entry fell outside the
    /// band (the constraint Jacobian left the pattern it was probed with).
    Rejected(&'static str),
}

/// The column range `lo ..= hi` of each row of a constraint Jacobian.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct RowRanges {
    /// Per row, its first and last column that may be non-zero.
    pub(crate) rows: Vec<(usize, usize)>,
}

impl RowRanges {
    /// The widest row: `max (hi − lo + 1)`.
    pub(crate) fn width(&self) -> usize {
        self.rows.iter().map(|&(lo, hi)| hi - lo + 1).max().unwrap_or(0)
    }
}

/// A saddle-point system of fixed structure, its interleaved order, and the
/// banded (or dense) storage it is factored in.
#[derive(Clone, Debug)]
pub(crate) struct Kkt {
    n: usize,
    /// The position of `x_j` (`j < n`) and of `y_r` (`n + r`) in the
    /// interleaved order.
    position: Vec<usize>,
    rows: RowRanges,
    /// The bandwidth of `A`, `None` for a general one.
    block_bandwidth: Option<usize>,
    /// The bandwidth of the interleaved matrix.
    bandwidth: usize,
    matrix: StepSolver,
    /// `A` alone, factored only to tell a failure apart.
    block: StepSolver,
    rhs: Vec<f64>,
    /// The largest entries `(α, β, γ)` of `A`, `B` and `C` at the last
    /// factorisation, which scale the blocks (see [`factor`](Self::factor)).
    scale: (f64, f64, f64),
}

/// The largest magnitude in `x`, 1 when all are zero.
fn largest(x: &[f64]) -> f64 {
    let m = x.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    if m > 0.0 { m } else { 1.0 }
}

impl Kkt {
    /// The structure for `n` unknowns `x`, an upper-left block of bandwidth
    /// `block_bandwidth` (`None`: general) and the constraint rows `rows`.
    pub(crate) fn new(n: usize, block_bandwidth: Option<usize>, rows: RowRanges) -> Result<Self, LinearSolveError> {
        let m = rows.rows.len();
        // Each multiplier after the middle column of its row: a counting
        // sort of the rows by that column keeps the order O(N + M).
        let mut after = vec![0usize; n + 1];
        for &(lo, hi) in &rows.rows {
            after[(lo + hi) / 2 + 1] += 1;
        }
        for j in 0..n {
            after[j + 1] += after[j];
        }
        // `after[j]`: the multipliers placed before `x_j`.
        let mut position = vec![0usize; n + m];
        for (j, p) in position.iter_mut().enumerate().take(n) {
            *p = j + after[j];
        }
        let mut next = vec![0usize; n];
        for (r, &(lo, hi)) in rows.rows.iter().enumerate() {
            let mid = (lo + hi) / 2;
            position[n + r] = position[mid] + 1 + next[mid];
            next[mid] += 1;
        }
        let size = n + m;
        let bandwidth = match block_bandwidth {
            None => size.saturating_sub(1),
            Some(b) => {
                let mut w = 0;
                for i in 0..n {
                    let j = (i + b).min(n - 1);
                    w = w.max(position[j] - position[i]);
                }
                for (r, &(lo, hi)) in rows.rows.iter().enumerate() {
                    let p = position[n + r];
                    w = w.max(p.abs_diff(position[lo])).max(p.abs_diff(position[hi]));
                }
                w
            }
        };
        let matrix = StepSolver::for_pattern(size, Pattern::banded(size, bandwidth))?;
        let block = StepSolver::for_pattern(n, block_bandwidth.map_or(Pattern::General, |b| Pattern::banded(n, b)))?;
        Ok(Self {
            n,
            position,
            rows,
            block_bandwidth,
            bandwidth,
            matrix,
            block,
            rhs: vec![0.0; size],
            scale: (1.0, 1.0, 1.0),
        })
    }

    /// The bandwidth of the interleaved matrix.
    pub(crate) fn bandwidth(&self) -> usize {
        self.bandwidth
    }

    /// Adds the upper-left block from `band` (row `i`'s `2b + 1` entries
    /// around the diagonal, or whole rows for a general block) to `m`.
    fn add_block(m: &mut StepSolver, n: usize, bandwidth: Option<usize>, band: &[f64]) -> Result<(), LinearSolveError> {
        let width = bandwidth.map_or(n, |b| 2 * b + 1);
        for i in 0..n {
            let row = &band[i * width..(i + 1) * width];
            for (c, &x) in row.iter().enumerate() {
                let j = match bandwidth {
                    Some(b) => match (i + c).checked_sub(b).filter(|&j| j < n) {
                        Some(j) => j,
                        None => continue,
                    },
                    None => c,
                };
                m.add(i, j, x)?;
            }
        }
        Ok(())
    }

    /// Assembles and factors `[A, σBᵀ; C, 0]` in the interleaved order:
    /// `band` holds `A` as [`add_block`](Self::add_block) reads it, `b` and
    /// `c` the rows of `B` and `C`, row `r` as the `width()` entries from
    /// column `lo_r` (entries past `hi_r` ignored). With `min_rcond > 0` the
    /// condition is estimated and a value below it is a failure.
    ///
    /// The blocks are factored as `[A/α, σBᵀ/β; C/γ, 0]`, `α`, `β`, `γ`
    /// their largest entries: the same solution up to the scaling of `y`,
    /// but a condition number that measures the problem, not its units (a
    /// step Jacobian `≈ −M/h` next to constraint gradients of order one
    /// would otherwise put the rcond of a well-posed chain of 10⁴ links,
    /// `h σ_min(G)² / ‖M/h‖`, near `10⁻¹³`).
    pub(crate) fn factor(
        &mut self,
        band: &[f64],
        sigma: f64,
        b: &[f64],
        c: &[f64],
        min_rcond: f64,
    ) -> Result<(), KktFailure> {
        let n = self.n;
        self.matrix.clear();
        let (alpha, beta, gamma) = (largest(band), largest(b), largest(c));
        self.scale = (alpha, beta, gamma);
        self.assemble(band, sigma, b, c).map_err(rejected)?;
        match self.matrix.factor(min_rcond) {
            Ok(_) => Ok(()),
            Err(LinearSolveError::Singular { rcond, .. }) => {
                // Which block: `A` alone.
                self.block.clear();
                Self::add_block(&mut self.block, n, self.block_bandwidth, band).map_err(rejected)?;
                match self.block.factor(min_rcond.max(f64::MIN_POSITIVE)) {
                    Ok(_) => Err(KktFailure::Constraints(rcond)),
                    Err(LinearSolveError::Singular { rcond, .. }) => Err(KktFailure::Block(rcond)),
                    Err(e) => Err(rejected(e)),
                }
            }
            Err(e) => Err(rejected(e)),
        }
    }

    /// Adds `[A/α, σBᵀ/β; C/γ, 0]` to the cleared matrix, in the interleaved
    /// order, with the scales of the last [`factor`](Self::factor).
    fn assemble(&mut self, band: &[f64], sigma: f64, b: &[f64], c: &[f64]) -> Result<(), LinearSolveError> {
        let n = self.n;
        let width = self.rows.width();
        let (alpha, beta, gamma) = self.scale;
        let width_a = self.block_bandwidth.map_or(n, |b| 2 * b + 1);
        for i in 0..n {
            let row = &band[i * width_a..(i + 1) * width_a];
            let pi = self.position[i];
            for (k, &x) in row.iter().enumerate() {
                let j = match self.block_bandwidth {
                    Some(bw) => match (i + k).checked_sub(bw).filter(|&j| j < n) {
                        Some(j) => j,
                        None => continue,
                    },
                    None => k,
                };
                self.matrix.add(pi, self.position[j], x / alpha)?;
            }
        }
        for (r, &(lo, hi)) in self.rows.rows.iter().enumerate() {
            let pr = self.position[n + r];
            for j in lo..=hi {
                let k = r * width + (j - lo);
                self.matrix.add(self.position[j], pr, sigma * b[k] / beta)?;
                self.matrix.add(pr, self.position[j], c[k] / gamma)?;
            }
        }
        Ok(())
    }

    /// Solves the factored system for the right-hand sides `r1` (`n`) and
    /// `r2` (`M`), overwriting them with `x` and `y`.
    pub(crate) fn solve(&mut self, r1: &mut [f64], r2: &mut [f64]) -> Result<(), KktFailure> {
        let n = self.n;
        let (alpha, beta, gamma) = self.scale;
        for (j, x) in r1.iter().enumerate() {
            self.rhs[self.position[j]] = -x / alpha;
        }
        for (r, x) in r2.iter().enumerate() {
            self.rhs[self.position[n + r]] = -x / gamma;
        }
        self.matrix.solve(&mut self.rhs).map_err(rejected)?;
        for (j, x) in r1.iter_mut().enumerate() {
            *x = self.rhs[self.position[j]];
        }
        for (r, x) in r2.iter_mut().enumerate() {
            *x = self.rhs[self.position[n + r]] * (alpha / beta);
        }
        Ok(())
    }

    /// Whether the interleaved matrix is stored banded (not dense).
    #[cfg(test)]
    fn is_banded(&self) -> bool {
        matches!(self.matrix, StepSolver::Banded(_))
    }
}

/// A linear-algebra failure of the saddle-point system.
fn rejected(e: LinearSolveError) -> KktFailure {
    match e {
        LinearSolveError::NonFinite { quantity } => KktFailure::NonFinite(quantity),
        LinearSolveError::Singular { rcond, .. } => KktFailure::Constraints(rcond),
        LinearSolveError::TooLarge { .. } => KktFailure::Rejected("the saddle-point system cannot be allocated"),
        _ => KktFailure::Rejected("the saddle-point system could not be assembled (internal error: please report)"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{DMatrix, DVector};

    /// A pseudo-random number in `[-0.5, 0.5)`.
    fn lcg(seed: &mut u64) -> f64 {
        *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (*seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    }

    /// A chain-like system: `A` tridiagonal and diagonally dominant,
    /// constraint rows of 4 columns at stride 2 (planar links).
    fn chain(links: usize, seed: &mut u64) -> (usize, Vec<f64>, RowRanges, Vec<f64>, Vec<f64>) {
        let n = 2 * links;
        let mut band = vec![0.0; n * 3];
        for i in 0..n {
            band[i * 3] = 0.1 * lcg(seed);
            band[i * 3 + 1] = -50.0 + lcg(seed);
            band[i * 3 + 2] = 0.1 * lcg(seed);
        }
        let rows: Vec<(usize, usize)> = (0..links).map(|r| (2 * r.max(1) - 2, 2 * r + 1)).collect();
        let rows = RowRanges { rows };
        let w = rows.width();
        let mut g0 = vec![0.0; links * w];
        let mut g1 = vec![0.0; links * w];
        for (r, &(lo, hi)) in rows.rows.iter().enumerate() {
            for k in 0..=(hi - lo) {
                g0[r * w + k] = 1.0 + lcg(seed);
                g1[r * w + k] = g0[r * w + k] + 0.01 * lcg(seed);
            }
        }
        (n, band, rows, g0, g1)
    }

    fn dense(n: usize, band: &[f64], rows: &RowRanges, sigma: f64, b: &[f64], c: &[f64]) -> DMatrix<f64> {
        let m = rows.rows.len();
        let w = rows.width();
        let mut k = DMatrix::zeros(n + m, n + m);
        for i in 0..n {
            for c3 in 0..3 {
                if let Some(j) = (i + c3).checked_sub(1).filter(|&j| j < n) {
                    k[(i, j)] += band[i * 3 + c3];
                }
            }
        }
        for (r, &(lo, hi)) in rows.rows.iter().enumerate() {
            for j in lo..=hi {
                k[(j, n + r)] = sigma * b[r * w + j - lo];
                k[(n + r, j)] = c[r * w + j - lo];
            }
        }
        k
    }

    #[test]
    fn the_interleaved_solve_matches_a_dense_one_and_has_a_narrow_band() {
        let mut seed = 7;
        for links in [3, 10, 40] {
            let (n, band, rows, g0, g1) = chain(links, &mut seed);
            let m = links;
            let mut kkt = Kkt::new(n, Some(1), rows.clone()).unwrap();
            // Rows of 4 columns at stride 2 and a tridiagonal block: the
            // band does not grow with the chain.
            assert!(kkt.bandwidth() <= 6, "bandwidth {}", kkt.bandwidth());
            if links >= 40 {
                assert!(kkt.is_banded());
            }
            for sigma in [1.0, -1.0] {
                kkt.factor(&band, sigma, &g0, &g1, 1e-14).unwrap();
                let r1: Vec<f64> = (0..n).map(|_| lcg(&mut seed)).collect();
                let r2: Vec<f64> = (0..m).map(|_| lcg(&mut seed)).collect();
                let (mut x, mut y) = (r1.clone(), r2.clone());
                kkt.solve(&mut x, &mut y).unwrap();
                let k = dense(n, &band, &rows, sigma, &g0, &g1);
                let rhs = -DVector::from_iterator(n + m, r1.iter().chain(&r2).copied());
                let exact = k.lu().solve(&rhs).unwrap();
                let got = DVector::from_iterator(n + m, x.iter().chain(&y).copied());
                let error = (got - &exact).amax() / exact.amax();
                assert!(error < 1e-12, "{links} links, σ = {sigma}: relative error {error:e}");
            }
        }
    }

    #[test]
    fn redundant_rows_are_told_from_a_singular_block() {
        let mut seed = 11;
        let (n, band, rows, mut g0, mut g1) = chain(12, &mut seed);
        let w = rows.width();
        // Row 5 repeated as row 6 (same columns): redundant constraints.
        let mut rows2 = rows.clone();
        rows2.rows[6] = rows.rows[5];
        for k in 0..w {
            g0[6 * w + k] = 2.0 * g0[5 * w + k];
            g1[6 * w + k] = 2.0 * g1[5 * w + k];
        }
        let mut kkt = Kkt::new(n, Some(1), rows2).unwrap();
        let failure = kkt.factor(&band, 1.0, &g0, &g1, 1e-13).unwrap_err();
        assert!(matches!(failure, KktFailure::Constraints(rcond) if rcond < 1e-13), "{failure:?}");
        // A zero block with regular constraints is the block's failure.
        let zero = vec![0.0; band.len()];
        let rows_width = rows.width();
        let mut kkt = Kkt::new(n, Some(1), rows).unwrap();
        let (_, _, _, g0, g1) = chain(12, &mut seed);
        let failure = kkt.factor(&zero, 1.0, &g0, &g1, 1e-13).unwrap_err();
        assert!(matches!(failure, KktFailure::Block(_)), "{failure:?}");
        // NaN in a constraint row (row 2, its second column).
        let mut bad = g1.clone();
        bad[2 * rows_width + 1] = f64::NAN;
        let failure = kkt.factor(&band, 1.0, &g0, &bad, 1e-13).unwrap_err();
        assert!(matches!(failure, KktFailure::NonFinite(_)), "{failure:?}");
    }
}
