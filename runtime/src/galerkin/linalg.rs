//! Dense LU with partial pivoting on the `sN × sN` Newton block of a
//! Galerkin step, with static sizes.
//!
//! Stable Rust has no `[f64; S * N]`, so the block system is held as arrays
//! of arrays: a vector is `[[f64; N]; S]` (node, then coordinate) and a
//! matrix the `sN` rows `[[f64; N]; S]` (row node, row coordinate; then
//! column node, column coordinate). The matrix lives on the heap: its
//! `(sN)²` entries would make a step's frame, and every value holding a
//! factored block, too large for a thread's stack at large `sN` (2 MiB at
//! `s = 2`, `N = 256`). Its storage is allocated once, row by row (no
//! `(sN)²` temporary on the stack), and the integrator reuses it from step
//! to step, so stepping does not allocate. A row and the list of rows are
//! flattened to slices of length `sN` by `as_flattened`, on which the
//! textbook elimination runs (Golub & Van Loan, Alg. 3.4.1). The reciprocal
//! condition number in the 1-norm is estimated from the factors by Hager's
//! method (Higham, *Accuracy and Stability*, Alg. 15.4), a few extra solves.

use crate::real::{Real, all_finite};

/// A vector of the block system: `S` blocks of `N`.
pub(crate) type BlockVector<const N: usize, const S: usize, T = f64> = [[T; N]; S];

/// A matrix of the block system: `S × S` blocks of `N × N`, its `sN` rows
/// ordered by `(row node, row coordinate)` on the heap. `a[m][i][n][k]` is
/// the entry of row `(m, i)` and column `(n, k)`. Empty (no allocation)
/// until first written through [`Lu::matrix_mut`].
#[derive(Debug, PartialEq)]
pub(crate) struct BlockMatrix<const N: usize, const S: usize, T = f64> {
    rows: Box<[[[T; N]; S]]>,
}

impl<const N: usize, const S: usize, T: Copy> Clone for BlockMatrix<N, S, T> {
    fn clone(&self) -> Self {
        Self { rows: self.rows.clone() }
    }

    /// Into the storage it has when that is of the same size: a copy of an
    /// integrator made before each step of a `solve` does not allocate.
    fn clone_from(&mut self, source: &Self) {
        if self.rows.len() == source.rows.len() {
            self.rows.copy_from_slice(&source.rows);
        } else {
            *self = source.clone();
        }
    }
}

impl<const N: usize, const S: usize, T: Real> BlockMatrix<N, S, T> {
    /// No storage yet.
    fn empty() -> Self {
        Self { rows: Box::default() }
    }

    /// `sN` rows of zeros, allocated without an `(sN)²` stack temporary.
    fn zeroed() -> Self {
        Self { rows: vec![[[T::zero(); N]; S]; S * N].into_boxed_slice() }
    }

    /// Allocated (with arbitrary entries) when empty.
    fn ensure_allocated(&mut self) {
        if self.rows.is_empty() {
            *self = Self::zeroed();
        }
    }

    /// Every entry zero, in the storage it has.
    pub(crate) fn fill_zero(&mut self) {
        self.ensure_allocated();
        self.rows.fill([[T::zero(); N]; S]);
    }

    /// The `sN` rows.
    pub(crate) fn rows(&self) -> &[[[T; N]; S]] {
        &self.rows
    }

    /// The `sN` rows.
    pub(crate) fn rows_mut(&mut self) -> &mut [[[T; N]; S]] {
        &mut self.rows
    }

    /// A matrix from its blocks.
    #[cfg(test)]
    pub(crate) fn from_blocks(a: [[[[T; N]; S]; N]; S]) -> Self {
        Self { rows: a.as_flattened().to_vec().into_boxed_slice() }
    }
}

impl<const N: usize, const S: usize, T> core::ops::Index<usize> for BlockMatrix<N, S, T> {
    type Output = [[[T; N]; S]; N];

    /// The `N` rows of row node `m`.
    #[inline]
    fn index(&self, m: usize) -> &Self::Output {
        &self.rows.as_chunks::<N>().0[m]
    }
}

