//! Verification: Galerkin discrete Lagrangians with forces and dissipation
//! (discrete Lagrange–d'Alembert through the basis). Order 2s against the
//! exact damped oscillator and driven RLC circuit, and the discrete Noether
//! balance `J_k − J_{k−1} = Σ_m F^m·ξ(Q_m)` at round-off.
use crate::common;

use common::forced::*;
use common::*;
use lagrangian::Symmetry;
use lagrangian::prelude::*;

/// Relative error of `(q, p/m)` at `t = 4` for Galerkin degree `S` with `S` Gauss points.
fn error<Sys: Lagrangian<1>, const S: usize>(system: Sys, h: f64, q0: f64, mass: f64, exact: [f64; 2]) -> f64 {
    let t_end = 4.0;
    let mut sim = GalerkinIntegrator::new(system, Galerkin::<S, S>::gauss(), h).start(0.0, [q0], [0.0]).unwrap();
    sim.run_until(t_end, |_| {}).unwrap();
    assert_eq!(sim.state().t, t_end);
    rel_err(&[sim.state().q[0], sim.state().p[0] / mass], &exact)
}

fn orders<const S: usize>(steps: &[f64]) -> (f64, f64, Vec<f64>) {
    let damped = DampedOscillator { m: 1.0, k: 4.0, c: 0.5 };
    let rlc = Rlc { l: 0.5, r: 1.5, c: 0.02, e0: 10.0, omega: 7.0 };
    let exact_damped = damped.exact(1.0, 4.0);
    let exact_rlc = rlc.exact(4.0);
    let e1: Vec<f64> = steps
        .iter()
        .map(|&h| error::<_, S>(DampedOscillator { m: 1.0, k: 4.0, c: 0.5 }, h, 1.0, 1.0, exact_damped))
        .collect();
    let e2: Vec<f64> = steps
        .iter()
        .map(|&h| error::<_, S>(Rlc { l: 0.5, r: 1.5, c: 0.02, e0: 10.0, omega: 7.0 }, h, 0.0, 0.5, exact_rlc))
        .collect();
    let mut all = e1.clone();
    all.extend(&e2);
    (fitted_order(steps, &e1), fitted_order(steps, &e2), all)
}

#[test]
fn forced_galerkin_converges_at_order_2s() {
    let cases: [(usize, Vec<f64>); 3] = [
        (1, vec![0.04, 0.02, 0.01, 0.005, 0.0025]),
        (2, vec![0.1, 0.05, 0.025, 0.0125, 0.00625]),
        (3, vec![0.2, 0.1, 0.05, 0.025, 0.0125]),
    ];
    for (s, steps) in cases {
        let (damped, rlc, errors) = match s {
            1 => orders::<1>(&steps),
            2 => orders::<2>(&steps),
            _ => orders::<3>(&steps),
        };
        println!("s = {s}: damped oscillator order {damped:.3}, driven RLC order {rlc:.3}; errors {errors:?}");
        let target = 2.0 * s as f64;
        assert!((damped - target).abs() < 0.15, "s = {s}: damped order {damped}");
        assert!((rlc - target).abs() < 0.15, "s = {s}: rlc order {rlc}");
    }
}

/// `(J_0, J_n, worst |J_k − J_{k−1} − impulse_k| relative)` over `n` steps of
/// Galerkin degree `S`.
fn noether_balance<const S: usize>(n: usize) -> (f64, f64, f64) {
    let rotation = Symmetry::<2>::rotation(0, 1).unwrap();
    let system = KeplerCartesian { mu: 1.0, c: 0.01, s: 0.02 };
    let mut sim =
        GalerkinIntegrator::new(system, Galerkin::<S, S>::gauss(), 0.05).start(0.0, [1.0, 0.0], [0.0, 1.1]).unwrap();
    let j_first = sim.momentum_map(&rotation);
    let mut worst = 0.0f64;
    for _ in 0..n {
        let before = sim.momentum_map(&rotation);
        sim.step().unwrap();
        let after = sim.momentum_map(&rotation);
        let impulse = sim.forcing_impulse(&rotation).unwrap();
        let size = before.abs().max(after.abs()).max(impulse.abs());
        worst = worst.max((after - before - impulse).abs() / size);
    }
    (j_first, sim.momentum_map(&rotation), worst)
}

/// Kepler with drag and a tangential thrust: rotation-invariant `L`, forces
/// that change the angular momentum. Every step balances it to round-off.
#[test]
fn forced_galerkin_balances_the_noether_impulse() {
    for (s, (j_first, j_last, worst)) in [(2, noether_balance::<2>(4000)), (4, noether_balance::<4>(4000))] {
        println!("s = {s}: J {j_first:.4} → {j_last:.4} over 4000 steps; worst |ΔJ − impulse| relative {worst:.1e}");
        assert!((j_last - j_first).abs() > 0.1, "the forces should change J");
        assert!(worst < 1e-13, "s = {s}: {worst:e}");
    }
}
