use nalgebra::{DMatrix, DVector};

use super::*;

/// SplitMix64: reproducible numbers without a dependency.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        // Uniform in [-1, 1).
        (z >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }
}

/// A random band matrix. `dominant`: the diagonal dominates its row and
/// column, so no row exchange is needed. Otherwise a dominant matrix of
/// bandwidths `kl − 1`, `ku − 1` with rows `2k` and `2k + 1` exchanged: as
/// well conditioned, but partial pivoting must exchange every pair back.
fn random_band(n: usize, kl: usize, ku: usize, dominant: bool, seed: u64) -> (BandedMatrix, DMatrix<f64>) {
    assert!(dominant || (kl >= 1 && ku >= 1));
    let (kl0, ku0) = if dominant { (kl, ku) } else { (kl - 1, ku - 1) };
    let mut rng = Rng(seed);
    let mut dense = DMatrix::zeros(n, n);
    for j in 0..n {
        for i in j.saturating_sub(ku0)..=(j + kl0).min(n - 1) {
            dense[(i, j)] = if i == j { (kl0 + ku0 + 1) as f64 + rng.next().abs() } else { rng.next() };
        }
    }
    if !dominant {
        for k in 0..n / 2 {
            dense.swap_rows(2 * k, 2 * k + 1);
        }
    }
    let mut band = BandedMatrix::new(n, kl, ku).unwrap();
    for j in 0..n {
        for i in 0..n {
            band.set(i, j, dense[(i, j)]).unwrap();
        }
    }
    (band, dense)
}

fn random_vector(n: usize, seed: u64) -> Vec<f64> {
    let mut rng = Rng(seed);
    (0..n).map(|_| rng.next()).collect()
}

fn max_abs(x: &[f64]) -> f64 {
    x.iter().fold(0.0, |m, v| m.max(v.abs()))
}

fn relative_difference(x: &[f64], y: &[f64]) -> f64 {
    let d: Vec<f64> = x.iter().zip(y).map(|(a, b)| a - b).collect();
    max_abs(&d) / max_abs(y)
}

/// Solves with the band LU and with nalgebra's dense LU; returns the
/// relative difference of the two solutions and whether any row was exchanged.
fn against_dense(n: usize, kl: usize, ku: usize, dominant: bool, seed: u64) -> (f64, bool) {
    let (mut band, dense) = random_band(n, kl, ku, dominant, seed);
    let b = random_vector(n, seed ^ 0xabcd);
    let mut ax = vec![0.0; n];
    band.mul_vec(&b, &mut ax).unwrap();
    let nalgebra_ax = &dense * DVector::from_column_slice(&b);
    assert!(relative_difference(&ax, nalgebra_ax.as_slice()) < 1e-15, "mul_vec disagrees with the dense product");
    band.factor(0.0).unwrap();
    let pivoted = band.lu.ipiv.iter().enumerate().any(|(j, &p)| p != j);
    let mut x = b.clone();
    band.solve(&mut x).unwrap();
    let reference = dense.lu().solve(&DVector::from_column_slice(&b)).unwrap();
    (relative_difference(&x, reference.as_slice()), pivoted)
}

#[test]
fn banded_dominant_systems_match_a_dense_solve() {
    for (kl, ku) in [(1, 1), (2, 2), (2, 3), (3, 1), (0, 2), (2, 0), (0, 0), (5, 7)] {
        let (error, pivoted) = against_dense(200, kl, ku, true, 17 + kl as u64 * 31 + ku as u64);
        assert!(error <= 1e-12, "kl = {kl}, ku = {ku}: relative error {error:e}");
        // A dominant diagonal never needs an exchange.
        assert!(!pivoted, "kl = {kl}, ku = {ku}");
    }
}

#[test]
fn banded_systems_that_need_pivoting_match_a_dense_solve() {
    for (kl, ku) in [(1, 1), (2, 2), (1, 3), (4, 1), (3, 6)] {
        let (error, pivoted) = against_dense(200, kl, ku, false, 5 + kl as u64 * 7 + ku as u64);
        assert!(pivoted, "kl = {kl}, ku = {ku}: the test matrix should need row exchanges");
        assert!(error <= 1e-12, "kl = {kl}, ku = {ku}: relative error {error:e}");
    }
}

