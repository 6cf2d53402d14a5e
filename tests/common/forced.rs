//! Systems with forces and dissipation (docs/theory.md §6) and with symmetries (§7),
//! shared by `tests/verification/forces.rs` and `tests/verification/noether.rs`.

use lagrangian::prelude::*;

/// `m q̈ + c q̇ + k q = 0`: `L = ½ m q̇² − ½ k q²`, `R = ½ c q̇²`.
#[derive(Clone, Debug)]
pub struct DampedOscillator {
    pub m: f64,
    pub k: f64,
    pub c: f64,
}

#[lagrangian]
impl DampedOscillator {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * self.m * v[0] * v[0] - 0.5 * self.k * q[0] * q[0]
    }

    fn dissipation(&self, _q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * self.c * v[0] * v[0]
    }
}

impl DampedOscillator {
    /// The exact `(q, q̇)` at `t` from `(q0, 0)`, underdamped.
    pub fn exact(&self, q0: f64, t: f64) -> [f64; 2] {
        let alpha = self.c / (2.0 * self.m);
        let wd = (self.k / self.m - alpha * alpha).sqrt();
        let (s, c) = (wd * t).sin_cos();
        let decay = (-alpha * t).exp();
        let q = q0 * decay * (c + alpha / wd * s);
        let v = -q0 * decay * (alpha * alpha + wd * wd) / wd * s;
        [q, v]
    }
}

/// Series RLC circuit driven by `E(t) = E0 cos(Ω t)`, charge `q` on the
/// capacitor: `L = ½ ℓ q̇² − q²/(2C)`, `R = ½ r q̇²`, force `E(t)`.
#[derive(Debug)]
pub struct Rlc {
    /// Inductance ℓ.
    pub l: f64,
    /// Resistance.
    pub r: f64,
    /// Capacitance.
    pub c: f64,
    /// Amplitude of the source.
    pub e0: f64,
    /// Angular frequency of the source.
    pub omega: f64,
}

#[lagrangian]
impl Rlc {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * self.l * v[0] * v[0] - 0.5 * q[0] * q[0] / self.c
    }

    fn dissipation(&self, _q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * self.r * v[0] * v[0]
    }

    fn force(&self, t: f64, _q: [f64; 1], _v: [f64; 1]) -> [f64; 1] {
        [self.e0 * (self.omega * t).cos()]
    }
}

impl Rlc {
    /// The exact `(q, i)` at `t` from `q = i = 0` at `t = 0` (underdamped):
    /// the steady state `Re(E0 e^{iΩt} / Z)`, `Z = 1/C − ℓΩ² + i r Ω`, plus
    /// the decaying transient that meets the initial data.
    pub fn exact(&self, t: f64) -> [f64; 2] {
        let alpha = self.r / (2.0 * self.l);
        let wd = (1.0 / (self.l * self.c) - alpha * alpha).sqrt();
        let (zr, zi) = (1.0 / self.c - self.l * self.omega * self.omega, self.r * self.omega);
        let norm = zr * zr + zi * zi;
        // E0 / Z = a + i b.
        let (a, b) = (self.e0 * zr / norm, -self.e0 * zi / norm);
        let c1 = -a;
        let c2 = (b * self.omega + alpha * c1) / wd;
        let (sw, cw) = (self.omega * t).sin_cos();
        let (sd, cd) = (wd * t).sin_cos();
        let decay = (-alpha * t).exp();
        let q = a * cw - b * sw + decay * (c1 * cd + c2 * sd);
        let i = -self.omega * (a * sw + b * cw) + decay * ((-alpha * c1 + wd * c2) * cd + (-alpha * c2 - wd * c1) * sd);
        [q, i]
    }
}

