//! Verification for time-dependent Lagrangians (docs/theory.md §3; de León & Martín de Diego):
//! the discrete energy balance under variable steps, the order of the
//! discrete energy under fixed steps, and the order of variable steps.

use crate::common;

use common::{SlowOscillator, fitted_order};
use lagrangian::derivatives::action_gradient;
use lagrangian::prelude::*;
use lagrangian::{DiscreteMechanics, StepBounds};

const SYSTEM: SlowOscillator = SlowOscillator { eps: 0.01 };

#[test]
fn the_macro_sees_the_time_argument() {
    const { assert!(!<SlowOscillator as Lagrangian<1>>::AUTONOMOUS) };
}

#[test]
fn variable_steps_satisfy_the_discrete_energy_balance_at_every_step() {
    // E_{k+1} − E_k + ∂A/∂t_k + ∂A/∂t_{k+1} = 0 (de León & Martín de Diego §3.2), with
    // E_k = −∂A(x_{k−1}, x_k)/∂t_k read from the integrator and the partials
    // of the step just taken recomputed from its segment.
    let h0 = 0.05;
    let mut sim = Integrator::new(SYSTEM, Midpoint, h0)
        .energy_preserving(StepBounds::around(h0))
        .start(0.0, [1.0], [0.0])
        .unwrap();
    sim.step().unwrap();
    let e1 = sim.discrete_energy();
    let mut worst = 0.0f64;
    for _ in 0..20_000 {
        let e_k = sim.discrete_energy();
        sim.step().unwrap();
        let grad = action_gradient(sim.system(), sim.method(), sim.last_segment().unwrap());
        let balance = sim.discrete_energy() - e_k + grad.d_t0 + grad.d_t1;
        worst = worst.max(balance.abs() / e_k.abs().max(grad.d_t0.abs()));
    }
    println!("largest relative imbalance {worst:e}");
    assert!(worst <= 1e-14, "largest relative imbalance {worst:e}");
    // Not a tautology of a constant energy: over t ≈ 1000 (εt ≈ 10) ω and
    // with it E vary by tens of percent.
    let e_end = sim.discrete_energy();
    assert!(sim.state().t > 500.0 && ((e_end - e1) / e1).abs() > 0.1, "t = {}, E: {e1} → {e_end}", sim.state().t);
}

#[test]
fn fixed_steps_track_the_exact_energy_at_order_two() {
    // |E_k − E(t_k)| at T = 100 (εT = 1) against RK4 with 2e5 steps
    // (error ~1e-13), for four step sizes.
    let t_end = 100.0;
    let (q_ref, v_ref) = SYSTEM.reference(1.0, 0.0, t_end, 200_000);
    let w = SYSTEM.omega(t_end);
    let e_ref = 0.5 * v_ref * v_ref + 0.5 * w * w * q_ref * q_ref;
    let steps = [0.1, 0.05, 0.025, 0.0125];
    let errors: Vec<f64> = steps
        .iter()
        .map(|&h| {
            let mut sim = Integrator::new(SYSTEM, Midpoint, h).start(0.0, [1.0], [0.0]).unwrap();
            sim.run((t_end / h).round() as usize, |_| {}).unwrap();
            assert!((sim.state().t - t_end).abs() < 1e-9);
            (sim.discrete_energy() - e_ref).abs()
        })
        .collect();
    let order = fitted_order(&steps, &errors);
    println!("energy errors {errors:?}, order {order}");
    assert!((order - 2.0).abs() <= 0.1, "order {order}, errors {errors:?}");
    // The energy really changed: E(0) = ½, E(T) differs by a finite amount.
    assert!((e_ref - 0.5).abs() > 0.05, "E(T) = {e_ref}");
}

#[test]
fn variable_steps_converge_at_order_two_at_a_fixed_time() {
    let t_end = 50.0;
    let (q_ref, _) = SYSTEM.reference(1.0, 0.0, t_end, 100_000);
    let steps = [0.04, 0.02, 0.01, 0.005];
    let errors: Vec<f64> = steps
        .iter()
        .map(|&h0| {
            let mut sim = Integrator::new(SYSTEM, Midpoint, h0)
                .energy_preserving(StepBounds::around(h0))
                .start(0.0, [1.0], [0.0])
                .unwrap();
            sim.run_until(t_end, |_| {}).unwrap();
            assert_eq!(sim.state().t, t_end);
            (sim.state().q[0] - q_ref).abs()
        })
        .collect();
    let order = fitted_order(&steps, &errors);
    println!("position errors {errors:?}, order {order}");
    assert!((order - 2.0).abs() <= 0.1, "order {order}, errors {errors:?}");
}

#[test]
fn the_continuous_energy_of_the_initial_data_is_e_l() {
    let e = SYSTEM.energy(0.0, [1.0], [0.5]);
    assert!((e - (0.125 + 0.5)).abs() < 1e-15, "{e}");
}
