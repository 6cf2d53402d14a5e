//! Systems the unit tests of the sensitivities share.

use super::Parametric;
use crate::system::{Lagrangian, Scalar};

/// A pendulum with its length and gravity as parameters (unit mass).
#[derive(Clone)]
pub(crate) struct Pendulum {
    pub(crate) theta: [f64; 2],
}

impl Lagrangian<1> for Pendulum {
    const AUTONOMOUS: bool = true;
    const CYCLIC: [bool; 1] = [false];
    fn lagrangian<D: Scalar>(&self, t: D, q: [D; 1], v: [D; 1]) -> D {
        self.lagrangian_with(&self.theta.map(D::from), t, q, v)
    }
}

impl Parametric<1, 2> for Pendulum {
    const NAMES: [&'static str; 2] = ["l", "g"];
    fn parameters(&self) -> [f64; 2] {
        self.theta
    }
    fn with_parameters(&self, theta: [f64; 2]) -> Self {
        Self { theta }
    }
    fn lagrangian_with<D: Scalar>(&self, theta: &[D; 2], _t: D, q: [D; 1], v: [D; 1]) -> D {
        let [l, g] = *theta;
        l * l * v[0] * v[0] * 0.5 + g * l * q[0].cos()
    }
}
