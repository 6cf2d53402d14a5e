//! Dense output: the fitted order of the error at mid-step against exact
//! solutions (the harmonic oscillator and the pendulum at 1 rad through
//! Jacobi's elliptic functions).
//!
//! Each measurement starts the integrator on the exact solution at a generic
//! time `t_a`, takes one step of size `h` and compares the solution object's
//! values at `τ = 0.1, 0.2, …, 0.9` of the step (through `Plan::save_at`, so
//! the path users run) with the exact ones; the largest counts. (At
//! mid-step alone the Galerkin s = 2 polynomial passes through its interior
//! Gauss–Lobatto node, where it is one order better: 3.87 instead of 3.)
//! That error is the interpolation error plus the step's
//! local error, so its order is `min(p + 1, r)` for a method of order `p`
//! and an interpolant of order `r` (see `lagrangian::dense`):
//!
//! | method | interpolant | `p + 1` | `r` | expected |
//! | --- | --- | --- | --- | --- |
//! | midpoint | native (cubic Hermite) | 3 | 4 | 3 |
//! | Galerkin s = 2 | native (its quadratic) | 5 | 3 | 3 |
//! | Galerkin s = 3 | native (its cubic) | 7 | 4 | 4 |
//! | Galerkin s = 2 | cubic Hermite | 5 | 4 | 4 |
//! | Galerkin s = 3 | quintic Hermite | 7 | 6 | 6 |
//!
//! The interpolants alone (fed the exact `q, v, a` at both ends) are checked
//! too: orders 4 and 6. `cargo test --test verification dense_output:: -- --nocapture`
//! prints the errors and fits.

use crate::common::galerkin_reference;

use galerkin_reference::pendulum_angle;
use lagrangian::dense::{DenseStep, Hermite, Node};
use lagrangian::prelude::*;
use lagrangian::{DenseKind, Plan, Stepping};

#[derive(Clone)]
struct Pendulum {
    omega2: f64,
}

#[lagrangian]
impl Pendulum {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] + self.omega2 * q[0].cos()
    }
}

#[derive(Clone)]
struct Oscillator;

#[lagrangian]
impl Oscillator {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] - 0.5 * 4.0 * q[0] * q[0]
    }
}

const OMEGA2: f64 = 9.81;
const THETA0: f64 = 1.0;
const T_A: f64 = 0.3;

/// The exact pendulum `(θ, θ̇)` from rest at 1 rad; `θ̇ < 0` on the first quarter period.
fn pendulum(t: f64) -> (f64, f64) {
    let theta = pendulum_angle(OMEGA2.sqrt(), THETA0, t);
    (theta, -(2.0 * OMEGA2 * (theta.cos() - THETA0.cos())).sqrt())
}

/// The exact oscillator `q = cos 2t`.
fn oscillator(t: f64) -> (f64, f64) {
    ((2.0 * t).cos(), -2.0 * (2.0 * t).sin())
}

