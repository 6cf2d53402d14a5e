//! Systems and numerical helpers shared by the integration tests.
#![allow(dead_code, missing_docs, unreachable_pub)]

use lagrangian::prelude::*;

pub mod forced;
pub mod galerkin_reference;
pub mod links;
pub mod parametric_chain;
pub mod schemes;

/// `L = ½ m l² θ̇² + m g l cos θ`.
#[derive(Clone, Debug)]
pub struct Pendulum {
    pub m: f64,
    pub l: f64,
    pub g: f64,
}

#[lagrangian]
impl Pendulum {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * self.m * self.l * self.l * v[0] * v[0] + self.m * self.g * self.l * q[0].cos()
    }
}

pub const PENDULUM: Pendulum = Pendulum { m: 1.3, l: 0.8, g: 9.81 };

/// Planar double pendulum, angles from the downward vertical.
#[derive(Clone, Debug)]
pub struct DoublePendulum {
    pub m1: f64,
    pub m2: f64,
    pub l1: f64,
    pub l2: f64,
    pub g: f64,
}

#[lagrangian]
impl DoublePendulum {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let kinetic = 0.5 * (self.m1 + self.m2) * self.l1 * self.l1 * v[0] * v[0]
            + 0.5 * self.m2 * self.l2 * self.l2 * v[1] * v[1]
            + self.m2 * self.l1 * self.l2 * v[0] * v[1] * (q[0] - q[1]).cos();
        let potential = -(self.m1 + self.m2) * self.g * self.l1 * q[0].cos() - self.m2 * self.g * self.l2 * q[1].cos();
        kinetic - potential
    }
}

pub const DOUBLE_PENDULUM: DoublePendulum = DoublePendulum { m1: 1.0, m2: 1.5, l1: 1.0, l2: 0.7, g: 9.81 };

/// `L = ½ m q̇² − ½ k q²`.
#[derive(Debug)]
pub struct Oscillator {
    pub m: f64,
    pub k: f64,
}

#[lagrangian]
impl Oscillator {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * self.m * v[0] * v[0] - 0.5 * self.k * q[0] * q[0]
    }
}

/// Planar Kepler problem in polar coordinates `(r, φ)`; `φ` is cyclic.
#[derive(Debug)]
pub struct KeplerPolar {
    pub mu: f64,
}

#[lagrangian]
impl KeplerPolar {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let r = q[0];
        0.5 * (v[0] * v[0] + r * r * v[1] * v[1]) + self.mu / r
    }
}

/// A charged particle in the plane, uniform magnetic field `B ẑ` (vector
/// potential `A = ½ B (−y, x)`) and electric potential `φ = ½ κ (x² + y²) + ε x⁴`:
/// `L = ½ m |v|² + e v·A(q) − e φ(q)`, not separable in `q` and `v`.
#[derive(Debug)]
pub struct ChargedParticle {
    pub m: f64,
    pub e: f64,
    pub b: f64,
    pub kappa: f64,
    pub eps: f64,
}

#[lagrangian]
impl ChargedParticle {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let (x, y) = (q[0], q[1]);
        let ax = -0.5 * self.b * y;
        let ay = 0.5 * self.b * x;
        let phi = 0.5 * self.kappa * (x * x + y * y) + self.eps * x * x * x * x;
        0.5 * self.m * (v[0] * v[0] + v[1] * v[1]) + self.e * (v[0] * ax + v[1] * ay) - self.e * phi
    }
}

pub const CHARGED: ChargedParticle = ChargedParticle { m: 1.0, e: 1.0, b: 2.0, kappa: 1.0, eps: 0.3 };

/// Least-squares slope of `ln err` against `ln h`: the observed order.
pub fn fitted_order(h: &[f64], err: &[f64]) -> f64 {
    let x: Vec<f64> = h.iter().map(|v| v.ln()).collect();
    let y: Vec<f64> = err.iter().map(|v| v.ln()).collect();
    linear_fit(&x, &y).1
}

/// `(intercept, slope)` of the least-squares line through `(x, y)`.
pub fn linear_fit(x: &[f64], y: &[f64]) -> (f64, f64) {
    let n = x.len() as f64;
    let mx = x.iter().sum::<f64>() / n;
    let my = y.iter().sum::<f64>() / n;
    let sxy: f64 = x.iter().zip(y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let sxx: f64 = x.iter().map(|a| (a - mx) * (a - mx)).sum();
    let slope = sxy / sxx;
    (my - slope * mx, slope)
}

/// Classical fourth-order Runge–Kutta for `y' = f(y)`, `n` steps of `h`:
/// the independent high-accuracy reference of the convergence tests.
pub fn rk4<const M: usize>(f: impl Fn(&[f64; M]) -> [f64; M], mut y: [f64; M], h: f64, n: usize) -> [f64; M] {
    let axpy = |y: &[f64; M], a: f64, k: &[f64; M]| -> [f64; M] { core::array::from_fn(|i| y[i] + a * k[i]) };
    for _ in 0..n {
        let k1 = f(&y);
        let k2 = f(&axpy(&y, h / 2.0, &k1));
        let k3 = f(&axpy(&y, h / 2.0, &k2));
        let k4 = f(&axpy(&y, h, &k3));
        y = core::array::from_fn(|i| y[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]));
    }
    y
}

/// `max_i |a_i − b_i| / max(max_i |b_i|, tiny)`.
pub fn rel_err(a: &[f64], b: &[f64]) -> f64 {
    let scale = b.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(1e-300);
    a.iter().zip(b).fold(0.0f64, |m, (x, y)| m.max((x - y).abs())) / scale
}

/// The slowly varying oscillator `L = ½ q̇² − ½ ω(εt)² q²`, with
/// `ω(s) = 1 + ½ sin s`: a time-dependent Lagrangian whose energy
/// `E = ½ q̇² + ½ ω² q²` changes at the rate `−∂L/∂t = ε ω ω'(εt) q²`.
#[derive(Debug, Clone, Copy)]
pub struct SlowOscillator {
    pub eps: f64,
}

#[lagrangian]
impl SlowOscillator {
    fn lagrangian(&self, t: f64, q: [f64; 1], v: [f64; 1]) -> f64 {
        let w = 1.0 + 0.5 * (self.eps * t).sin();
        0.5 * v[0] * v[0] - 0.5 * w * w * q[0] * q[0]
    }
}

impl SlowOscillator {
    /// `ω(εt)`.
    pub fn omega(&self, t: f64) -> f64 {
        1.0 + 0.5 * (self.eps * t).sin()
    }

    /// `(q, v)` at `t` from `(q0, v0)` at 0 by RK4 with `n` steps.
    pub fn reference(&self, q0: f64, v0: f64, t: f64, n: usize) -> (f64, f64) {
        // Time is carried as a third component so the autonomous RK4 applies.
        let [q, v, _] = rk4(
            |y: &[f64; 3]| {
                let w = self.omega(y[2]);
                [y[1], -w * w * y[0], 1.0]
            },
            [q0, v0, 0.0],
            t / n as f64,
            n,
        );
        (q, v)
    }
}
