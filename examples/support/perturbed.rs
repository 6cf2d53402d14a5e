//! The perturbed pendulum of Luo, Guo, Li & Wu §V and the measurements made on it;
//! shared by `examples/perturbed_pendulum.rs` (which writes the CSV and the
//! plots) and `tests/verification/perturbed_pendulum.rs` (which asserts on them).
//!
//! `H = l²/2 + (1 − cos θ)(1 − 0.1 sin 0.02t)`, i.e.
//! `L = ½ θ̇² − (1 − cos θ)(1 − 0.1 sin 0.02t)`, from `l0 = θ0 = 0.5`,
//! `t0 = 0`, integrated with energy-preserving midpoint steps from `τ0 = 0.5`.
#![allow(dead_code, unreachable_pub)]

use lagrangian::prelude::*;
use lagrangian::{Error, StepBounds};

/// The pendulum with a slowly modulated gravity.
#[derive(Clone, Copy, Debug)]
pub struct PerturbedPendulum;

#[lagrangian]
impl PerturbedPendulum {
    fn lagrangian(&self, t: f64, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] - (1.0 - q[0].cos()) * (1.0 - 0.1 * (0.02 * t).sin())
    }
}

/// The angular frequency of the perturbation.
pub const PERTURBATION: f64 = 0.02;

/// One node of the run: `t_k`, `θ_k`, `l_k` and the step `τ_k = t_{k+1} − t_k` taken from it.
#[derive(Clone, Copy, Debug)]
pub struct Node {
    /// `t_k`.
    pub t: f64,
    /// `θ_k`.
    pub theta: f64,
    /// `l_k = p_k`.
    pub l: f64,
    /// `τ_k`.
    pub tau: f64,
    /// The discrete energy `E_k`.
    pub energy: f64,
}

/// Integrates from `t = 0` until `t_k ≥ t_end` and returns every node with its step.
pub fn record(t_end: f64) -> Result<Vec<Node>, Error> {
    let tau0 = 0.5;
    let mut sim = Integrator::new(PerturbedPendulum, Midpoint, tau0)
        .energy_preserving(StepBounds::around(tau0))
        .start(0.0, [0.5], [0.5])?;
    let mut nodes = Vec::new();
    while sim.state().t < t_end {
        let (t, theta, l, energy) = (sim.state().t, sim.state().q[0], sim.state().p[0], sim.discrete_energy());
        sim.step()?;
        nodes.push(Node { t, theta, l, tau: sim.state().t - t, energy });
    }
    Ok(nodes)
}

/// The envelope of the steps: the largest `τ` of each swing (between
/// successive sign changes of `θ`), placed at the time it occurs.
pub fn envelope(nodes: &[Node]) -> Vec<(f64, f64)> {
    let mut out = Vec::new();
    let mut best: Option<(f64, f64)> = None;
    for pair in nodes.windows(2) {
        let b = best.get_or_insert((pair[0].t, pair[0].tau));
        if pair[0].tau > b.1 {
            *b = (pair[0].t, pair[0].tau);
        }
        if pair[0].theta.signum() != pair[1].theta.signum() {
            out.extend(best.take());
        }
    }
    // The first and last swings are incomplete.
    if out.len() > 2 {
        out.remove(0);
    }
    out
}

/// The period of the slow modulation of `τ`: the period `P` in
/// `[P_lo, P_hi]` whose least-squares fit `a + b sin(2πt/P) + c cos(2πt/P)`
/// to the envelope leaves the smallest residual (scanned in steps of 0.1 s).
pub fn modulation_period(envelope: &[(f64, f64)], (p_lo, p_hi): (f64, f64)) -> f64 {
    let residual = |period: f64| {
        let w = std::f64::consts::TAU / period;
        // Normal equations of the 3-parameter linear fit.
        let mut m = [[0.0f64; 3]; 3];
        let mut r = [0.0f64; 3];
        for &(t, y) in envelope {
            let basis = [1.0, (w * t).sin(), (w * t).cos()];
            for i in 0..3 {
                r[i] += basis[i] * y;
                for j in 0..3 {
                    m[i][j] += basis[i] * basis[j];
                }
            }
        }
        let coef = solve3(m, r);
        envelope
            .iter()
            .map(|&(t, y)| {
                let fit = coef[0] + coef[1] * (w * t).sin() + coef[2] * (w * t).cos();
                (y - fit).powi(2)
            })
            .sum::<f64>()
    };
    let n = ((p_hi - p_lo) / 0.1).round() as usize;
    (0..=n).map(|i| p_lo + 0.1 * i as f64).min_by(|a, b| residual(*a).total_cmp(&residual(*b))).unwrap_or(p_lo)
}

/// Solves a 3×3 system by Cramer's rule (well conditioned here: the basis
/// functions are nearly orthogonal over many periods).
fn solve3(m: [[f64; 3]; 3], r: [f64; 3]) -> [f64; 3] {
    let det = |a: [[f64; 3]; 3]| {
        a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
            + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0])
    };
    let d = det(m);
    core::array::from_fn(|k| {
        let mut a = m;
        for i in 0..3 {
            a[i][k] = r[i];
        }
        det(a) / d
    })
}

/// Thresholds of [`swing_statistics`], as fractions of a swing's amplitude.
pub const SMALL: f64 = 0.5;
/// See [`SMALL`].
pub const LARGE: f64 = 0.7;

/// Where the steps are smallest and largest within each swing.
#[derive(Clone, Copy, Debug)]
pub struct SwingStatistics {
    /// Complete swings seen.
    pub swings: usize,
    /// Fraction of swings whose smallest step has `|θ| ≤ SMALL · amplitude` at its middle.
    pub smallest_near_zero: f64,
    /// Fraction of swings whose largest step has `|θ| ≥ LARGE · amplitude` at its middle.
    pub largest_near_extreme: f64,
}

/// Splits the run into swings (from one extreme of `θ` to the next, i.e.
/// between sign changes of `l`) and, in each, locates the smallest and the
/// largest step by the angle at its middle.
pub fn swing_statistics(nodes: &[Node]) -> SwingStatistics {
    let mut swings = 0;
    let (mut near_zero, mut near_extreme) = (0, 0);
    let mut start = None;
    for k in 1..nodes.len() {
        if nodes[k].l.signum() == nodes[k - 1].l.signum() {
            continue;
        }
        if let Some(s) = start {
            let steps: Vec<(f64, f64)> =
                (s..k).map(|i| (nodes[i].tau, (0.5 * (nodes[i].theta + nodes[i + 1].theta)).abs())).collect();
            let amplitude = steps.iter().fold(0.0f64, |m, p| m.max(p.1));
            let smallest = steps.iter().min_by(|a, b| a.0.total_cmp(&b.0)).map_or(0.0, |p| p.1);
            let largest = steps.iter().max_by(|a, b| a.0.total_cmp(&b.0)).map_or(0.0, |p| p.1);
            swings += 1;
            near_zero += usize::from(smallest <= SMALL * amplitude);
            near_extreme += usize::from(largest >= LARGE * amplitude);
        }
        start = Some(k);
    }
    let n = swings.max(1) as f64;
    SwingStatistics { swings, smallest_near_zero: near_zero as f64 / n, largest_near_extreme: near_extreme as f64 / n }
}