impl<const N: usize, const S: usize, T> core::ops::IndexMut<usize> for BlockMatrix<N, S, T> {
    #[inline]
    fn index_mut(&mut self, m: usize) -> &mut Self::Output {
        &mut self.rows.as_chunks_mut::<N>().0[m]
    }
}

/// The factors `PA = LU` (unit lower `L` below the diagonal, `U` on and above).
#[derive(Debug, PartialEq)]
pub(crate) struct Lu<const N: usize, const S: usize, T = f64> {
    lu: BlockMatrix<N, S, T>,
    perm: [[usize; N]; S],
    /// `‖A‖₁`.
    norm1: T,
    /// `lu` holds `A⁻ᵀ` instead of the factors (see [`Lu::invert_in_place`]).
    inverted: bool,
}

impl<const N: usize, const S: usize, T: Copy> Clone for Lu<N, S, T> {
    fn clone(&self) -> Self {
        let Self { lu, perm, norm1, inverted } = self;
        Self { lu: lu.clone(), perm: *perm, norm1: *norm1, inverted: *inverted }
    }

    /// The factors into the storage they have (see [`BlockMatrix`]'s).
    fn clone_from(&mut self, source: &Self) {
        let Self { lu, perm, norm1, inverted } = self;
        lu.clone_from(&source.lu);
        (*perm, *norm1, *inverted) = (source.perm, source.norm1, source.inverted);
    }
}

/// Why a factorisation failed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum LuFailure {
    /// A zero pivot: exactly singular.
    Singular,
    /// A NaN or an infinity in the matrix.
    NonFinite,
}

impl<const N: usize, const S: usize, T: Real> Lu<N, S, T> {
    /// Factors `a`.
    #[cfg(test)]
    pub(crate) fn factor(a: &BlockMatrix<N, S, T>) -> Result<Self, LuFailure> {
        let mut out = Self::empty();
        *out.matrix_mut() = a.clone();
        out.factor_in_place()?;
        Ok(out)
    }

    /// No storage yet: allocated by the first [`matrix_mut`](Self::matrix_mut).
    #[inline]
    pub(crate) fn empty() -> Self {
        Self { lu: BlockMatrix::empty(), perm: [[0; N]; S], norm1: T::zero(), inverted: false }
    }

    /// Whether the storage is allocated.
    pub(crate) fn is_allocated(&self) -> bool {
        !self.lu.rows.is_empty()
    }

    /// Storage for a matrix to be factored in place, allocated.
    pub(crate) fn allocated() -> Self {
        Self { lu: BlockMatrix::zeroed(), ..Self::empty() }
    }

    /// The matrix [`factor_in_place`](Self::factor_in_place) factors: the
    /// Newton block is assembled here, so that it is never copied. Its
    /// entries are those left by the last use of the storage.
    #[inline]
    pub(crate) fn matrix_mut(&mut self) -> &mut BlockMatrix<N, S, T> {
        self.lu.ensure_allocated();
        &mut self.lu
    }

    /// Factors the matrix held in [`matrix_mut`](Self::matrix_mut),
    /// overwriting it with its factors. On failure the storage holds no
    /// usable factorisation.
    #[inline]
    pub(crate) fn factor_in_place(&mut self) -> Result<(), LuFailure> {
        let zero = T::zero();
        let out = self;
        out.inverted = false;
        let n = S * N;
        let perm = out.perm.as_flattened_mut();
        for (i, p) in perm.iter_mut().enumerate() {
            *p = i;
        }
        out.lu.ensure_allocated();
        let rows = out.lu.rows_mut();
        let mut col_sums = [[zero; N]; S];
        for row in rows.iter() {
            for (s, x) in col_sums.as_flattened_mut().iter_mut().zip(row.as_flattened()) {
                *s += x.abs();
            }
        }
        if !all_finite(col_sums.as_flattened()) {
            return Err(LuFailure::NonFinite);
        }
        out.norm1 = col_sums.as_flattened().iter().fold(zero, |m, &x| if x > m { x } else { m });
        for k in 0..n {
            let mut piv = k;
            let mut max = rows[k].as_flattened()[k].abs();
            for (i, row) in rows.iter().enumerate().skip(k + 1) {
                let v = row.as_flattened()[k].abs();
                if v > max {
                    max = v;
                    piv = i;
                }
            }
            if max == zero {
                return Err(LuFailure::Singular);
            }
            rows.swap(k, piv);
            perm.swap(k, piv);
            let (top, bottom) = rows.split_at_mut(k + 1);
            let pr = top[k].as_flattened();
            let inv = pr[k].recip();
            for row in bottom.iter_mut() {
                let r = row.as_flattened_mut();
                let f = r[k] * inv;
                r[k] = f;
                if f != zero {
                    for c in k + 1..n {
                        r[c] -= f * pr[c];
                    }
                }
            }
        }
        Ok(())
    }

