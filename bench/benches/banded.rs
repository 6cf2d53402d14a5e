//! Factor-and-solve time of the heap step matrices (`lagrangian::banded`):
//! the banded LU for n = 1e2 … 1e6 with a fitted cost exponent, against
//! faer's sparse LU (with the `faer` feature), and against dense LU at
//! n = 100 and 256; then the dimension where the banded solver starts to beat
//! the dense one (`prefers_banded`).
//!
//! Run with `cargo bench -p lagrangian-bench --bench banded` (add
//! `--features faer` for the faer column). A plain timing loop, not
//! criterion: each entry is the median of repeated runs of one
//! factorisation and one solve, the matrix re-assembled outside the timed
//! region; the systems are `−1, 4, −1.5` (tridiagonal) and
//! `0.5, −1, 6, −1.5, 0.25` (pentadiagonal), wider bands and a full
//! matrix with `4` on the diagonal and `−1/d²` (below) or `−0.5/d²` (above) at
//! distance `d`: diagonally dominant, so no
//! solver exchanges rows and all do the same arithmetic.
#![allow(missing_docs)]

use std::hint::black_box;
use std::time::{Duration, Instant};

use lagrangian_runtime::banded::{BandedMatrix, DenseMatrix, StepMatrix};

/// The band of row `i`, as `(column offset, value)`: a dominant diagonal
/// and decaying neighbours out to `bandwidth`.
fn stencil(bandwidth: usize) -> Vec<(isize, f64)> {
    match bandwidth {
        1 => vec![(-1, -1.0), (0, 4.0), (1, -1.5)],
        2 => vec![(-2, 0.5), (-1, -1.0), (0, 6.0), (1, -1.5), (2, 0.25)],
        b => (-(b as isize)..=b as isize)
            .map(|d| (d, if d == 0 { 4.0 } else { -1.0 / (d * d) as f64 * if d < 0 { 1.0 } else { 0.5 } }))
            .collect(),
    }
}

fn entries(n: usize, bandwidth: usize) -> impl Iterator<Item = (usize, usize, f64)> {
    let stencil = stencil(bandwidth);
    (0..n).flat_map(move |i| {
        stencil.clone().into_iter().filter_map(move |(d, x)| {
            let j = i as isize + d;
            (j >= 0 && (j as usize) < n).then_some((i, j as usize, x))
        })
    })
}

fn assemble<M: StepMatrix>(m: &mut M, bandwidth: usize) {
    m.clear();
    for (i, j, x) in entries(m.dim(), bandwidth) {
        m.add(i, j, x).unwrap();
    }
}

fn rhs(n: usize) -> Vec<f64> {
    (0..n).map(|i| ((i * 7919) % 1000) as f64 / 1000.0 - 0.5).collect()
}

/// Median of `sample()` (each call times one run and returns seconds),
/// repeated for about `budget`.
fn median(budget: Duration, mut sample: impl FnMut() -> f64) -> f64 {
    let mut times = Vec::new();
    let start = Instant::now();
    while times.len() < 5 || (start.elapsed() < budget && times.len() < 100_000) {
        times.push(sample());
    }
    times.sort_by(f64::total_cmp);
    times[times.len() / 2]
}

/// Factor (`min_rcond` > 0: with the condition estimate) and solve, the
/// assembly outside the timed region. For small `n`, where a clock read
/// costs as much as the work, [`time_small`] is used instead.
fn time_step_matrix<M: StepMatrix>(m: &mut M, bandwidth: usize, min_rcond: f64, budget: Duration) -> f64 {
    let b0 = rhs(m.dim());
    let mut b = b0.clone();
    median(budget, || {
        assemble(m, bandwidth);
        b.copy_from_slice(&b0);
        let t = Instant::now();
        black_box(m.factor(min_rcond).unwrap());
        m.solve(black_box(&mut b)).unwrap();
        t.elapsed().as_secs_f64()
    })
}

/// Assembly, factor and solve, 1000 times per sample: the whole cost of one
/// Newton linear solve at small `n`.
fn time_small<M: StepMatrix>(m: &mut M, bandwidth: usize, budget: Duration) -> f64 {
    const BATCH: usize = 1000;
    let b0 = rhs(m.dim());
    let mut b = b0.clone();
    median(budget, || {
        let t = Instant::now();
        for _ in 0..BATCH {
            assemble(m, bandwidth);
            b.copy_from_slice(&b0);
            black_box(m.factor(0.0).unwrap());
            m.solve(black_box(&mut b)).unwrap();
        }
        t.elapsed().as_secs_f64() / BATCH as f64
    })
}

fn time_banded(n: usize, bandwidth: usize, min_rcond: f64, budget: Duration) -> f64 {
    let mut m = BandedMatrix::new(n, bandwidth, bandwidth).unwrap();
    time_step_matrix(&mut m, bandwidth, min_rcond, budget)
}

fn time_dense(n: usize, bandwidth: usize, budget: Duration) -> f64 {
    let mut m = DenseMatrix::new(n).unwrap();
    time_step_matrix(&mut m, bandwidth, 0.0, budget)
}

fn time_nalgebra(n: usize, bandwidth: usize, budget: Duration) -> f64 {
    use nalgebra034::{DMatrix, DVector};
    let mut a = DMatrix::zeros(n, n);
    for (i, j, x) in entries(n, bandwidth) {
        a[(i, j)] = x;
    }
    let b0 = DVector::from_vec(rhs(n));
    let mut b = b0.clone();
    median(budget, || {
        let copy = a.clone();
        b.copy_from(&b0);
        let t = Instant::now();
        let lu = copy.lu();
        assert!(lu.solve_mut(black_box(&mut b)));
        t.elapsed().as_secs_f64()
    })
}

