//! The constraint Jacobian `G = ∂g/∂q` of a run-time-sized system: its
//! structure, found once from the operations of `g`, and its values, from
//! one evaluation of `g` on dual lanes per colour chunk.
//!
//! **Structure.** `g` is recorded once on the tape (`tape.rs`), and a
//! forward pass over the recorded operations gives each constraint the
//! first and last coordinate it depends on ([`Tape::input_ranges`]): the
//! columns `lo_r ..= hi_r` of row `r`. The ranges are structural — a
//! derivative that happens to vanish at the probed point still counts — so
//! they hold at every configuration where `g` takes the same operations
//! (a body without branches on `q`). Nothing is declared by the user. They
//! are not checked again during a run: a body whose other branch involves
//! other coordinates would alias their derivatives into the colours below.
//!
//! **Values.** With rows at most `w` columns wide, colouring column `j`
//! with `j mod w` never puts two columns of one row in the same colour
//! (Curtis, Powell & Reid, *On the estimation of sparse Jacobian matrices*,
//! 1974): `g` evaluated on dual numbers with `q_j` seeded in the lane of its
//! colour gives every entry of `G` in `⌈w / LANES⌉` evaluations, `O(ops)`
//! each, whatever `N`.

use super::kkt::RowRanges;
use crate::hyperdual::DualArray;
use crate::system::DynLagrangian;
use crate::tape::{Tape, Var};

/// Colours carried by one evaluation.
const LANES: usize = 4;

/// The dual number of one evaluation.
type Lane = DualArray<[f64; LANES]>;

/// Why the structure of `G` could not be found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum ProbeFailure {
    /// A constraint does not depend on `q` at all: `G` has a zero row.
    ConstantRow,
    /// The tape failed (a recording inside `constraints`) or is too large.
    Tape,
}

/// Row `r`'s columns of `G` from one recording of `g(t, q)` with
/// `m` constraints.
pub(crate) fn probe<S: DynLagrangian>(system: &S, t: f64, q: &[f64], m: usize) -> Result<RowRanges, ProbeFailure> {
    let mut tape = Tape::new();
    let mut g = vec![Var::constant(0.0); m];
    tape.record(q, |x: &[Var]| {
        system.constraints(Var::constant(t), x, &mut g);
        g.first().copied().unwrap_or(Var::constant(0.0))
    })
    .map_err(|_| ProbeFailure::Tape)?;
    let mut ranges = vec![None; m];
    tape.input_ranges(&g, &mut ranges).map_err(|_| ProbeFailure::Tape)?;
    let rows = ranges.into_iter().collect::<Option<Vec<_>>>().ok_or(ProbeFailure::ConstantRow)?;
    Ok(RowRanges { rows })
}

/// `g` and `G` at one configuration, in the row storage of
/// [`Kkt::factor`](super::kkt::Kkt::factor): row `r` as `width` entries
/// from column `lo_r`.
#[derive(Clone, Debug)]
pub(crate) struct Jacobian {
    rows: RowRanges,
    width: usize,
    /// `g(t, q)`.
    pub(crate) values: Vec<f64>,
    /// The rows of `G`.
    pub(crate) entries: Vec<f64>,
    /// The seeded coordinates and the constraint values of one evaluation.
    seeded: Vec<Lane>,
    out: Vec<Lane>,
}

impl Jacobian {
    /// Storage for the structure `rows` of a system of `n` coordinates.
    pub(crate) fn new(n: usize, rows: RowRanges) -> Self {
        let (m, width) = (rows.rows.len(), rows.width());
        Self {
            rows,
            width,
            values: vec![0.0; m],
            entries: vec![0.0; m * width],
            seeded: vec![Lane::from_re(0.0); n],
            out: vec![Lane::from_re(0.0); m],
        }
    }

    /// `g(t, q)` and `G(t, q)`; `false` when a value or a derivative is not
    /// finite. No allocation.
    pub(crate) fn evaluate<S: DynLagrangian>(&mut self, system: &S, t: f64, q: &[f64]) -> bool {
        let w = self.width;
        let mut first = 0;
        while first < w {
            for (j, (x, &qj)) in self.seeded.iter_mut().zip(q).enumerate() {
                *x = Lane::from_re(qj);
                let colour = j % w;
                if (first..first + LANES).contains(&colour) {
                    x.eps[colour - first] = 1.0;
                }
            }
            self.out.fill(Lane::from_re(0.0));
            system.constraints(Lane::from_re(t), &self.seeded, &mut self.out);
            for (r, &(lo, hi)) in self.rows.rows.iter().enumerate() {
                let g = &self.out[r];
                for j in lo..=hi {
                    let colour = j % w;
                    if (first..first + LANES).contains(&colour) {
                        self.entries[r * w + j - lo] = g.eps[colour - first];
                    }
                }
            }
            first += LANES;
        }
        for (value, g) in self.values.iter_mut().zip(&self.out) {
            *value = g.re;
        }
        self.values.iter().chain(&self.entries).all(|x| x.is_finite())
    }

    /// `out = G x`.
    pub(crate) fn apply(&self, x: &[f64], out: &mut [f64]) {
        let w = self.width;
        for (r, (&(lo, hi), o)) in self.rows.rows.iter().zip(out.iter_mut()).enumerate() {
            *o = (lo..=hi).map(|j| self.entries[r * w + j - lo] * x[j]).sum();
        }
    }

    /// `out += σ Gᵀ y`.
    pub(crate) fn add_transposed(&self, sigma: f64, y: &[f64], out: &mut [f64]) {
        let w = self.width;
        for (r, &(lo, hi)) in self.rows.rows.iter().enumerate() {
            let s = sigma * y[r];
            for j in lo..=hi {
                out[j] += s * self.entries[r * w + j - lo];
            }
        }
    }

    /// The Euclidean norm of row `r` of `G`.
    pub(crate) fn row_norm(&self, r: usize) -> f64 {
        let w = self.width;
        self.entries[r * w..(r + 1) * w].iter().map(|x| x * x).sum::<f64>().sqrt()
    }
}