    /// `x` with `A x = b`: one matrix–vector product once the factors are
    /// inverted, forward and back substitution before.
    #[inline]
    pub(crate) fn solve(&self, b: &BlockVector<N, S, T>) -> BlockVector<N, S, T> {
        if self.inverted {
            // Column by column (the inverse is stored transposed): the rows of
            // x are independent sums, which vectorise.
            let mut x = [[T::zero(); N]; S];
            let xf = x.as_flattened_mut();
            for (column, &y) in self.lu.rows().iter().zip(b.as_flattened()) {
                for (xi, &a) in xf.iter_mut().zip(column.as_flattened()) {
                    *xi += a * y;
                }
            }
            return x;
        }
        self.substitute(b)
    }

    /// Replaces the factors by `A⁻¹` (`sN` solves, `(sN)³` operations), so
    /// that every later [`solve`](Self::solve) is one matrix–vector product:
    /// worth it for a block the simplified Newton iteration keeps for many
    /// solves (at `sN = 12` a substitution costs about three times the
    /// product, whose rows are independent). The condition estimate needs
    /// the factors: take it before. `scratch` is storage for the inverse;
    /// it receives the storage of the factors.
    pub(crate) fn invert_in_place(&mut self, scratch: &mut Self) {
        if self.inverted {
            return;
        }
        let n = S * N;
        let inverse = &mut scratch.lu;
        inverse.ensure_allocated();
        for k in 0..n {
            let mut e = [[T::zero(); N]; S];
            e.as_flattened_mut()[k] = T::one();
            // Stored transposed: row k of the storage is column k of A⁻¹.
            inverse.rows_mut()[k] = self.substitute(&e);
        }
        core::mem::swap(&mut self.lu, inverse);
        self.inverted = true;
    }

    /// `x` with `A x = b` from the factors.
    #[inline(always)]
    fn substitute(&self, b: &BlockVector<N, S, T>) -> BlockVector<N, S, T> {
        debug_assert!(!self.inverted);
        let n = S * N;
        let rows = self.lu.rows();
        let perm = self.perm.as_flattened();
        let bf = b.as_flattened();
        let mut x = [[T::zero(); N]; S];
        let y = x.as_flattened_mut();
        for i in 0..n {
            let r = rows[i].as_flattened();
            let mut v = bf[perm[i]];
            for c in 0..i {
                v -= r[c] * y[c];
            }
            y[i] = v;
        }
        for i in (0..n).rev() {
            let r = rows[i].as_flattened();
            let mut v = y[i];
            for c in i + 1..n {
                v -= r[c] * y[c];
            }
            y[i] = v / r[i];
        }
        x
    }

    /// `z` with `Aᵀ z = b` (`Aᵀ = Uᵀ Lᵀ P`).
    fn solve_transposed(&self, b: &BlockVector<N, S, T>) -> BlockVector<N, S, T> {
        debug_assert!(!self.inverted);
        let n = S * N;
        let rows = self.lu.rows();
        let perm = self.perm.as_flattened();
        let mut w = *b;
        let wf = w.as_flattened_mut();
        // Uᵀ w = b, forward.
        for i in 0..n {
            let mut v = wf[i];
            for c in 0..i {
                v -= rows[c].as_flattened()[i] * wf[c];
            }
            wf[i] = v / rows[i].as_flattened()[i];
        }
        // Lᵀ u = w, backward, unit diagonal.
        for i in (0..n).rev() {
            let mut v = wf[i];
            for c in i + 1..n {
                v -= rows[c].as_flattened()[i] * wf[c];
            }
            wf[i] = v;
        }
        let mut z = [[T::zero(); N]; S];
        let zf = z.as_flattened_mut();
        for i in 0..n {
            zf[perm[i]] = wf[i];
        }
        z
    }