#[cfg(feature = "faer")]
mod with_faer {
    use super::*;
    use faer::linalg::solvers::Solve;
    use faer::sparse::linalg::solvers::{Lu, SymbolicLu};
    use faer::sparse::{SparseColMat, Triplet};

    /// Numeric sparse LU (the symbolic analysis done once, as a Newton loop
    /// would) and one solve; also returns the time of the symbolic analysis.
    pub(super) fn time_faer(n: usize, bandwidth: usize, budget: Duration) -> (f64, f64) {
        faer::set_global_parallelism(faer::Par::Seq);
        let triplets: Vec<_> = entries(n, bandwidth).map(|(i, j, x)| Triplet::new(i, j, x)).collect();
        let a = SparseColMat::<usize, f64>::try_new_from_triplets(n, n, &triplets).unwrap();
        let t = Instant::now();
        let symbolic = SymbolicLu::try_new(a.symbolic()).unwrap();
        let symbolic_time = t.elapsed().as_secs_f64();
        let values = rhs(n);
        let b0 = faer::Col::<f64>::from_fn(n, |i| values[i]);
        let mut b = b0.clone();
        let numeric = median(budget, || {
            b.copy_from(&b0);
            let t = Instant::now();
            let lu = Lu::try_new_with_symbolic(symbolic.clone(), a.as_ref()).unwrap();
            lu.solve_in_place(black_box(b.as_mat_mut()));
            t.elapsed().as_secs_f64()
        });
        (numeric, symbolic_time)
    }
}

/// Least-squares slope of `log t` against `log n`.
fn exponent(points: &[(usize, f64)]) -> f64 {
    let xs: Vec<f64> = points.iter().map(|p| (p.0 as f64).ln()).collect();
    let ys: Vec<f64> = points.iter().map(|p| p.1.ln()).collect();
    let (mx, my) = (xs.iter().sum::<f64>() / xs.len() as f64, ys.iter().sum::<f64>() / ys.len() as f64);
    let sxy: f64 = xs.iter().zip(&ys).map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = xs.iter().map(|x| (x - mx) * (x - mx)).sum();
    sxy / sxx
}

fn main() {
    // `cargo test --benches` passes `--bench`-less arguments; run quickly then.
    let quick = !std::env::args().any(|a| a == "--bench");
    let budget = Duration::from_millis(if quick { 5 } else { 400 });
    let sizes: &[usize] = if quick { &[100, 1000] } else { &[100, 1_000, 10_000, 100_000, 1_000_000] };

    println!("## banded LU: factor + solve (median), µs\n");
    println!(
        "| bandwidth | n | banded | banded + rcond estimate | ns per unknown | faer sparse LU (numeric) | faer symbolic (once) |"
    );
    println!("| --- | --- | --- | --- | --- | --- | --- |");
    for bandwidth in [1, 2] {
        let mut points = Vec::new();
        for &n in sizes {
            let t = time_banded(n, bandwidth, 0.0, budget);
            let t_rcond = time_banded(n, bandwidth, 1e-13, budget);
            points.push((n, t));
            #[cfg(feature = "faer")]
            let faer_cells = {
                let (numeric, symbolic) = with_faer::time_faer(n, bandwidth, budget);
                format!("{:.2} | {:.2}", numeric * 1e6, symbolic * 1e6)
            };
            #[cfg(not(feature = "faer"))]
            let faer_cells = "(`--features faer`) | ".to_string();
            println!(
                "| {bandwidth} | {n} | {:.2} | {:.2} | {:.1} | {faer_cells} |",
                t * 1e6,
                t_rcond * 1e6,
                t * 1e9 / n as f64
            );
        }
        println!("\nbandwidth {bandwidth}: fitted exponent of the banded time in n: {:.3}\n", exponent(&points));
    }

    println!("## dense against banded at moderate n (tridiagonal and pentadiagonal systems), µs\n");
    println!("| bandwidth | n | banded | dense (this crate) | nalgebra 0.34 dense LU |");
    println!("| --- | --- | --- | --- | --- |");
    for bandwidth in [1, 2] {
        for n in [100, 256] {
            println!(
                "| {bandwidth} | {n} | {:.2} | {:.2} | {:.2} |",
                time_banded(n, bandwidth, 0.0, budget) * 1e6,
                time_dense(n, bandwidth, budget) * 1e6,
                time_nalgebra(n, bandwidth, budget) * 1e6
            );
        }
    }

    println!("\n## a full matrix (the N-link pendulum's case): dense LU, µs\n");
    println!("| n | dense (this crate) | nalgebra 0.34 dense LU |");
    println!("| --- | --- | --- |");
    for n in [100, 256] {
        // Bandwidth n − 1 with the dominant stencil's values: every entry non-zero.
        println!("| {n} | {:.2} | {:.2} |", time_dense(n, n - 1, budget) * 1e6, time_nalgebra(n, n - 1, budget) * 1e6);
    }

    println!("\n## small n: banded against dense (for `prefers_banded`): assemble + factor + solve, ns\n");
    println!("| bandwidth | n | banded | dense |");
    println!("| --- | --- | --- | --- |");
    for bandwidth in [1, 2, 4, 8] {
        for n in [2, 3, 4, 5, 6, 8, 12, 16, 24, 32, 48, 64] {
            if n <= bandwidth || (bandwidth > 2 && n < 2 * bandwidth) {
                continue;
            }
            println!(
                "| {bandwidth} | {n} | {:.0} | {:.0} |",
                time_small(&mut BandedMatrix::new(n, bandwidth, bandwidth).unwrap(), bandwidth, budget) * 1e9,
                time_small(&mut DenseMatrix::new(n).unwrap(), bandwidth, budget) * 1e9
            );
        }
    }
}
