//! Verification: fitted orders of convergence against analytic and
//! high-accuracy references (midpoint and trapezoid: 2; α-β with α ∈ {0, 1}: 1).
use crate::common;

use common::*;
use lagrangian::{AlphaBeta, DiscreteLagrangian, Integrator, Lagrangian, Midpoint, Trapezoid};

/// `q(T)` after integrating from `(0, q0, v0)` with step `h`.
fn final_q<S: Lagrangian<N>, M: DiscreteLagrangian, const N: usize>(
    system: S,
    method: M,
    h: f64,
    q0: [f64; N],
    v0: [f64; N],
    t_end: f64,
) -> [f64; N] {
    let mut sim = Integrator::new(system, method, h).start(0.0, q0, v0).unwrap();
    sim.run_until(t_end, |_| {}).unwrap();
    assert!((sim.state().t - t_end).abs() < 1e-12);
    sim.state().q
}

const STEPS: [f64; 5] = [0.04, 0.02, 0.01, 0.005, 0.0025];

fn order_against<M: DiscreteLagrangian, S: Lagrangian<N>, const N: usize>(
    make: impl Fn() -> S,
    method: M,
    q0: [f64; N],
    v0: [f64; N],
    t_end: f64,
    reference: [f64; N],
) -> (f64, Vec<f64>) {
    let errors: Vec<f64> =
        STEPS.iter().map(|&h| rel_err(&final_q(make(), method, h, q0, v0, t_end), &reference)).collect();
    (fitted_order(&STEPS, &errors), errors)
}

#[test]
fn harmonic_oscillator_orders_against_the_analytic_solution() {
    let (q0, v0, t_end): (f64, f64, f64) = (0.7, 0.4, 3.0);
    let exact = [q0 * t_end.cos() + v0 * t_end.sin()];
    let make = || Oscillator { m: 1.0, k: 1.0 };
    for (name, order, expected) in [
        ("midpoint", order_against(make, Midpoint, [q0], [v0], t_end, exact), 2.0),
        ("trapezoid", order_against(make, Trapezoid, [q0], [v0], t_end, exact), 2.0),
        ("alpha=0", order_against(make, AlphaBeta::EULER_B, [q0], [v0], t_end, exact), 1.0),
        ("alpha=1", order_against(make, AlphaBeta::EULER_A, [q0], [v0], t_end, exact), 1.0),
    ] {
        let (fitted, errors) = order;
        assert!((fitted - expected).abs() <= 0.1, "{name}: order {fitted}, errors {errors:?}");
    }
}

#[test]
fn pendulum_orders_against_a_high_accuracy_reference() {
    let (q0, v0, t_end) = (1.2, 0.0, 3.0);
    let s = PENDULUM;
    let w2 = s.g / s.l;
    // RK4 with h = 1e-4: global error ~1e-15, far below the errors measured.
    let reference = rk4(|y: &[f64; 2]| [y[1], -w2 * y[0].sin()], [q0, v0], 1e-4, 30_000);
    let make = || Pendulum { ..PENDULUM };
    for (name, order, expected) in [
        ("midpoint", order_against(make, Midpoint, [q0], [v0], t_end, [reference[0]]), 2.0),
        ("trapezoid", order_against(make, Trapezoid, [q0], [v0], t_end, [reference[0]]), 2.0),
        ("alpha=0", order_against(make, AlphaBeta::EULER_B, [q0], [v0], t_end, [reference[0]]), 1.0),
        ("alpha=1", order_against(make, AlphaBeta::EULER_A, [q0], [v0], t_end, [reference[0]]), 1.0),
    ] {
        let (fitted, errors) = order;
        assert!((fitted - expected).abs() <= 0.1, "{name}: order {fitted}, errors {errors:?}");
    }
}

#[test]
fn charged_particle_in_a_magnetic_field_converges_at_order_two() {
    let c = CHARGED;
    let (q0, v0, t_end) = ([0.5, 0.0], [0.0, 0.8], 3.0);
    let w = c.e / c.m;
    // Lorentz force: m ẍ = e(−∂φ/∂x + B ẏ), m ÿ = e(−∂φ/∂y − B ẋ).
    let f = |y: &[f64; 4]| {
        [
            y[2],
            y[3],
            w * (-c.kappa * y[0] - 4.0 * c.eps * y[0] * y[0] * y[0] + c.b * y[3]),
            w * (-c.kappa * y[1] - c.b * y[2]),
        ]
    };
    let reference = rk4(f, [q0[0], q0[1], v0[0], v0[1]], 1e-4, 30_000);
    let make = || ChargedParticle { ..CHARGED };
    for (name, (fitted, errors)) in [
        ("midpoint", order_against(make, Midpoint, q0, v0, t_end, [reference[0], reference[1]])),
        ("trapezoid", order_against(make, Trapezoid, q0, v0, t_end, [reference[0], reference[1]])),
    ] {
        assert!((fitted - 2.0).abs() <= 0.1, "{name}: order {fitted}, errors {errors:?}");
    }
}

#[test]
fn declared_orders() {
    assert_eq!(Midpoint.order(), 2);
    assert_eq!(Trapezoid.order(), 2);
    assert_eq!(AlphaBeta::new(0.5).unwrap().order(), 2);
    assert_eq!(AlphaBeta::EULER_A.order(), 1);
    assert!(AlphaBeta::new(f64::NAN).is_none());
}
