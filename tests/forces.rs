//! Verification: forces and dissipation (MATH.md §6, paper 002). Order of the
//! forced integrators against analytic solutions, the discrete energy
//! balance, paper 002's electromechanical sensor and its first integral, and
//! what bad forces do.
mod common;

use common::forced::*;
use common::*;
use lagrangian::forcing::{self, EnergyBalance};
use lagrangian::prelude::*;
use lagrangian::{Segment, StepBounds, Symmetry};

/// Fixed-step run to `t_end`, returning the integrator.
fn run_to<S: Lagrangian<N>, M: DiscreteLagrangian, const N: usize>(
    system: S,
    method: M,
    h: f64,
    q0: [f64; N],
    v0: [f64; N],
    t_end: f64,
) -> Integrator<S, M, N> {
    let mut sim = Integrator::new(system, method, h).start(0.0, q0, v0).unwrap();
    let n = (t_end / h).round() as usize;
    sim.run(n, |_| {}).unwrap();
    assert!((sim.state().t - t_end).abs() < 1e-9);
    sim
}

const STEPS: [f64; 5] = [0.08, 0.04, 0.02, 0.01, 0.005];

fn orders<M: DiscreteLagrangian>(method: M, err: fn(M, f64) -> f64) -> f64 {
    let errors: Vec<f64> = STEPS.iter().map(|&h| err(method, h)).collect();
    fitted_order(&STEPS, &errors)
}

fn damped() -> DampedOscillator {
    DampedOscillator { m: 1.0, k: 4.0, c: 0.5 }
}

fn rlc() -> Rlc {
    Rlc { l: 0.5, r: 1.5, c: 0.02, e0: 10.0, omega: 7.0 }
}

/// Relative error in position and momentum (`p = m q̇`) at `t = 4` against
/// the exact damped oscillation.
fn damped_error<M: DiscreteLagrangian>(method: M, h: f64) -> f64 {
    let t_end = 4.0;
    let sim = run_to(damped(), method, h, [1.0], [0.0], t_end);
    let s = sim.state();
    rel_err(&[s.q[0], s.p[0] / damped().m], &damped().exact(1.0, t_end))
}

/// Relative error in charge and current at `t = 4` against the exact
/// driven RLC response; the current from the discrete momentum, `i = p/ℓ`.
fn rlc_error<M: DiscreteLagrangian>(method: M, h: f64) -> f64 {
    let t_end = 4.0;
    let sim = run_to(rlc(), method, h, [0.0], [0.0], t_end);
    let s = sim.state();
    rel_err(&[s.q[0], s.p[0] / rlc().l], &rlc().exact(t_end))
}

#[test]
fn damped_oscillator_converges_with_order_2() {
    let midpoint = orders(Midpoint, damped_error);
    let trapezoid = orders(Trapezoid, damped_error);
    // α = 1 puts the whole impulse on q_k: first order, which the fit must see.
    let euler = orders(AlphaBeta::EULER_A, damped_error);
    eprintln!("damped oscillator: orders midpoint {midpoint:.3}, trapezoid {trapezoid:.3}, α=1 {euler:.3}");
    assert!((midpoint - 2.0).abs() < 0.1, "midpoint order {midpoint}");
    assert!((trapezoid - 2.0).abs() < 0.1, "trapezoid order {trapezoid}");
    assert!((euler - 1.0).abs() < 0.1, "α = 1 order {euler}");
}

#[test]
fn driven_rlc_circuit_converges_with_order_2() {
    let midpoint = orders(Midpoint, rlc_error);
    let trapezoid = orders(Trapezoid, rlc_error);
    eprintln!("rlc: orders midpoint {midpoint:.3}, trapezoid {trapezoid:.3}");
    assert!((midpoint - 2.0).abs() < 0.1, "midpoint order {midpoint}");
    assert!((trapezoid - 2.0).abs() < 0.1, "trapezoid order {trapezoid}");
}

