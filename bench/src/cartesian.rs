//! The double pendulum of the `double-pendulum` problem written in
//! Cartesian coordinates `(x₁, y₁, x₂, y₂)` with its two rod constraints:
//! the `#[lagrangian]` system, the maps between its positions and the
//! angles, its energy, and the measure of how far a state is from the
//! constraints that the report applies to every method. Also the single
//! pendulum in its angle and as a point on the unit circle, the pair whose
//! step costs `benches/constrained.rs` and `examples/constrained_steps.rs`
//! compare.

use lagrangian::prelude::*;

use crate::problems::DoublePendulum;

/// The double pendulum as two points in the plane, gravity along `−y`, the
/// rods as constraints in squared form, `|r₁|² − l₁²` and `|r₂ − r₁|² − l₂²`.
#[derive(Debug, Clone, Copy)]
pub struct CartesianDoublePendulumSys {
    /// Upper mass.
    pub m1: f64,
    /// Lower mass.
    pub m2: f64,
    /// Upper rod.
    pub l1: f64,
    /// Lower rod.
    pub l2: f64,
    /// Gravity.
    pub g: f64,
}

#[lagrangian]
impl CartesianDoublePendulumSys {
    fn lagrangian(&self, q: [f64; 4], v: [f64; 4]) -> f64 {
        let kinetic = 0.5 * self.m1 * (v[0] * v[0] + v[1] * v[1]) + 0.5 * self.m2 * (v[2] * v[2] + v[3] * v[3]);
        kinetic - self.g * (self.m1 * q[1] + self.m2 * q[3])
    }

    fn constraints(&self, q: [f64; 4]) -> [f64; 2] {
        let (dx, dy) = (q[2] - q[0], q[3] - q[1]);
        [q[0] * q[0] + q[1] * q[1] - self.l1 * self.l1, dx * dx + dy * dy - self.l2 * self.l2]
    }
}

/// The system with the angle problem's parameters.
pub fn system() -> CartesianDoublePendulumSys {
    let p = DoublePendulum::P;
    CartesianDoublePendulumSys { m1: p.m1, m2: p.m2, l1: p.l1, l2: p.l2, g: p.g }
}

/// Positions and velocities of the angles `θ` (from the downward vertical)
/// and their rates, in any precision.
pub fn to_cartesian<T: Real>(theta: &[T; 2], rate: &[T; 2]) -> ([T; 4], [T; 4]) {
    let p = DoublePendulum::P;
    let (s1, c1) = theta[0].sin_cos();
    let (s2, c2) = theta[1].sin_cos();
    let (x1, y1) = (s1 * p.l1, -c1 * p.l1);
    let (u1, w1) = (c1 * rate[0] * p.l1, s1 * rate[0] * p.l1);
    let q = [x1, y1, x1 + s2 * p.l2, y1 - c2 * p.l2];
    let v = [u1, w1, u1 + c2 * rate[1] * p.l2, w1 + s2 * rate[1] * p.l2];
    (q, v)
}

/// The angles and their rates of Cartesian positions and velocities (the
/// rod directions and the angular velocities of the rods; their lengths are
/// not checked).
pub fn to_angles(q: &[f64; 4], v: &[f64; 4]) -> ([f64; 2], [f64; 2]) {
    let (d, dv) = ([q[2] - q[0], q[3] - q[1]], [v[2] - v[0], v[3] - v[1]]);
    let theta = [q[0].atan2(-q[1]), d[0].atan2(-d[1])];
    let rate = [
        (q[0] * v[1] - q[1] * v[0]) / (q[0] * q[0] + q[1] * q[1]),
        (d[0] * dv[1] - d[1] * dv[0]) / (d[0] * d[0] + d[1] * d[1]),
    ];
    (theta, rate)
}

/// The constraints in squared form and their Jacobian `G = ∂g/∂q`.
pub fn squared_constraints(q: &[f64; 4]) -> ([f64; 2], [[f64; 4]; 2]) {
    let p = DoublePendulum::P;
    let (dx, dy) = (q[2] - q[0], q[3] - q[1]);
    let g = [q[0] * q[0] + q[1] * q[1] - p.l1 * p.l1, dx * dx + dy * dy - p.l2 * p.l2];
    let jac = [[2.0 * q[0], 2.0 * q[1], 0.0, 0.0], [-2.0 * dx, -2.0 * dy, 2.0 * dx, 2.0 * dy]];
    (g, jac)
}

/// `[max_i |‖r_i − r_{i−1}‖ − l_i| / l_i, max_i |d‖r_i − r_{i−1}‖/dt|]`
/// (`r₀ = 0`): how far the rods are from their lengths, relative to them,
/// and how fast their lengths change (m/s), the hidden constraint `G v` of
/// the constraints written as lengths. The same measure for every method,
/// whatever form of the constraints it holds.
pub fn constraint_errors(q: &[f64; 4], v: &[f64; 4]) -> [f64; 2] {
    let p = DoublePendulum::P;
    let rods = [([q[0], q[1]], [v[0], v[1]], p.l1), ([q[2] - q[0], q[3] - q[1]], [v[2] - v[0], v[3] - v[1]], p.l2)];
    let (mut position, mut velocity) = (0.0f64, 0.0f64);
    for (d, dv, l) in rods {
        let length = d[0].hypot(d[1]);
        position = position.max((length - l).abs() / l);
        velocity = velocity.max(((d[0] * dv[0] + d[1] * dv[1]) / length).abs());
    }
    [position, velocity]
}

/// The energy `½ m₁|v₁|² + ½ m₂|v₂|² + g (m₁ y₁ + m₂ y₂)`.
pub fn energy(q: &[f64; 4], v: &[f64; 4]) -> f64 {
    let p = DoublePendulum::P;
    0.5 * p.m1 * (v[0] * v[0] + v[1] * v[1])
        + 0.5 * p.m2 * (v[2] * v[2] + v[3] * v[3])
        + p.g * (p.m1 * q[1] + p.m2 * q[3])
}

/// A unit pendulum under unit gravity in its angle.
#[derive(Debug, Clone, Copy)]
pub struct AnglePendulum;

#[lagrangian]
impl AnglePendulum {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] + q[0].cos()
    }
}

/// The same pendulum as a point on the unit circle.
#[derive(Debug, Clone, Copy)]
pub struct CartesianPendulum;

#[lagrangian]
impl CartesianPendulum {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) - q[1]
    }
    fn constraints(&self, q: [f64; 2]) -> [f64; 1] {
        [q[0] * q[0] + q[1] * q[1] - 1.0]
    }
}
