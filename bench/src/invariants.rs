//! The conserved quantities a run is checked against.

use crate::problems::Model;

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
}