    /// Estimated `1 / (‖A‖₁ ‖A⁻¹‖₁)` (Hager's method, at most five rounds).
    pub(crate) fn rcond(&self) -> f64 {
        let n = S * N;
        let (zero, one) = (T::zero(), T::one());
        let mut x = [[T::from(1.0 / n as f64); N]; S];
        let mut est = zero;
        for round in 0..5 {
            let y = self.substitute(&x);
            let norm: T = y.as_flattened().iter().map(|v| v.abs()).sum();
            if round > 0 && norm <= est {
                break;
            }
            est = norm;
            let xi = y.map(|b| b.map(|v| if v >= zero { one } else { -one }));
            let z = self.solve_transposed(&xi);
            let zf = z.as_flattened();
            let (j, zmax) =
                zf.iter().enumerate().fold((0, zero), |(j, m), (i, v)| if v.abs() > m { (i, v.abs()) } else { (j, m) });
            let ztx: T = zf.iter().zip(x.as_flattened()).map(|(&a, &b)| a * b).sum();
            if round > 0 && zmax <= ztx {
                break;
            }
            x = [[zero; N]; S];
            x.as_flattened_mut()[j] = one;
        }
        (self.norm1 * est).recip().to_f64()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::DMatrix;

    fn dense<const N: usize, const S: usize>(a: &BlockMatrix<N, S>) -> DMatrix<f64> {
        let rows = a.rows();
        DMatrix::from_fn(S * N, S * N, |i, j| rows[i].as_flattened()[j])
    }

    #[test]
    fn solves_and_estimates_the_condition_like_a_dense_inverse() {
        // A non-symmetric 3 × 3 blocks of 2 × 2, needing pivoting (zero leading entry).
        let mut a: BlockMatrix<2, 3> = BlockMatrix::zeroed();
        let mut seed = 0.3f64;
        for rows in a.rows_mut() {
            for x in rows.as_flattened_mut() {
                seed = (seed * 7.31 + 0.17).fract();
                *x = seed - 0.5;
            }
        }
        a[0][0][0][0] = 0.0;
        let lu = Lu::factor(&a).unwrap();
        let b = [[1.0, -2.0], [0.5, 3.0], [-1.0, 0.25]];
        let x = lu.solve(&b);
        let z = lu.solve_transposed(&b);
        let m = dense(&a);
        let inv = m.clone().try_inverse().unwrap();
        let bv = nalgebra::DVector::from_row_slice(b.as_flattened());
        let want_x = &inv * &bv;
        let want_z = inv.transpose() * &bv;
        for i in 0..6 {
            assert!((x.as_flattened()[i] - want_x[i]).abs() <= 1e-12);
            assert!((z.as_flattened()[i] - want_z[i]).abs() <= 1e-12);
        }
        let norm1 = |m: &DMatrix<f64>| m.column_iter().map(|c| c.lp_norm(1)).fold(0.0, f64::max);
        let exact = 1.0 / (norm1(&m) * norm1(&inv));
        let est = lu.rcond();
        // Hager's estimate of ‖A⁻¹‖₁ is a lower bound, usually exact.
        assert!(est >= exact * (1.0 - 1e-12) && est <= 3.0 * exact, "{est} vs {exact}");
    }

    #[test]
    fn reports_singular_and_non_finite_matrices() {
        let a: BlockMatrix<1, 2> = BlockMatrix::from_blocks([[[[1.0], [2.0]]], [[[2.0], [4.0]]]]);
        assert!(matches!(Lu::factor(&a), Err(LuFailure::Singular)) || Lu::factor(&a).unwrap().rcond() < 1e-15);
        let b: BlockMatrix<1, 2> = BlockMatrix::from_blocks([[[[f64::NAN], [2.0]]], [[[2.0], [4.0]]]]);
        assert_eq!(Lu::factor(&b).unwrap_err(), LuFailure::NonFinite);
    }
}
