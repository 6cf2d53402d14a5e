//! The tables of a Galerkin rule whose degree is chosen at run time, and
//! where an entry of its Newton block is stored: shared by the step
//! (`galerkin.rs`) and its discrete forces (`galerkin_forces.rs`).

use crate::galerkin::{NodeFamily, gauss_legendre_into, gauss_lobatto_into, lagrange, lagrange_derivative};

/// The tables of a Galerkin rule of degree `s` whose size is chosen at run
/// time: control nodes, quadrature, and the Lagrange basis at the points.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Rule {
    pub(super) s: usize,
    /// `τ_0 = 0, τ_1, …, τ_s = 1`.
    pub(super) tau: Vec<f64>,
    /// The quadrature points `c_j`.
    pub(super) points: Vec<f64>,
    /// The quadrature weights `b_j`.
    pub(super) weights: Vec<f64>,
    /// `ℓ_m(c_j)`, `m = 1 … s`, at `j·s + m − 1`.
    pub(super) col: Vec<f64>,
    /// `ℓ_m'(c_j)` likewise.
    pub(super) col_d: Vec<f64>,
}

impl Rule {
    /// Degree `s ≥ 1` on the control nodes `family`, with `r`
    /// Gauss–Legendre points or (`lobatto`, `r ≥ 2`) Gauss–Lobatto points.
    pub(crate) fn new(s: usize, family: NodeFamily, lobatto: bool, r: usize) -> Self {
        let tau: Vec<f64> = family.nodes(s);
        let (mut points, mut weights) = (vec![0.0; r], vec![0.0; r]);
        if lobatto {
            gauss_lobatto_into(&mut points, &mut weights);
        } else {
            gauss_legendre_into(&mut points, &mut weights);
        }
        let (mut col, mut col_d) = (vec![0.0; r * s], vec![0.0; r * s]);
        for (j, &c) in points.iter().enumerate() {
            for m in 1..=s {
                col[j * s + m - 1] = lagrange(&tau, m, c);
                col_d[j * s + m - 1] = lagrange_derivative(&tau, m, c);
            }
        }
        Self { s, tau, points, weights, col, col_d }
    }

    /// The control nodes `τ_0 = 0, τ_1, …, τ_s = 1`.
    pub(crate) fn nodes(&self) -> &[f64] {
        &self.tau
    }

    /// `ℓ_m(τ)` for `m = 0 … s`.
    pub(crate) fn basis(&self, m: usize, tau: f64) -> f64 {
        lagrange(&self.tau, m, tau)
    }

    /// The degree `s`.
    pub(super) fn degree(&self) -> usize {
        self.s
    }

    /// The quadrature points `c_j`.
    pub(super) fn points(&self) -> &[f64] {
        &self.points
    }

    /// The quadrature weights `b_j`.
    pub(super) fn weights(&self) -> &[f64] {
        &self.weights
    }

    /// `(ℓ_m(c_j), ℓ_m'(c_j))` for `m = 1 … s`, at `m − 1`.
    pub(super) fn columns(&self, j: usize) -> (&[f64], &[f64]) {
        let s = self.s;
        (&self.col[j * s..(j + 1) * s], &self.col_d[j * s..(j + 1) * s])
    }
}

/// Where entry `(e, u)` of the Newton block sits in its storage: band
/// storage of bandwidth `offset` (row `e`'s `2·offset + 1` entries around the
/// diagonal) or whole rows.
#[derive(Clone, Copy, Debug)]
pub(crate) struct BlockLayout {
    pub(super) width: usize,
    pub(super) offset: usize,
    pub(super) banded: bool,
}

impl BlockLayout {
    /// The storage of `unknowns` unknowns with bandwidth `bandwidth` (`None`: dense).
    pub(super) fn new(unknowns: usize, bandwidth: Option<usize>) -> Self {
        match bandwidth {
            Some(b) => Self { width: 2 * b + 1, offset: b, banded: true },
            None => Self { width: unknowns, offset: 0, banded: false },
        }
    }

    /// The index of entry `(e, u)`.
    #[inline(always)]
    pub(super) fn slot(self, e: usize, u: usize) -> usize {
        if self.banded { e * self.width + u + self.offset - e } else { e * self.width + u }
    }
}
