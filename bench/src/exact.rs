//! Exact solutions: the pendulum through Jacobi's elliptic functions, the
//! Kepler problem through Kepler's equation.
//!
//! Written once over [`Real`], so the same formulas give `f64` values and
//! double-double ([`DoubleDouble`](lagrangian::DoubleDouble)) ones; either way
//! they are accurate to a few units of the type's precision. (The formulas are
//! those of the facade's Galerkin verification tests, Abramowitz & Stegun 16.4
//! for the elliptic functions.)

use lagrangian::prelude::Real;

/// `π` in the precision of `T`.
pub fn pi<T: Real>() -> T {
    T::one().atan() * 4.0
}

/// `cd(u | m) = cn/dn` by the arithmetic–geometric mean: with `φ_0` from the
/// descending recursion, `cd = cos(φ_1 − φ_0)`.
pub fn jacobi_cd<T: Real>(u: T, m: T) -> T {
    let (mut a, mut b) = (T::one(), (T::one() - m).sqrt());
    let mut c = [T::zero(); 64];
    let mut aa = [T::zero(); 64];
    let mut n = 0;
    loop {
        c[n] = (a - b) * 0.5;
        let an = (a + b) * 0.5;
        b = (a * b).sqrt();
        a = an;
        aa[n] = a;
        n += 1;
        if c[n - 1].abs() <= a * (2.0 * T::EPSILON) || n == 64 {
            break;
        }
    }
    // Reduce u modulo the period 4K of cd, K = π / (2 a_N).
    let period = pi::<T>() * 4.0 / (a * 2.0);
    let u = u - period * (u / period).to_f64().round();
    let mut phi = a * u * 2f64.powi(n as i32);
    let mut prev = phi;
    for i in (0..n).rev() {
        prev = phi;
        phi = (phi + (c[i] / aa[i] * phi.sin()).asin()) * 0.5;
    }
    (prev - phi).cos()
}

/// `θ(t)` of `θ̈ = −ω² sin θ` from rest at `θ0`: `sin(θ/2) = k cd(ωt | k²)`, `k = sin(θ0/2)`.
pub fn pendulum_angle<T: Real>(omega: T, theta0: T, t: T) -> T {
    let k = (theta0 * 0.5).sin();
    (k * jacobi_cd(omega * t, k * k)).asin() * 2.0
}

/// The period of that pendulum, `4K(k²)/ω`.
pub fn pendulum_period<T: Real>(omega: T, theta0: T) -> T {
    let k = (theta0 * 0.5).sin();
    let (mut a, mut b) = (T::one(), (T::one() - k * k).sqrt());
    for _ in 0..64 {
        if (a - b).abs() <= a * (4.0 * T::EPSILON) {
            break;
        }
        let an = (a + b) * 0.5;
        b = (a * b).sqrt();
        a = an;
    }
    pi::<T>() * 2.0 / (a * omega)
}

/// The eccentric anomaly `E` with `E − e sin E = M` (Newton from `M + e sin M`,
/// safeguarded by bisection on the bracket `[M − e, M + e]`, which always holds the root).
pub fn eccentric_anomaly<T: Real>(e: T, m: T) -> T {
    let (mut lo, mut hi) = (m - e, m + e);
    let mut ea = m + e * m.sin();
    for _ in 0..100 {
        let f = ea - e * ea.sin() - m;
        if f.to_f64() > 0.0 {
            hi = ea;
        } else {
            lo = ea;
        }
        let mut next = ea - f / (T::one() - e * ea.cos());
        // A Newton step that leaves the bracket (possible near e = 1) is replaced by bisection.
        if !(next.to_f64() > lo.to_f64() && next.to_f64() < hi.to_f64()) {
            next = (lo + hi) * 0.5;
        }
        let d = (next - ea).abs();
        ea = next;
        if d.to_f64() <= T::EPSILON * ea.abs().to_f64().max(1.0) {
            break;
        }
    }
    ea
}

/// Cartesian position of the Kepler orbit with `μ = 1`, `a = 1`, eccentricity
/// `e`, pericentre on the positive x axis at `t = 0`, moving counter-clockwise.
pub fn kepler_position<T: Real>(e: T, t: T) -> [T; 2] {
    let ea = eccentric_anomaly(e, t);
    [ea.cos() - e, (T::one() - e * e).sqrt() * ea.sin()]
}

/// The same orbit in polar coordinates `(r, φ)`, with `φ` the true anomaly
/// counted on from 0 (continuous in `t`, not reduced modulo 2π):
/// `r = 1 − e cos E`, `φ = E + 2 atan(β sin E / (1 − β cos E))` with
/// `β = e / (1 + √(1 − e²))` (the half-angle relation
/// `tan(φ/2) = √((1 + e)/(1 − e)) tan(E/2)` written without its branch cuts).
pub fn kepler_polar<T: Real>(e: T, t: T) -> [T; 2] {
    let ea = eccentric_anomaly(e, t);
    let beta = e / (T::one() + (T::one() - e * e).sqrt());
    let phi = ea + (beta * ea.sin() / (T::one() - beta * ea.cos())).atan() * 2.0;
    [T::one() - e * ea.cos(), phi]
}

/// Initial data `(q0, v0)` of that orbit, at pericentre.
pub fn kepler_start(e: f64) -> ([f64; 2], [f64; 2]) {
    ([1.0 - e, 0.0], [0.0, ((1.0 + e) / (1.0 - e)).sqrt()])
}