#[test]
fn one_by_one_and_two_by_two() {
    let mut m = BandedMatrix::new(1, 3, 3).unwrap();
    assert_eq!((m.kl(), m.ku()), (0, 0));
    m.set(0, 0, 4.0).unwrap();
    let f = m.factor(1e-13).unwrap();
    assert_eq!(f.rcond, Some(1.0));
    let mut b = [2.0];
    m.solve(&mut b).unwrap();
    assert_eq!(b, [0.5]);

    // [[0, 1], [2, 3]] needs the exchange.
    let mut m = BandedMatrix::new(2, 1, 1).unwrap();
    m.set(0, 1, 1.0).unwrap();
    m.set(1, 0, 2.0).unwrap();
    m.set(1, 1, 3.0).unwrap();
    m.factor(0.0).unwrap();
    let mut b = [1.0, 5.0];
    m.solve(&mut b).unwrap();
    assert_eq!(b, [1.0, 1.0]);
}

#[test]
fn empty_matrix_solves_trivially() {
    let mut m = BandedMatrix::new(0, 1, 1).unwrap();
    assert_eq!(m.factor(1e-13).unwrap().rcond, Some(1.0));
    m.solve(&mut []).unwrap();
    let mut d = DenseMatrix::new(0).unwrap();
    d.factor(1e-13).unwrap();
    d.solve(&mut []).unwrap();
}

#[test]
fn singular_bands_are_typed_errors() {
    // Two equal rows of a tridiagonal matrix: elimination meets a zero pivot.
    let mut m = BandedMatrix::new(4, 1, 1).unwrap();
    for (i, j, x) in [(0, 0, 2.0), (0, 1, 1.0), (1, 0, 2.0), (1, 1, 1.0), (2, 2, 1.0), (3, 3, 1.0)] {
        m.set(i, j, x).unwrap();
    }
    assert_eq!(m.factor(0.0), Err(LinearSolveError::Singular { rcond: 0.0, pivot: Some(1) }));
    assert_eq!(m.solve(&mut [1.0; 4]), Err(LinearSolveError::NotFactored));
    // A zero column.
    let mut m = BandedMatrix::new(5, 2, 1).unwrap();
    for i in [0, 1, 3, 4] {
        m.set(i, i, 1.0).unwrap();
    }
    assert!(matches!(m.factor(0.0), Err(LinearSolveError::Singular { rcond: 0.0, .. })));
    // The zero matrix.
    let mut d = DenseMatrix::new(3).unwrap();
    assert_eq!(d.factor(0.0), Err(LinearSolveError::Singular { rcond: 0.0, pivot: Some(0) }));
}

/// Upper bidiagonal, 1 on the diagonal and −2 above: every pivot is 1, the
/// condition number is above 2ⁿ. The pivot ratio cannot see it; the
/// estimate does.
fn doubling_matrix(n: usize) -> BandedMatrix {
    let mut m = BandedMatrix::new(n, 0, 1).unwrap();
    for i in 0..n {
        m.set(i, i, 1.0).unwrap();
        if i + 1 < n {
            m.set(i, i + 1, -2.0).unwrap();
        }
    }
    m
}

#[test]
fn ill_conditioning_is_caught_by_the_estimate_not_by_the_pivots() {
    let n = 60;
    let f = doubling_matrix(n).factor(0.0).unwrap();
    assert_eq!(f.pivot_ratio(), 1.0);
    assert_eq!(f.rcond, None);
    match doubling_matrix(n).factor(1e-13) {
        Err(LinearSolveError::Singular { rcond, pivot: None }) => {
            // ‖A‖₁ = 3 and ‖A⁻¹‖₁ = 2ⁿ − 1 exactly.
            let exact = 1.0 / (3.0 * (2f64.powi(n as i32) - 1.0));
            assert!((rcond / exact - 1.0).abs() < 1e-12, "rcond {rcond:e}, exact {exact:e}");
        }
        other => panic!("expected an ill-conditioned error, got {other:?}"),
    }
    // At n = 20 the same matrix is fine for that threshold.
    assert!(doubling_matrix(20).factor(1e-13).is_ok());
}