/// Runs `n` steps and returns every energy balance (from node 1 on).
fn balances<S: Lagrangian<N>, M: DiscreteLagrangian, const N: usize>(
    system: S,
    method: M,
    h: f64,
    q0: [f64; N],
    v0: [f64; N],
    n: usize,
) -> Vec<EnergyBalance> {
    let mut sim = Integrator::new(system, method, h).start(0.0, q0, v0).unwrap();
    let mut out = Vec::with_capacity(n);
    assert!(sim.energy_balance().is_none());
    sim.step().unwrap();
    assert!(sim.energy_balance().is_none(), "node 0 has no step behind it");
    sim.run(n, |s| out.push(s.energy_balance().unwrap())).unwrap();
    out
}

/// Largest `|E_{k+1} − E_k − W_k| / max(|E_k|, |E_{k+1}|)` over a run.
fn worst_relative(balances: &[EnergyBalance]) -> f64 {
    balances.iter().map(|b| b.residual().abs() / b.energy_before.abs().max(b.energy_after.abs())).fold(0.0, f64::max)
}

#[test]
fn energy_balance_closes_to_round_off_for_quadratic_lagrangians() {
    // The midpoint rule with fixed steps on a Lagrangian quadratic in (q, v):
    // E_{k+1} − E_k = W_k exactly (proof in `forcing`), whatever the forces
    // (linear damping, a time-dependent source, a battery). Asserted at every
    // node: |E_{k+1} − E_k − W_k| ≤ 1e-13 max(|E_k|, |E_{k+1}|).
    let n = 20_000;
    let damped = balances(damped(), Midpoint, 0.01, [1.0], [0.0], 2_000);
    // Over 2000 steps (t = 20) the energy decays by e^{-10}: the bound is per node, relative.
    let rlc = balances(rlc(), Midpoint, 0.01, [0.0], [0.0], n);
    let sensor = balances(Sensor { ..SENSOR }, Midpoint, 0.001, [0.0, 0.0], [0.0, 0.0], n);
    for (name, b) in [("damped oscillator", &damped), ("rlc", &rlc), ("sensor, constant L1", &sensor)] {
        let worst = worst_relative(b);
        let work: f64 = b.iter().map(|b| b.work.abs()).sum();
        eprintln!("{name}: worst relative balance residual {worst:.2e} (total |work| {work:.3e})");
        assert!(worst <= 1e-13, "{name}: residual {worst:e}");
        assert!(work > 1e-3, "{name}: the forces must do work for the test to mean anything");
    }
}

#[test]
fn energy_balance_residual_is_third_order_otherwise() {
    // Non-quadratic L (the sensor with L1(x) = L0/(1 + x/a)) and the
    // trapezoid rule: the residual is the local energy error of the method,
    // O(h³) per node. Max over the same time interval at three step sizes.
    let steps = [0.004, 0.002, 0.001];
    let t_end = 0.5;
    let fit = |residuals: Vec<f64>| fitted_order(&steps, &residuals);
    let sensor: Vec<f64> = steps
        .iter()
        .map(|&h| {
            let n = (t_end / h) as usize;
            let b = balances(Sensor { ..SENSOR_VARIABLE }, Midpoint, h, [0.0, 0.0], [0.0, 0.0], n);
            b.iter().map(|b| b.residual().abs()).fold(0.0, f64::max)
        })
        .collect();
    let trapezoid: Vec<f64> = steps
        .iter()
        .map(|&h| {
            let n = (t_end / h) as usize;
            let b = balances(damped(), Trapezoid, h, [1.0], [0.0], n);
            b.iter().map(|b| b.residual().abs()).fold(0.0, f64::max)
        })
        .collect();
    eprintln!("variable-L1 sensor, midpoint: max residuals {sensor:?}, order {:.3}", fit(sensor.clone()));
    eprintln!("damped oscillator, trapezoid: max residuals {trapezoid:?}, order {:.3}", fit(trapezoid.clone()));
    assert!((fit(sensor) - 3.0).abs() < 0.2);
    assert!((fit(trapezoid) - 3.0).abs() < 0.2);
}