/// Fu, Dai & Tang §4, the electromechanical sensor: armature `x` (`q[0]`) and
/// charge `q` (`q[1]`), `L = ½ m ẋ² + ½ L1(x) q̇² − ½ k x² + m g x` with
/// `L1(x) = L0 / (1 + x/a)`, resistor `R = ½ r q̇²` and battery EMF `E` on the
/// charge. `a = ∞` gives the constant inductance `L1 = L0`.
#[derive(Debug)]
pub struct Sensor {
    pub m: f64,
    pub k: f64,
    pub g: f64,
    pub l0: f64,
    pub a: f64,
    pub r: f64,
    pub e: f64,
}

#[lagrangian]
impl Sensor {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let x = q[0];
        let l1 = self.l0 / (1.0 + x / self.a);
        0.5 * self.m * v[0] * v[0] + 0.5 * l1 * v[1] * v[1] - 0.5 * self.k * x * x + self.m * self.g * x
    }

    fn dissipation(&self, _q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * self.r * v[1] * v[1]
    }

    fn force(&self, _q: [f64; 2], _v: [f64; 2]) -> [f64; 2] {
        [0.0, self.e]
    }
}

pub const SENSOR: Sensor = Sensor { m: 0.2, k: 80.0, g: 9.81, l0: 0.5, a: f64::INFINITY, r: 10.0, e: 12.0 };
pub const SENSOR_VARIABLE: Sensor = Sensor { a: 0.2, ..SENSOR };

/// Planar Kepler problem in Cartesian coordinates, `L = ½|v|² + μ/r`,
/// optionally with linear drag `R = ½ c |v|²` and a tangential thrust of
/// magnitude `s` (force `s (−y, x)/r`). Rotation-invariant; no coordinate is cyclic.
#[derive(Debug)]
pub struct KeplerCartesian {
    pub mu: f64,
    pub c: f64,
    pub s: f64,
}

#[lagrangian]
impl KeplerCartesian {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let r = (q[0] * q[0] + q[1] * q[1]).sqrt();
        0.5 * (v[0] * v[0] + v[1] * v[1]) + self.mu / r
    }

    fn dissipation(&self, _q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * self.c * (v[0] * v[0] + v[1] * v[1])
    }

    fn force(&self, q: [f64; 2], _v: [f64; 2]) -> [f64; 2] {
        let r = (q[0] * q[0] + q[1] * q[1]).sqrt();
        [-self.s * q[1] / r, self.s * q[0] / r]
    }
}

/// Kepler without forces (no `force`, no `dissipation`): rotation-invariant,
/// declared in the attribute.
#[derive(Debug)]
pub struct FreeKeplerCartesian {
    pub mu: f64,
}

#[lagrangian(symmetry = rotation(0, 1))]
impl FreeKeplerCartesian {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let r = (q[0] * q[0] + q[1] * q[1]).sqrt();
        0.5 * (v[0] * v[0] + v[1] * v[1]) + self.mu / r
    }
}

/// Spherical pendulum, polar angle `θ` and azimuth `φ` (cyclic):
/// `L = ½ m l² (θ̇² + sin²θ φ̇²) + m g l cos θ`.
#[derive(Debug)]
pub struct SphericalPendulum {
    pub m: f64,
    pub l: f64,
    pub g: f64,
}

#[lagrangian]
impl SphericalPendulum {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let s = q[0].sin();
        0.5 * self.m * self.l * self.l * (v[0] * v[0] + s * s * v[1] * v[1]) + self.m * self.g * self.l * q[0].cos()
    }
}

/// Two bodies on a line joined by a Morse spring: invariant under the
/// translation of both, `ξ = (1, 1)`, a generator the user declares (here in
/// the attribute).
#[derive(Debug)]
pub struct MorsePair {
    pub m1: f64,
    pub m2: f64,
    pub d: f64,
    pub w: f64,
    pub r0: f64,
}

#[lagrangian(symmetry = generator(|_| [1.0, 1.0]))]
impl MorsePair {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let e = 1.0 - (-self.w * (q[1] - q[0] - self.r0)).exp();
        0.5 * self.m1 * v[0] * v[0] + 0.5 * self.m2 * v[1] * v[1] - self.d * e * e
    }
}
