//! The storage of the dense saddle-point system of a constrained Galerkin
//! step (`galerkin.rs`): its matrix with the LU factors a simplified
//! Newton iteration reuses, and the right-hand side, allocated once per
//! integrator so that stepping does not allocate.

use crate::banded::{DenseMatrix, LinearSolveError, StepMatrix};

/// The saddle-point storage of an integrator: `n = s(N + M)` unknowns.
#[derive(Clone, Debug)]
pub(super) struct Work {
    n: usize,
    /// The matrix, and after [`factor`](Self::factor) its LU factors.
    matrix: DenseMatrix,
    /// `‖A‖₁` at the last factorisation.
    norm: f64,
    /// The right-hand side, overwritten by the solution.
    pub(super) rhs: Vec<f64>,
}

impl Work {
    /// Storage for `n` unknowns (allocated here, once per integrator).
    pub(super) fn new(n: usize) -> Self {
        // `n` is `s(N + M)` of a const-size system: a few dozen at most.
        let matrix = DenseMatrix::new(n).expect("a saddle-point matrix of a const-size system");
        Self { n, matrix, norm: 0.0, rhs: vec![0.0; n] }
    }

    /// The number of unknowns.
    pub(super) fn n(&self) -> usize {
        self.n
    }

    /// The matrix, cleared for assembly, and the right-hand side, zeroed.
    pub(super) fn assemble(&mut self) -> (&mut DenseMatrix, &mut [f64]) {
        self.matrix.clear();
        self.rhs.fill(0.0);
        (&mut self.matrix, &mut self.rhs)
    }

    /// The right-hand side, zeroed (the factors stay).
    pub(super) fn rhs_zeroed(&mut self) -> &mut [f64] {
        self.rhs.fill(0.0);
        &mut self.rhs
    }

    /// Factors the assembled matrix: the ratio of its smallest to its
    /// largest pivot; `Err(Some(0))` where a pivot is zero, `Err(None)`
    /// where a value is not finite.
    pub(super) fn factor(&mut self) -> Result<f64, Option<f64>> {
        match self.matrix.factor(0.0) {
            Ok(report) => {
                self.norm = report.norm1;
                Ok(report.pivot_ratio())
            }
            Err(LinearSolveError::Singular { rcond, .. }) => Err(Some(rcond)),
            Err(_) => Err(None),
        }
    }

    /// `‖A‖₁` of the factored matrix: the size of the residual a
    /// correction at round-off leaves.
    pub(super) fn norm(&self) -> f64 {
        self.norm
    }

    /// Overwrites `rhs` with the solution of the factored system; `false`
    /// where it is not finite (or nothing is factored).
    pub(super) fn solve(&mut self) -> bool {
        self.matrix.solve(&mut self.rhs).is_ok()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn factors_serve_several_right_hand_sides_and_failures_are_told_apart() {
        let mut work = Work::new(3);
        // Upper bidiagonal, 2 on the diagonal: the last component of the
        // solution is half the last of the right-hand side.
        let (a, _) = work.assemble();
        for i in 0..3 {
            a.add(i, i, 2.0).unwrap();
            if i < 2 {
                a.add(i, i + 1, 1.0).unwrap();
            }
        }
        assert_eq!(work.factor(), Ok(1.0));
        for b in [1.0, 3.0] {
            work.rhs_zeroed()[2] = b;
            assert!(work.solve());
            assert_eq!(work.rhs, [b / 8.0, -b / 4.0, b / 2.0]);
        }
        work.assemble();
        assert_eq!(work.factor(), Err(Some(0.0)));
        assert!(!work.solve());
        let (a, _) = work.assemble();
        a.add(0, 0, f64::NAN).unwrap();
        assert_eq!(work.factor(), Err(None));
    }
}
