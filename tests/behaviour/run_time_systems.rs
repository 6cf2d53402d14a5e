//! The systems several run-time-size test files step at both sizes: each
//! written once, so that one test binary builds the steppers of each once.

use lagrangian::prelude::*;

/// Four FPU-β masses between walls, their number known at compile time.
#[derive(Clone)]
pub struct Chain4;

#[lagrangian]
impl Chain4 {
    fn lagrangian(&self, q: [f64; 4], v: [f64; 4]) -> f64 {
        let mut kinetic = 0.0;
        for i in 0..4 {
            kinetic += 0.5 * v[i] * v[i];
        }
        let mut potential = 0.5 * q[0] * q[0] + 0.25 * q[0].powi(4) + 0.5 * q[3] * q[3] + 0.25 * q[3].powi(4);
        for i in 0..3 {
            let d = q[i + 1] - q[i];
            potential += 0.5 * d * d + 0.25 * d.powi(4);
        }
        kinetic - potential
    }
}

/// The same chain with its size known at run time; `walls: false` frees its ends.
#[derive(Clone, Debug)]
pub struct Chain {
    pub n: usize,
    pub walls: bool,
}

#[lagrangian]
impl Chain {
    fn dimension(&self) -> usize {
        self.n
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        let n = q.len();
        let mut kinetic = 0.0;
        for i in 0..n {
            kinetic += 0.5 * v[i] * v[i];
        }
        let mut potential = 0.0;
        if self.walls {
            potential += 0.5 * q[0] * q[0] + 0.25 * q[0].powi(4) + 0.5 * q[n - 1] * q[n - 1] + 0.25 * q[n - 1].powi(4);
        }
        for i in 0..n - 1 {
            let d = q[i + 1] - q[i];
            potential += 0.5 * d * d + 0.25 * d.powi(4);
        }
        kinetic - potential
    }
}

/// A double pendulum (unit masses and lengths, gravity `g`): a
/// non-separable `L`, its mass matrix depends on `q`.
#[derive(Clone)]
pub struct DoublePendulum {
    pub g: f64,
}

#[lagrangian]
impl DoublePendulum {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let kinetic = v[0] * v[0] + 0.5 * v[1] * v[1] + v[0] * v[1] * (q[0] - q[1]).cos();
        kinetic + 2.0 * self.g * q[0].cos() + self.g * q[1].cos()
    }
}

/// The double pendulum over slices.
#[derive(Clone)]
pub struct DoublePendulumDyn {
    pub g: f64,
}

#[lagrangian]
impl DoublePendulumDyn {
    fn dimension(&self) -> usize {
        2
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        let kinetic = v[0] * v[0] + 0.5 * v[1] * v[1] + v[0] * v[1] * (q[0] - q[1]).cos();
        kinetic + 2.0 * self.g * q[0].cos() + self.g * q[1].cos()
    }
}

/// [`DoublePendulum`] under the Earth's gravity, `g = 9.81`.
pub const PENDULUM: DoublePendulum = DoublePendulum { g: 9.81 };

/// [`DoublePendulumDyn`] under the Earth's gravity.
pub const PENDULUM_DYN: DoublePendulumDyn = DoublePendulumDyn { g: 9.81 };

/// An oscillator whose stiffness depends on time: its discrete energy
/// changes by `−(∂A/∂t_k + ∂A/∂t_{k+1})` at each step.
#[derive(Clone)]
pub struct Pumped;

#[lagrangian]
impl Pumped {
    fn lagrangian(&self, t: f64, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] - 0.5 * (1.0 + 0.2 * t.sin()) * q[0] * q[0]
    }
}

/// The same oscillator over slices.
#[derive(Clone)]
pub struct PumpedDyn;

#[lagrangian]
impl PumpedDyn {
    fn dimension(&self) -> usize {
        1
    }

    fn lagrangian(&self, t: f64, q: &[f64], v: &[f64]) -> f64 {
        0.5 * v[0] * v[0] - 0.5 * (1.0 + 0.2 * t.sin()) * q[0] * q[0]
    }
}

/// Kepler in Cartesian coordinates, μ = 1.
#[derive(Clone)]
pub struct Kepler;

#[lagrangian]
impl Kepler {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) + 1.0 / (q[0] * q[0] + q[1] * q[1]).sqrt()
    }
}

/// Kepler with its size known at run time.
#[derive(Clone, Debug)]
pub struct KeplerDyn;

#[lagrangian]
impl KeplerDyn {
    fn dimension(&self) -> usize {
        2
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) + 1.0 / (q[0] * q[0] + q[1] * q[1]).sqrt()
    }
}
