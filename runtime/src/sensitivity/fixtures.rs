//! Systems and checks the unit tests of the sensitivities share.

use num_dual::Dual64;

use super::forward::Jacobian;
use super::{Loss, Parametric};
use crate::Separability;
use crate::solution::Solution;
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

/// A damped harmonic oscillator with its mass, stiffness and damping
/// coefficient as parameters: `L = ½ m v² − ½ k q²`, `R = ½ c v²`.
#[derive(Clone)]
pub(crate) struct DampedOscillator {
    pub(crate) theta: [f64; 3],
}

impl Lagrangian<1> for DampedOscillator {
    const AUTONOMOUS: bool = true;
    const CYCLIC: [bool; 1] = [false];
    const HAS_DISSIPATION: bool = true;
    fn lagrangian<D: Scalar>(&self, t: D, q: [D; 1], v: [D; 1]) -> D {
        self.lagrangian_with(&self.theta.map(D::from), t, q, v)
    }
    fn dissipation<D: Scalar>(&self, q: [D; 1], v: [D; 1]) -> D {
        self.dissipation_with(&self.theta.map(D::from), q, v)
    }
}

impl Parametric<1, 3> for DampedOscillator {
    const NAMES: [&'static str; 3] = ["m", "k", "c"];
    fn parameters(&self) -> [f64; 3] {
        self.theta
    }
    fn with_parameters(&self, theta: [f64; 3]) -> Self {
        Self { theta }
    }
    fn lagrangian_with<D: Scalar>(&self, theta: &[D; 3], _t: D, q: [D; 1], v: [D; 1]) -> D {
        let [m, k, _] = *theta;
        (m * v[0] * v[0] - k * q[0] * q[0]) * 0.5
    }
    fn dissipation_with<D: Scalar>(&self, theta: &[D; 3], _q: [D; 1], v: [D; 1]) -> D {
        theta[2] * v[0] * v[0] * 0.5
    }
}

/// A damped pendulum driven by a periodic torque, with its length,
/// gravity, damping and drive amplitude as parameters (unit mass):
/// `L = ½ l² v² + g l cos q`, `Q = a cos(ω t) − b v`, `ω` = [`DRIVE`].
#[derive(Clone)]
pub(crate) struct ForcedPendulum {
    pub(crate) theta: [f64; 4],
}

/// The angular frequency `ω` of the forced pendulum's drive.
pub(crate) const DRIVE: f64 = 1.7;

impl Lagrangian<1> for ForcedPendulum {
    const AUTONOMOUS: bool = true;
    const CYCLIC: [bool; 1] = [false];
    const HAS_FORCE: bool = true;
    fn lagrangian<D: Scalar>(&self, t: D, q: [D; 1], v: [D; 1]) -> D {
        self.lagrangian_with(&self.theta.map(D::from), t, q, v)
    }
    fn force<D: Scalar>(&self, t: D, q: [D; 1], v: [D; 1]) -> [D; 1] {
        self.force_with(&self.theta.map(D::from), t, q, v)
    }
}

impl Parametric<1, 4> for ForcedPendulum {
    const NAMES: [&'static str; 4] = ["l", "g", "b", "a"];
    fn parameters(&self) -> [f64; 4] {
        self.theta
    }
    fn with_parameters(&self, theta: [f64; 4]) -> Self {
        Self { theta }
    }
    fn lagrangian_with<D: Scalar>(&self, theta: &[D; 4], _t: D, q: [D; 1], v: [D; 1]) -> D {
        let [l, g, _, _] = *theta;
        l * l * v[0] * v[0] * 0.5 + g * l * q[0].cos()
    }
    fn force_with<D: Scalar>(&self, theta: &[D; 4], t: D, _q: [D; 1], v: [D; 1]) -> [D; 1] {
        let [_, _, b, a] = *theta;
        [a * (t * DRIVE).cos() - b * v[0]]
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

/// The loss `J = Σ_k ℓ_k(t_k, q_k, p_k) + terminal` over the nodes of `sol`.
pub(crate) fn loss_of<F: Loss<N, P>, const N: usize, const P: usize>(
    loss: &F,
    sol: &Solution,
    theta: &[f64; P],
) -> f64 {
    let n = sol.len() - 1;
    let mut j = 0.0;
    for k in 0..=n {
        j += loss.running(k as u64, sol.t[k], sol.q.array(k).unwrap(), sol.p.array(k).unwrap(), theta);
    }
    j + loss.terminal(sol.t[n], sol.q.array(n).unwrap(), sol.p.array(n).unwrap(), theta)
}

/// The largest difference of `a` from `b`, relative to the largest entry of `b`.
pub(crate) fn relative(a: &[f64], b: &[f64]) -> f64 {
    let scale = b.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    a.iter().zip(b).fold(0.0f64, |m, (x, y)| m.max((x - y).abs())) / scale
}

/// Central differences of `f` over whole runs (`run`) from the inputs
/// `base` moved by `ε max(1, |x|)`, `ε = 1e-5`; every run must take `steps`
/// steps.
pub(crate) fn central<const D: usize>(
    base: [f64; D],
    steps: usize,
    run: impl Fn([f64; D]) -> Solution,
    f: impl Fn(&Solution, [f64; D]) -> f64,
) -> [f64; D] {
    core::array::from_fn(|i| {
        let step = 1e-5 * base[i].abs().max(1.0);
        let at = |s: f64| {
            let mut x = base;
            x[i] += s;
            let sol = run(x);
            assert_eq!(sol.len(), steps + 1, "a perturbed run took another number of steps");
            f(&sol, x)
        };
        (at(step) - at(-step)) / (2.0 * step)
    })
}

/// The rows of `(t, q, p)` derivatives at every node of a one-coordinate
/// run, as [`chained`] takes them, from the run's Jacobians.
pub(crate) fn node_rows<const D: usize>(jacobians: &[Jacobian]) -> Vec<[[f64; D]; 3]> {
    jacobians
        .iter()
        .map(|j| {
            [
                core::array::from_fn(|c| j.time[c]),
                core::array::from_fn(|c| j.get(0, c)),
                core::array::from_fn(|c| j.get(1, c)),
            ]
        })
        .collect()
}

/// `dJ/d(q0, v0, θ)` of a one-coordinate run (`D = 2 + P` inputs) from the
/// rows of `(t, q, p)` derivatives at every node: `Σ_k ∂ℓ_k/∂(t, q, p) S_k
/// + ∂ℓ_k/∂θ`, the partial derivatives by dual numbers.
pub(crate) fn chained<F: Loss<1, P>, const D: usize, const P: usize>(
    loss: &F,
    sol: &Solution,
    theta: &[f64; P],
    rows: &[[[f64; D]; 3]],
) -> [f64; D] {
    assert_eq!(D, 2 + P, "the inputs are q0, v0 and the parameters");
    let n = sol.len() - 1;
    let mut out = [0.0; D];
    for (k, s) in rows.iter().enumerate() {
        let node = [sol.t[k], sol.q[k][0], sol.p[k][0]].map(Dual64::from);
        let d = |x: &[Dual64; 3], th: &[Dual64; P]| {
            let r = loss.running(k as u64, x[0], [x[1]], [x[2]], th);
            if k == n { r + loss.terminal(x[0], [x[1]], [x[2]], th) } else { r }
        };
        let th = theta.map(Dual64::from);
        for (col, slot) in out.iter_mut().enumerate() {
            for (i, row) in s.iter().enumerate() {
                let mut x = node;
                x[i].eps = 1.0;
                *slot += d(&x, &th).eps * row[col];
            }
            if col >= 2 {
                let mut th = th;
                th[col - 2].eps = 1.0;
                *slot += d(&node, &th).eps;
            }
        }
    }
    out
}
