//! Systems the unit tests of the sensitivities share.

use super::Parametric;
use crate::Separability;
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

/// Kepler in the plane with the gravitational parameter `μ` (unit mass,
/// constant mass matrix: the explicit splitting takes it).
#[derive(Clone)]
pub(crate) struct Kepler {
    pub(crate) mu: f64,
}

impl Lagrangian<2> for Kepler {
    const AUTONOMOUS: bool = true;
    const CYCLIC: [bool; 2] = [false; 2];
    const SEPARABILITY: Separability = Separability::ConstantMass;
    fn lagrangian<D: Scalar>(&self, t: D, q: [D; 2], v: [D; 2]) -> D {
        self.lagrangian_with(&[D::from(self.mu)], t, q, v)
    }
}

impl Parametric<2, 1> for Kepler {
    const NAMES: [&'static str; 1] = ["mu"];
    fn parameters(&self) -> [f64; 1] {
        [self.mu]
    }
    fn with_parameters(&self, theta: [f64; 1]) -> Self {
        Self { mu: theta[0] }
    }
    fn lagrangian_with<D: Scalar>(&self, theta: &[D; 1], _t: D, q: [D; 2], v: [D; 2]) -> D {
        (v[0] * v[0] + v[1] * v[1]) * 0.5 + theta[0] / (q[0] * q[0] + q[1] * q[1]).sqrt()
    }
}
