//! Verification: compositions of symmetric bases other than the trapezoid
//! through `Problem` (`Scheme::composed`) have the order `max(p, q)` of a
//! symmetric base of order `p` under weights of order `q`: fitted orders
//! (± 0.2) on the double pendulum, whose configuration-dependent mass makes
//! every sub-step a Newton solve, against Galerkin s = 6 (order 12) at a
//! step 20 times smaller; and one of them, midpoint with Yoshida 6's
//! weights, at a run-time size (the reverse-mode driver's sub-steps).
use crate::common;

use common::fitted_order;
use lagrangian::prelude::*;

#[derive(Clone)]
struct DoublePendulum;

#[lagrangian]
impl DoublePendulum {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let kinetic = v[0] * v[0] + 0.5 * v[1] * v[1] + v[0] * v[1] * (q[0] - q[1]).cos();
        kinetic + 2.0 * 9.81 * q[0].cos() + 9.81 * q[1].cos()
    }
}

const T_END: f64 = 1.0;

fn problem() -> Problem<DoublePendulum, Dim<2>> {
    let tight = NewtonOptions { rtol: 1e-15, ..NewtonOptions::default() };
    Problem::new(DoublePendulum, 0.0, [1.0, -0.5], [0.0, 0.3]).newton(tight)
}

/// The double pendulum over slices.
#[derive(Clone)]
struct DoublePendulumDyn;

#[lagrangian]
impl DoublePendulumDyn {
    fn dimension(&self) -> usize {
        2
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        let kinetic = v[0] * v[0] + 0.5 * v[1] * v[1] + v[0] * v[1] * (q[0] - q[1]).cos();
        kinetic + 2.0 * 9.81 * q[0].cos() + 9.81 * q[1].cos()
    }
}

/// `(q, p)` at `T_END` with `scheme` and `n` steps.
fn end(scheme: &Scheme, n: usize) -> [f64; 4] {
    let mut sim = problem().stepper(scheme, T_END / n as f64).unwrap();
    sim.run_until(T_END).unwrap();
    let s = sim.state();
    [s.q[0], s.q[1], s.p[0], s.p[1]]
}

/// `(q, p)` at `T_END` with `scheme` and `n` steps at a run-time size.
fn end_at_run_time(scheme: &Scheme, n: usize) -> [f64; 4] {
    let tight = NewtonOptions { rtol: 1e-15, ..NewtonOptions::default() };
    let problem = Problem::new(DoublePendulumDyn, 0.0, vec![1.0, -0.5], vec![0.0, 0.3]).newton(tight);
    let mut sim = problem.stepper(scheme, T_END / n as f64).unwrap();
    sim.run_until(T_END).unwrap();
    let s = sim.state();
    [s.q[0], s.q[1], s.p[0], s.p[1]]
}

/// The fitted order of `scheme` over `steps` (each end point by `end`), and
/// its errors.
fn order_of(
    scheme: &Scheme,
    steps: &[usize],
    reference: &[f64; 4],
    end: fn(&Scheme, usize) -> [f64; 4],
) -> (f64, Vec<f64>) {
    let h: Vec<f64> = steps.iter().map(|&n| T_END / n as f64).collect();
    let err: Vec<f64> = steps
        .iter()
        .map(|&n| end(scheme, n).iter().zip(reference).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max))
        .collect();
    (fitted_order(&h, &err), err)
}

#[test]
fn composed_bases_have_the_order_of_base_and_weights() {
    let reference = end(&Scheme::galerkin(6), 400);
    let alpha_beta = Scheme::alpha_beta(0.5).unwrap();
    for (scheme, steps) in [
        (Scheme::MIDPOINT.composed(Composition::YOSHIDA4), [40, 57, 80, 113, 160]),
        (Scheme::MIDPOINT.composed(Composition::YOSHIDA6), [20, 28, 40, 57, 80]),
        (alpha_beta.composed(Composition::YOSHIDA6), [20, 28, 40, 57, 80]),
        (Scheme::MIDPOINT.composed(Composition::KAHAN_LI8), [40, 48, 57, 68, 80]),
        (Scheme::galerkin(2).composed(Composition::YOSHIDA4), [40, 57, 80, 113, 160]),
        (Scheme::galerkin(2).composed(Composition::YOSHIDA6), [68, 80, 100, 120, 160]),
        // Order 6 base, order 4 weights: the base's order stays.
        (Scheme::galerkin(3).composed(Composition::YOSHIDA4), [57, 68, 80, 100, 120]),
    ] {
        let (order, err) = order_of(&scheme, &steps, &reference, end);
        let want = f64::from(scheme.order());
        println!("{}: fitted order {order:.3}, errors {:.2e} … {:.2e}", scheme.name(), err[0], err[4]);
        assert!((order - want).abs() <= 0.2, "{}: fitted order {order:.3}, want {want}; errors {err:?}", scheme.name());
        assert!(err[4] > 1e-12, "{}: smallest error {:e} near round-off", scheme.name(), err[4]);
    }
}

#[test]
fn a_composed_midpoint_at_a_run_time_size_has_order_six() {
    let reference = end(&Scheme::galerkin(6), 400);
    let scheme = Scheme::MIDPOINT.composed(Composition::YOSHIDA6);
    let (order, err) = order_of(&scheme, &[20, 28, 40, 57, 80], &reference, end_at_run_time);
    println!("{} at a run-time size: fitted order {order:.3}, errors {:.2e} … {:.2e}", scheme.name(), err[0], err[4]);
    assert!((order - 6.0).abs() <= 0.2, "fitted order {order:.3}, want 6; errors {err:?}");
    assert!(err[4] > 1e-12, "smallest error {:e} near round-off", err[4]);
}