/// `‖A⁻¹‖₁` exactly, from nalgebra's inverse.
fn exact_inverse_norm1(dense: &DMatrix<f64>) -> f64 {
    let inverse = dense.clone().try_inverse().unwrap();
    inverse.column_iter().map(|c| c.lp_norm(1)).fold(0.0, f64::max)
}

#[test]
fn condition_estimate_is_a_tight_lower_bound() {
    for seed in 0..20 {
        let (kl, ku) = (1 + seed as usize % 3, 2 + seed as usize % 2);
        let (mut band, dense) = random_band(40, kl, ku, seed % 2 == 1, 100 + seed);
        let norm = dense.column_iter().map(|c| c.lp_norm(1)).fold(0.0, f64::max);
        let exact = 1.0 / (norm * exact_inverse_norm1(&dense));
        let estimate = band.factor(1e-300).unwrap().rcond.unwrap();
        // A lower bound on ‖A⁻¹‖₁ is an upper bound on rcond; Hager's
        // estimate is within a factor 3 in Higham's experiments.
        assert!(estimate >= exact * (1.0 - 1e-10), "seed {seed}: {estimate:e} < exact {exact:e}");
        assert!(estimate <= 3.0 * exact, "seed {seed}: {estimate:e} far above exact {exact:e}");

        let mut d = DenseMatrix::new(40).unwrap();
        for j in 0..40 {
            for i in 0..40 {
                d.set(i, j, dense[(i, j)]).unwrap();
            }
        }
        let dense_estimate = d.factor(1e-300).unwrap().rcond.unwrap();
        assert!(
            (dense_estimate / estimate - 1.0).abs() < 1e-8,
            "seed {seed}: dense {dense_estimate:e}, band {estimate:e}"
        );
    }
}

#[test]
fn non_finite_input_is_a_typed_error() {
    for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        let (mut m, _) = random_band(10, 1, 2, true, 3);
        m.set(4, 5, bad).unwrap();
        assert_eq!(m.factor(1e-13), Err(LinearSolveError::NonFinite { quantity: "matrix" }));
        assert_eq!(m.solve(&mut [1.0; 10]), Err(LinearSolveError::NotFactored));

        let (mut m, _) = random_band(10, 1, 2, true, 3);
        m.factor(1e-13).unwrap();
        let mut b = [1.0; 10];
        b[7] = bad;
        assert_eq!(m.solve(&mut b), Err(LinearSolveError::NonFinite { quantity: "right-hand side" }));

        let mut d = DenseMatrix::new(3).unwrap();
        d.set(1, 2, bad).unwrap();
        assert_eq!(d.factor(0.0), Err(LinearSolveError::NonFinite { quantity: "matrix" }));
    }
}

#[test]
fn overflow_in_the_solution_is_a_typed_error() {
    // Pivots 1e-300 and 1: finite factors, but A⁻¹ b overflows.
    let mut m = BandedMatrix::new(2, 0, 0).unwrap();
    m.set(0, 0, 1e-300).unwrap();
    m.set(1, 1, 1.0).unwrap();
    m.factor(0.0).unwrap();
    let mut b = [1e10, 1.0];
    assert_eq!(m.solve(&mut b), Err(LinearSolveError::NonFinite { quantity: "solution" }));
}

#[test]
fn entries_outside_the_band_and_the_matrix() {
    let mut m = BandedMatrix::new(6, 1, 2).unwrap();
    assert!(m.may_couple(3, 2) && m.may_couple(2, 4) && !m.may_couple(4, 2) && !m.may_couple(0, 3));
    assert!(!m.may_couple(6, 6));
    assert_eq!(m.add(4, 2, 1.5), Err(LinearSolveError::OutsideBand { i: 4, j: 2, kl: 1, ku: 2, value: 1.5 }));
    assert!(matches!(m.set(0, 3, f64::NAN), Err(LinearSolveError::OutsideBand { .. })));
    // An exact zero outside the band is what the band already holds.
    m.add(4, 2, 0.0).unwrap();
    assert_eq!(m.get(4, 2), Ok(0.0));
    assert_eq!(m.add(6, 0, 1.0), Err(LinearSolveError::OutOfRange { i: 6, j: 0, n: 6 }));
    assert_eq!(m.get(0, 9), Err(LinearSolveError::OutOfRange { i: 0, j: 9, n: 6 }));
    m.add(2, 4, 1.0).unwrap();
    m.add(2, 4, 2.0).unwrap();
    assert_eq!(m.get(2, 4), Ok(3.0));
    let mut d = DenseMatrix::new(2).unwrap();
    assert_eq!(d.add(2, 0, 1.0), Err(LinearSolveError::OutOfRange { i: 2, j: 0, n: 2 }));
}

