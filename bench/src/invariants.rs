//! The conserved quantities a run is checked against, and their samples
//! along a run.

use crate::problems::Model;
use crate::run::Run;

/// The relative errors of the conserved quantities of a model at a state.
pub(crate) struct Invariants<'a, M, const N: usize> {
    model: &'a M,
    e0: f64,
    l0: Option<[f64; 3]>,
}

impl<'a, M: Model<N>, const N: usize> Invariants<'a, M, N> {
    pub(crate) fn new(model: &'a M, q0: &[f64; N], v0: &[f64; N]) -> Self {
        Self { model, e0: model.energy(q0, v0), l0: model.angular_momentum(q0, v0) }
    }

    /// `(E − E0)/|E0|`.
    pub(crate) fn energy(&self, q: &[f64; N], v: &[f64; N]) -> f64 {
        (self.model.energy(q, v) - self.e0) / self.e0.abs().max(f64::MIN_POSITIVE)
    }

    /// `|L − L0|/|L0|` (Euclidean norms), when the model conserves `L`.
    pub(crate) fn momentum(&self, q: &[f64; N], v: &[f64; N]) -> Option<f64> {
        let (l0, l) = (self.l0?, self.model.angular_momentum(q, v)?);
        let norm = |x: [f64; 3]| x.iter().map(|c| c * c).sum::<f64>().sqrt();
        Some(norm([l[0] - l0[0], l[1] - l0[1], l[2] - l0[2]]) / norm(l0).max(f64::MIN_POSITIVE))
    }

    /// The constraint errors of a model with constraints ([`Model::constraint_errors`]).
    pub(crate) fn constraints(&self, q: &[f64; N], v: &[f64; N]) -> Option<[f64; 2]> {
        self.model.constraint_errors(q, v)
    }
}

/// The invariants of a run at about `samples` evenly spaced times (none
/// when `samples == 0`): the first state recorded at or after each, and the
/// initial state.
pub(crate) struct Sampler<'a, M, const N: usize> {
    invariants: Invariants<'a, M, N>,
    on: bool,
    every: f64,
    next: f64,
    energy: Vec<(f64, f64)>,
    momentum: Vec<(f64, f64)>,
    constraints: Vec<(f64, [f64; 2])>,
}

impl<'a, M: Model<N>, const N: usize> Sampler<'a, M, N> {
    /// Samples of a run from `(q0, v0)` at `t = 0` to `t_end`.
    pub(crate) fn new(model: &'a M, q0: &[f64; N], v0: &[f64; N], t_end: f64, samples: usize) -> Self {
        let invariants = Invariants::new(model, q0, v0);
        let on = samples > 0;
        let every = if on { t_end / samples as f64 } else { f64::INFINITY };
        let mut energy = Vec::with_capacity(samples + 1);
        let mut momentum = Vec::new();
        let mut constraints = Vec::new();
        if on {
            energy.push((0.0, 0.0));
            if invariants.momentum(q0, v0).is_some() {
                momentum.push((0.0, 0.0));
            }
            if let Some(c) = invariants.constraints(q0, v0) {
                constraints.push((0.0, c));
            }
        }
        Self { invariants, on, every, next: every, energy, momentum, constraints }
    }

    /// The state `(q, v)` at `t`, kept when `t` reaches the next sampling time.
    pub(crate) fn record(&mut self, t: f64, q: &[f64; N], v: &[f64; N]) {
        if t >= self.next * (1.0 - 1e-12) {
            self.energy.push((t, self.invariants.energy(q, v)));
            if let Some(l) = self.invariants.momentum(q, v) {
                self.momentum.push((t, l));
            }
            if let Some(c) = self.invariants.constraints(q, v) {
                self.constraints.push((t, c));
            }
            while self.next <= t * (1.0 + 1e-12) {
                self.next += self.every;
            }
        }
    }

    /// Adds the samples to those `out` has (a peer's own), in time order.
    pub(crate) fn finish(mut self, out: &mut Run) {
        if !self.on {
            return;
        }
        out.energy.append(&mut self.energy);
        out.momentum.append(&mut self.momentum);
        out.constraints.append(&mut self.constraints);
        for series in [&mut out.energy, &mut out.momentum] {
            // A run that blew up (its failure says so) would put NaN in the JSON, which has no NaN.
            series.retain(|s| s.1.is_finite());
            series.sort_by(|a, b| a.0.total_cmp(&b.0));
        }
        out.constraints.retain(|s| s.1.iter().all(|x| x.is_finite()));
        out.constraints.sort_by(|a, b| a.0.total_cmp(&b.0));
    }
}
