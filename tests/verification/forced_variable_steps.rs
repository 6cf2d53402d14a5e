//! Verification: variable steps for forced systems, fixed by the discrete
//! energy balance `E_{k+1} − E_k = W_k` (time as a variable in the discrete
//! Lagrange–d'Alembert principle, docs/theory.md §6).
//!
//! With time varied too, the principle adds to each step the work of its
//! discrete forces on the time variations, `−F_k^−·v̂_k δt_k − F_k^+·v̂_k δt_{k+1}`,
//! and the equation of `δt_k` says that the discrete energy changes across
//! node `k` by `W_k = F_{k−1}^+·v̂_{k−1} + F_k^−·v̂_k`. The integrator solves it
//! with the DEL for `(q_{k+1}, h_k)`, so `EnergyBalance::variational_residual`
//! is round-off at every node; these tests check that, and that the steps
//! still converge at the method's order.
use crate::common;

use common::fitted_order;
use common::forced::{DampedOscillator, SENSOR_VARIABLE};
use lagrangian::prelude::*;

fn damped() -> DampedOscillator {
    DampedOscillator { m: 1.0, k: 4.0, c: 0.5 }
}

/// Largest `|E_{k+1} − E_k − W_k| / (|E_k| + |E_{k+1}| + |W_k|)` over the
/// steps up to `t_end` (each one a balance step: `run_until`'s landing step
/// is a fixed step and would not be), and the total work.
fn worst_balance<S: Lagrangian<N>, M: DiscreteLagrangian, const N: usize>(
    sim: &mut Integrator<S, M, N>,
    t_end: f64,
) -> (f64, f64) {
    let mut worst = 0.0f64;
    let mut work = 0.0;
    let (mut h_min, mut h_max) = (f64::INFINITY, 0.0f64);
    while sim.state().t < t_end {
        sim.step().unwrap();
        let h = sim.last_step_size().unwrap();
        h_min = h_min.min(h);
        h_max = h_max.max(h);
        if let Some(b) = sim.energy_balance() {
            let scale = b.energy_before.abs() + b.energy_after.abs() + b.variational_work.abs();
            worst = worst.max(b.variational_residual().abs() / scale);
            work += b.variational_work;
        }
    }
    println!("  {} steps in [{h_min:.2e}, {h_max:.2e}]", sim.stats().steps);
    (worst, work)
}

#[test]
fn damped_oscillator_balance_at_round_off_every_step() {
    let mut sim = Integrator::new(damped(), Midpoint, 0.01)
        .energy_preserving(StepBounds::around(0.01))
        .start(0.0, [1.0], [0.0])
        .unwrap();
    let (worst, work) = worst_balance(&mut sim, 6.0);
    let iterations = sim.stats().newton_iterations as f64 / sim.stats().steps as f64;
    println!(
        "damped oscillator, midpoint: balance steps to t = {:.3}, worst relative balance {worst:.1e}, work {work:.4}, \
         {iterations:.2} Newton iterations per step",
        sim.state().t
    );
    assert!(worst < 1e-13, "balance {worst:e}");
    // The dissipation removed energy: W < 0, and most of E_0 = 2 is gone.
    assert!(work < -1.5, "work {work}");
}

/// The trapezoid rule's energy equation loses its root on an oscillator
/// within a quarter swing (docs/energy-steps.md), forced or not: a typed
/// `NoEnergyStep` with the state kept, not a wrong step.
#[test]
fn trapezoid_balance_steps_stop_typed() {
    let mut sim = Integrator::new(damped(), Trapezoid, 0.01)
        .energy_preserving(StepBounds::around(0.01))
        .start(0.0, [1.0], [0.0])
        .unwrap();
    let outcome = sim.run_until(6.0, |_| {});
    let before = *sim.state();
    match outcome {
        Err(Error::NoEnergyStep { state, .. }) => {
            assert_eq!(state, before);
            println!("trapezoid balance steps: NoEnergyStep at t = {:.4}", state.t);
        }
        other => panic!("expected NoEnergyStep, got {other:?}"),
    }
}

#[test]
fn sensor_balance_at_round_off_every_step() {
    // The electromechanical sensor with a position-dependent inductance:
    // a forced, dissipative, nonlinear system (EMF, resistance).
    let mut sim = Integrator::new(SENSOR_VARIABLE, Midpoint, 1e-3)
        .energy_preserving(StepBounds::around(1e-3))
        .start(0.0, [0.0, 0.0], [0.0, 0.0])
        .unwrap();
    let (worst, work) = worst_balance(&mut sim, 0.5);
    println!("sensor: balance steps to t = {:.4}, worst relative balance {worst:.1e}, work {work:.4}", sim.state().t);
    assert!(worst < 1e-12, "sensor balance {worst:e}");
}

/// The balance steps converge at order 2 in the first step size (damped
/// oscillator, q(4) against the exact solution).
#[test]
fn balance_steps_converge_at_order_2() {
    let hs = [0.02, 0.01, 0.005, 0.0025];
    let err: Vec<f64> = hs
        .iter()
        .map(|&h0| {
            let mut sim = Integrator::new(damped(), Midpoint, h0)
                .energy_preserving(StepBounds::around(h0))
                .start(0.0, [1.0], [0.0])
                .unwrap();
            sim.run_until(4.0, |_| {}).unwrap();
            (sim.state().q[0] - damped().exact(1.0, 4.0)[0]).abs()
        })
        .collect();
    let order = fitted_order(&hs, &err);
    println!("balance steps, midpoint, damped oscillator: fitted order {order:.3}, errors {err:?}");
    assert!((order - 2.0).abs() <= 0.15, "order {order}, errors {err:?}");
}

/// Galerkin rules do not have balance steps yet: refused typed.
#[test]
fn galerkin_balance_steps_are_refused() {
    let err = Integrator::new(damped(), Galerkin::<2, 2>::gauss(), 0.05)
        .energy_preserving(StepBounds::around(0.05))
        .start(0.0, [1.0], [0.0]);
    assert!(matches!(err, Err(Error::Unsupported { .. })), "{err:?}");
}

/// Bad input on the energy-balance path: typed errors at `start`, and a
/// failed step (Newton limited to one iteration) leaves the state as it was.
#[test]
fn balance_steps_bad_input_is_typed() {
    let start = |h: f64, bounds: StepBounds, q0: f64| {
        Integrator::new(damped(), Midpoint, h).energy_preserving(bounds).start(0.0, [q0], [0.0]).map(|_| ())
    };
    assert!(matches!(start(0.0, StepBounds::around(0.01), 1.0), Err(Error::InvalidStepSize { .. })));
    assert!(matches!(start(-0.01, StepBounds::around(0.01), 1.0), Err(Error::InvalidStepSize { .. })));
    assert!(matches!(start(0.01, StepBounds::around(0.01), f64::NAN), Err(Error::InvalidInitialData { .. })));
    let bad = StepBounds { max_ratio: 1.0, ..StepBounds::around(0.01) };
    assert!(matches!(start(0.01, bad, 1.0), Err(Error::InvalidStepBounds { .. })));
    let mut sim = Integrator::new(damped(), Midpoint, 0.01)
        .energy_preserving(StepBounds::around(0.01))
        .newton(NewtonOptions { max_iterations: 1, ..NewtonOptions::default() })
        .start(0.0, [1.0], [0.0])
        .unwrap();
    let before = *sim.state();
    assert!(sim.step().is_err(), "one Newton iteration cannot converge");
    assert_eq!(*sim.state(), before);
    assert_eq!(sim.stats().failed_steps, 1);
}
