//! Exact solutions for the Galerkin verification tests: the pendulum through
//! Jacobi's elliptic functions, Kepler's problem through Kepler's equation.
//!
//! Written once over [`Real`], so the same formulas serve `f64` runs and the
//! extended-precision ([`DoubleDouble`](lagrangian::DoubleDouble)) runs that
//! verify orders up to 16; either way they are accurate to a few units of the
//! type's precision, far below the errors the tests measure.
#![allow(dead_code, missing_docs, unreachable_pub)]

use lagrangian::Real;

/// `π` in the precision of `T`.
pub fn pi<T: Real>() -> T {
    T::one().atan() * 4.0
}

/// `cd(u | m) = cn/dn` by the arithmetic–geometric mean (Abramowitz &
/// Stegun 16.4): with `φ_0` from the descending recursion,
/// `cd = cos(φ_1 − φ_0)`.
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

/// Kepler orbit with `μ = 1`, `a = 1`, eccentricity `e`, pericentre at
/// `t = 0` on the axis `φ = 0`: `(r, φ)` at time `t`, with `φ` unwrapped.
pub fn kepler_polar<T: Real>(e: T, t: T) -> [T; 2] {
    let m = t;
    let mut ea = m + e * m.sin();
    for _ in 0..60 {
        let d = (ea - e * ea.sin() - m) / (T::one() - e * ea.cos());
        ea -= d;
        if d.abs().to_f64() <= T::EPSILON * ea.abs().to_f64().max(1.0) {
            break;
        }
    }
    // ν = E + 2 atan(β sin E / (1 − β cos E)), continuous in E.
    let beta = e / (T::one() + (T::one() - e * e).sqrt());
    [T::one() - e * ea.cos(), ea + (beta * ea.sin() / (T::one() - beta * ea.cos())).atan() * 2.0]
}

/// Initial data `(q0, v0)` of that orbit in polar coordinates, at pericentre.
pub fn kepler_start<T: Real>(e: T) -> ([T; 2], [T; 2]) {
    let r = T::one() - e;
    ([r, T::zero()], [T::zero(), (T::one() - e * e).sqrt() / (r * r)])
}

#[test]
fn references_are_consistent() {
    use core::f64::consts::PI;
    // cd at u = 0 is 1; the pendulum returns to θ0 after a period, crosses 0 at a quarter.
    assert!((jacobi_cd(0.0, 0.3) - 1.0f64).abs() < 1e-15);
    let (w, th) = (3.0, 1.0);
    let period = pendulum_period(w, th);
    assert!((pendulum_angle(w, th, period) - th).abs() < 1e-13);
    assert!(pendulum_angle(w, th, 0.25 * period).abs() < 1e-13);
    // Small amplitude: the period tends to 2π/ω.
    assert!((pendulum_period(w, 1e-6) - 2.0 * PI / w).abs() < 1e-12);
    // Kepler: back at pericentre after 2π, φ advanced by 2π.
    let [r, phi] = kepler_polar(0.5, 2.0 * PI);
    assert!((r - 0.5).abs() < 1e-14 && (phi - 2.0 * PI).abs() < 1e-13);
}