#[test]
fn the_cycle_is_enforced() {
    let (mut m, _) = random_band(8, 2, 1, true, 9);
    assert_eq!(m.solve(&mut [0.0; 8]), Err(LinearSolveError::NotFactored));
    assert!(m.pivot_growth().is_none());
    m.factor(0.0).unwrap();
    assert_eq!(m.add(0, 0, 1.0), Err(LinearSolveError::Factored));
    assert_eq!(m.get(0, 0), Err(LinearSolveError::Factored));
    assert_eq!(m.factor(0.0), Err(LinearSolveError::Factored));
    assert_eq!(m.mul_vec(&[0.0; 8], &mut [0.0; 8]), Err(LinearSolveError::Factored));
    assert_eq!(m.solve(&mut [0.0; 7]), Err(LinearSolveError::DimensionMismatch { expected: 8, found: 7 }));
    m.clear();
    assert_eq!(m.get(1, 0), Ok(0.0));
    m.add(0, 0, 1.0).unwrap();
}

#[test]
fn huge_sizes_are_errors_not_aborts() {
    assert!(matches!(BandedMatrix::new(usize::MAX / 2, 3, 3), Err(LinearSolveError::TooLarge { .. })));
    assert!(matches!(DenseMatrix::new(1 << 40), Err(LinearSolveError::TooLarge { .. })));
}

#[test]
fn pivot_growth_is_reported() {
    let (mut m, _) = random_band(100, 2, 2, false, 11);
    m.factor(0.0).unwrap();
    let growth = m.pivot_growth().unwrap();
    // Bounded by 2^(2kl+ku) = 64 in theory, small in practice.
    assert!((1.0..64.0).contains(&growth), "growth {growth}");
}

#[test]
fn dense_solves_match_nalgebra_with_pivoting() {
    for (n, seed) in [(1, 1), (2, 2), (7, 3), (50, 4), (120, 5)] {
        let mut rng = Rng(seed);
        let mut d = DenseMatrix::new(n).unwrap();
        let mut dense = DMatrix::zeros(n, n);
        for j in 0..n {
            for i in 0..n {
                // A small diagonal: rows must be exchanged.
                let x = if i == j { 0.01 * rng.next() } else { rng.next() };
                d.add(i, j, x).unwrap();
                dense[(i, j)] = x;
            }
        }
        d.factor(0.0).unwrap();
        let b = random_vector(n, seed + 40);
        let mut x = b.clone();
        d.solve(&mut x).unwrap();
        let reference = dense.lu().solve(&DVector::from_column_slice(&b)).unwrap();
        let error = relative_difference(&x, reference.as_slice());
        assert!(error <= 1e-12, "n = {n}: relative error {error:e}");
    }
}

/// `Aᵀ x = b` from the factors of `A`, banded (with row exchanges) and
/// dense, against nalgebra's LU of the transpose.
#[test]
fn transposed_solves_match_nalgebra() {
    for (n, kl, ku, seed) in [(1, 1, 1, 7), (9, 2, 1, 8), (40, 1, 3, 9)] {
        let (mut band, dense) = random_band(n, kl, ku, false, seed);
        let mut full = DenseMatrix::new(n).unwrap();
        for j in 0..n {
            for i in 0..n {
                full.add(i, j, dense[(i, j)]).unwrap();
            }
        }
        band.factor(0.0).unwrap();
        full.factor(0.0).unwrap();
        let b = random_vector(n, seed + 50);
        let reference = dense.transpose().lu().solve(&DVector::from_column_slice(&b)).unwrap();
        let (mut x, mut y) = (b.clone(), b.clone());
        band.solve_transposed(&mut x).unwrap();
        full.solve_transposed(&mut y).unwrap();
        for (what, got) in [("banded", &x), ("dense", &y)] {
            let error = relative_difference(got, reference.as_slice());
            assert!(error <= 1e-13, "{what}, n = {n}: relative error {error:e}");
        }
    }
    // Before a factorisation there are no factors to solve with.
    let mut z = vec![1.0; 3];
    assert_eq!(DenseMatrix::new(3).unwrap().solve_transposed(&mut z), Err(LinearSolveError::NotFactored));
}

