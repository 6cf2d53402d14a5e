//! Exact solutions for the Galerkin verification tests: the pendulum through
//! Jacobi's elliptic functions, Kepler's problem through Kepler's equation.
//! Both are accurate to a few ulps, far below the errors the tests measure.
#![allow(dead_code, missing_docs, unreachable_pub)]

use core::f64::consts::PI;

/// `cd(u | m) = cn/dn` by the arithmetic–geometric mean (Abramowitz &
/// Stegun 16.4): with `φ_0` from the descending recursion,
/// `cd = cos(φ_1 − φ_0)`.
pub fn jacobi_cd(u: f64, m: f64) -> f64 {
    let (mut a, mut b) = (1.0f64, (1.0 - m).sqrt());
    let mut c = [0.0f64; 64];
    let mut aa = [0.0f64; 64];
    let mut n = 0;
    loop {
        c[n] = 0.5 * (a - b);
        let an = 0.5 * (a + b);
        b = (a * b).sqrt();
        a = an;
        aa[n] = a;
        n += 1;
        if c[n - 1].abs() <= 2e-16 * a || n == 64 {
            break;
        }
    }
    // Reduce u modulo the period 4K of cd, K = π / (2 a_N).
    let period = 4.0 * PI / (2.0 * a);
    let u = u - period * (u / period).round();
    let mut phi = 2f64.powi(n as i32) * a * u;
    let mut prev = phi;
    for i in (0..n).rev() {
        prev = phi;
        phi = 0.5 * (phi + (c[i] / aa[i] * phi.sin()).asin());
    }
    (prev - phi).cos()
}

/// `θ(t)` of `θ̈ = −ω² sin θ` from rest at `θ0`: `sin(θ/2) = k cd(ωt | k²)`, `k = sin(θ0/2)`.
pub fn pendulum_angle(omega: f64, theta0: f64, t: f64) -> f64 {
    let k = (theta0 / 2.0).sin();
    2.0 * (k * jacobi_cd(omega * t, k * k)).asin()
}

/// The period of that pendulum, `4K(k²)/ω`.
pub fn pendulum_period(omega: f64, theta0: f64) -> f64 {
    let k = (theta0 / 2.0).sin();
    let (mut a, mut b) = (1.0f64, (1.0 - k * k).sqrt());
    for _ in 0..64 {
        if (a - b).abs() <= 4e-16 * a {
            break;
        }
        let an = 0.5 * (a + b);
        b = (a * b).sqrt();
        a = an;
    }
    2.0 * PI / (a * omega)
}

/// Kepler orbit with `μ = 1`, `a = 1`, eccentricity `e`, pericentre at
/// `t = 0` on the axis `φ = 0`: `(r, φ)` at time `t`, with `φ` unwrapped.
pub fn kepler_polar(e: f64, t: f64) -> [f64; 2] {
    let m = t;
    let mut ea = m + e * m.sin();
    for _ in 0..60 {
        let d = (ea - e * ea.sin() - m) / (1.0 - e * ea.cos());
        ea -= d;
        if d.abs() <= 1e-16 * ea.abs().max(1.0) {
            break;
        }
    }
    // ν = E + 2 atan(β sin E / (1 − β cos E)), continuous in E.
    let beta = e / (1.0 + (1.0 - e * e).sqrt());
    [1.0 - e * ea.cos(), ea + 2.0 * (beta * ea.sin() / (1.0 - beta * ea.cos())).atan()]
}

/// Initial data `(q0, v0)` of that orbit in polar coordinates, at pericentre.
pub fn kepler_start(e: f64) -> ([f64; 2], [f64; 2]) {
    let r = 1.0 - e;
    ([r, 0.0], [0.0, (1.0 - e * e).sqrt() / (r * r)])
}

#[test]
fn references_are_consistent() {
    // cd at u = 0 is 1; the pendulum returns to θ0 after a period, crosses 0 at a quarter.
    assert!((jacobi_cd(0.0, 0.3) - 1.0).abs() < 1e-15);
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