/// Least-squares slope of `log e` against `log h`.
fn slope(h: &[f64], e: &[f64]) -> f64 {
    let x: Vec<f64> = h.iter().map(|h| h.ln()).collect();
    let y: Vec<f64> = e.iter().map(|e| e.ln()).collect();
    let n = x.len() as f64;
    let (mx, my) = (x.iter().sum::<f64>() / n, y.iter().sum::<f64>() / n);
    let sxy: f64 = x.iter().zip(&y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let sxx: f64 = x.iter().map(|a| (a - mx) * (a - mx)).sum();
    sxy / sxx
}

/// The largest error at `τ = 0.1, 0.2, …, 0.9` inside one step of size `h`
/// from the exact state at `T_A`.
fn mid_step_error<I: Stepping<1>>(
    start: impl Fn(f64, [f64; 1], [f64; 1]) -> I,
    solve: impl Fn(&mut I, Plan<'static>) -> lagrangian::Solution,
    exact: fn(f64) -> (f64, f64),
    kind: DenseKind,
    h: f64,
) -> f64 {
    let (q, v) = exact(T_A);
    let mut sim = start(h, [q], [v]);
    let times: Vec<f64> = (1..10).map(|k| T_A + 0.1 * k as f64 * h).collect();
    let sol = solve(&mut sim, Plan::until(T_A + h).every(0).save_at(times).dense(kind));
    assert!(sol.is_finished(), "{:?}", sol.status);
    assert_eq!(sol.len(), 9);
    sol.t.iter().zip(&sol.q).map(|(&t, q)| (q[0] - exact(t).0).abs()).fold(0.0, f64::max)
}

fn check(name: &str, expected: f64, errors: impl Fn(f64) -> f64, steps: &[f64]) {
    let e: Vec<f64> = steps.iter().map(|&h| errors(h)).collect();
    let p = slope(steps, &e);
    let e_text: Vec<String> = e.iter().map(|x| format!("{x:.2e}")).collect();
    println!("{name}: errors {}, fitted order {p:.3} (expected {expected})", e_text.join(" "));
    assert!((p - expected).abs() < 0.2, "{name}: fitted order {p:.3}, expected {expected}");
}

macro_rules! galerkin {
    ($s:literal, $system:expr) => {
        (
            |h: f64, q: [f64; 1], v: [f64; 1]| {
                GalerkinIntegrator::new($system, Galerkin::<$s, $s>::gauss(), h).start(T_A, q, v).unwrap()
            },
            |sim: &mut GalerkinIntegrator<_, 1, $s, $s>, plan| sim.solve(plan).unwrap(),
        )
    };
}

#[test]
fn midpoint_dense_output_has_order_three_locally() {
    let steps = [0.1, 0.05, 0.025, 0.0125];
    for (name, exact) in [("oscillator", oscillator as fn(f64) -> (f64, f64)), ("pendulum", pendulum)] {
        let errors = |h: f64| {
            if name == "oscillator" {
                let start = |h, q, v| Integrator::new(Oscillator, Midpoint, h).start(T_A, q, v).unwrap();
                mid_step_error(start, |s, p| s.solve(p).unwrap(), exact, DenseKind::Native, h)
            } else {
                let sys = Pendulum { omega2: OMEGA2 };
                let start = |h, q, v| Integrator::new(sys.clone(), Midpoint, h).start(T_A, q, v).unwrap();
                mid_step_error(start, |s, p| s.solve(p).unwrap(), exact, DenseKind::Native, h)
            }
        };
        check(&format!("midpoint, cubic Hermite, {name}"), 3.0, errors, &steps);
    }
}

#[test]
fn galerkin_dense_output_orders() {
    let steps = [0.2, 0.1, 0.05, 0.025];
    let sys = Pendulum { omega2: OMEGA2 };
    for (label, exact) in [("oscillator", oscillator as fn(f64) -> (f64, f64)), ("pendulum", pendulum)] {
        let run2 = |kind, h| {
            if label == "oscillator" {
                let (start, solve) = galerkin!(2, Oscillator);
                mid_step_error(start, solve, exact, kind, h)
            } else {
                let (start, solve) = galerkin!(2, sys.clone());
                mid_step_error(start, solve, exact, kind, h)
            }
        };
        let run3 = |kind, h| {
            if label == "oscillator" {
                let (start, solve) = galerkin!(3, Oscillator);
                mid_step_error(start, solve, exact, kind, h)
            } else {
                let (start, solve) = galerkin!(3, sys.clone());
                mid_step_error(start, solve, exact, kind, h)
            }
        };
        check(&format!("galerkin s = 2, own polynomial, {label}"), 3.0, |h| run2(DenseKind::Native, h), &steps);
        check(&format!("galerkin s = 2, cubic Hermite, {label}"), 4.0, |h| run2(DenseKind::Cubic, h), &steps);
        check(&format!("galerkin s = 3, own polynomial, {label}"), 4.0, |h| run3(DenseKind::Native, h), &steps);
        check(&format!("galerkin s = 3, quintic Hermite, {label}"), 6.0, |h| run3(DenseKind::Quintic, h), &steps);
    }
}

/// The interpolants on exact data: orders 4 (cubic) and 6 (quintic).
#[test]
fn hermite_interpolants_on_exact_data() {
    let steps = [0.2, 0.1, 0.05, 0.025];
    let accel = |q: f64| -OMEGA2 * q.sin();
    let node = |t: f64| {
        let (q, v) = pendulum(t);
        Node { t, q: [q], p: [v], v: [v] }
    };
    let cubic = |h: f64| {
        let d = Hermite::cubic(&node(T_A), &node(T_A + h));
        (d.eval(T_A + 0.5 * h).0[0] - pendulum(T_A + 0.5 * h).0).abs()
    };
    let quintic = |h: f64| {
        let (a, b) = (node(T_A), node(T_A + h));
        let d = Hermite::quintic(&a, [accel(a.q[0])], &b, [accel(b.q[0])]);
        (d.eval(T_A + 0.5 * h).0[0] - pendulum(T_A + 0.5 * h).0).abs()
    };
    check("cubic Hermite on exact data", 4.0, cubic, &steps);
    check("quintic Hermite on exact data", 6.0, quintic, &steps);
}

/// Over a run, dense output keeps the method's order: midpoint, order 2 at
/// every mid-step over a period of the oscillator.
#[test]
fn midpoint_dense_output_over_a_run_has_order_two() {
    let steps = [0.04, 0.02, 0.01, 0.005];
    let errors = |h: f64| {
        let mut sim = Integrator::new(Oscillator, Midpoint, h).start(0.0, [1.0], [0.0]).unwrap();
        let n = (3.0 / h).round() as usize;
        let times: Vec<f64> = (0..n).map(|k| (k as f64 + 0.5) * h).collect();
        let sol = sim.solve(Plan::until(3.0).every(0).save_at(times)).unwrap();
        sol.t.iter().zip(&sol.q).map(|(&t, q)| (q[0] - oscillator(t).0).abs()).fold(0.0, f64::max)
    };
    check("midpoint over t ∈ [0, 3], max at mid-steps", 2.0, errors, &steps);
}