/// Newton on the discrete Bratu problem `−u'' = λ eᵘ`, `u = 0` at both ends,
/// written once over the trait: the tridiagonal and dense paths agree.
fn bratu<M: StepMatrix>(m: &mut M) -> Vec<f64> {
    let n = m.dim();
    let h = 1.0 / (n + 1) as f64;
    let lambda = 1.0;
    let mut u = vec![0.0; n];
    let mut r = vec![0.0; n];
    for _ in 0..20 {
        m.clear();
        for i in 0..n {
            let left = if i > 0 { u[i - 1] } else { 0.0 };
            let right = if i + 1 < n { u[i + 1] } else { 0.0 };
            r[i] = (2.0 * u[i] - left - right) / (h * h) - lambda * u[i].exp();
            m.add(i, i, 2.0 / (h * h) - lambda * u[i].exp()).unwrap();
            if i > 0 {
                m.add(i, i - 1, -1.0 / (h * h)).unwrap();
            }
            if i + 1 < n {
                m.add(i, i + 1, -1.0 / (h * h)).unwrap();
            }
        }
        m.factor(1e-13).unwrap();
        m.solve(&mut r).unwrap();
        for (ui, di) in u.iter_mut().zip(&r) {
            *ui -= di;
        }
        if max_abs(&r) < 1e-14 {
            break;
        }
    }
    u
}

#[test]
fn one_newton_loop_runs_on_both_solvers() {
    let n = 64;
    let mut banded = StepSolver::for_pattern(n, Pattern::banded(n, 1)).unwrap();
    let mut dense = StepSolver::for_pattern(n, Pattern::General).unwrap();
    assert!(matches!(banded, StepSolver::Banded(_)) && matches!(dense, StepSolver::Dense(_)));
    assert!(matches!(StepSolver::for_pattern(15, Pattern::banded(15, 1)).unwrap(), StepSolver::Dense(_)));
    assert!(matches!(StepSolver::for_pattern(16, Pattern::banded(16, 1)).unwrap(), StepSolver::Banded(_)));
    assert!(matches!(StepSolver::for_pattern(16, Pattern::Diagonal).unwrap(), StepSolver::Banded(_)));
    let (a, b) = (bratu(&mut banded), bratu(&mut dense));
    assert!(relative_difference(&a, &b) < 1e-13);
    // The lower Bratu branch at λ = 1 peaks near u(½) = 0.1405.
    assert!((max_abs(&a) - 0.1405).abs() < 2e-3, "max u = {}", max_abs(&a));
}

#[test]
fn a_million_unknowns_in_a_small_stack() {
    let run = || {
        let n = 1_000_000;
        let mut m = BandedMatrix::new(n, 1, 1).unwrap();
        for i in 0..n {
            m.set(i, i, 4.0).unwrap();
            if i > 0 {
                m.set(i, i - 1, -1.0).unwrap();
            }
            if i + 1 < n {
                m.set(i, i + 1, -1.5).unwrap();
            }
        }
        let x_true = random_vector(n, 77);
        let mut b = vec![0.0; n];
        m.mul_vec(&x_true, &mut b).unwrap();
        let f = m.factor(1e-13).unwrap();
        m.solve(&mut b).unwrap();
        (relative_difference(&b, &x_true), f.rcond.unwrap())
    };
    let (error, rcond) = std::thread::Builder::new().stack_size(2 << 20).spawn(run).unwrap().join().unwrap();
    assert!(error < 1e-13, "relative error {error:e}");
    // Diagonally dominant by 1.5: ‖A⁻¹‖₁ ≤ 1/1.5, ‖A‖₁ = 6.5.
    assert!(rcond > 1.5 / 6.5 * (1.0 - 1e-12), "rcond {rcond:e}");
}
