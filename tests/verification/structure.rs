//! Verification: long-time structure. Bounded energy error without drift,
//! exact conservation of a cyclic momentum, symplecticity of the step map.
use crate::common;

use common::*;
use lagrangian::{DiscreteLagrangian, Integrator, Lagrangian, Midpoint, Trapezoid};

/// Runs `n` steps and returns `(t_k, E_L(t_k) − E_0)` at every step.
fn energy_errors<S: Lagrangian<N>, M: DiscreteLagrangian, const N: usize>(
    system: S,
    method: M,
    h: f64,
    q0: [f64; N],
    v0: [f64; N],
    n: usize,
) -> (Vec<f64>, Vec<f64>) {
    let mut sim = Integrator::new(system, method, h).start(0.0, q0, v0).unwrap();
    let e0 = sim.energy().unwrap();
    let (mut t, mut de) = (Vec::with_capacity(n), Vec::with_capacity(n));
    sim.run(n, |s| {
        t.push(s.state().t);
        de.push(s.energy().unwrap() - e0);
    })
    .unwrap();
    (t, de)
}

/// Energy error stays bounded over 1e5 steps and its least-squares trend
/// over the whole run is below 1% of its amplitude (a drifting method, such
/// as explicit Euler or RK4, fails this).
fn assert_bounded_without_drift(name: &str, t: &[f64], de: &[f64], bound: f64) {
    let amplitude = de.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let (_, slope) = linear_fit(t, de);
    let drift = slope * (t[t.len() - 1] - t[0]);
    assert!(amplitude <= bound, "{name}: energy error {amplitude:e} above {bound:e}");
    assert!(drift.abs() <= 0.01 * amplitude, "{name}: drift {drift:e} over the run, amplitude {amplitude:e}");
    // The error in the last tenth is no larger than over the first tenth, with margin for sampling.
    let tenth = de.len() / 10;
    let head = de[..tenth].iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let tail = de[de.len() - tenth..].iter().fold(0.0f64, |m, v| m.max(v.abs()));
    assert!(tail <= 1.1 * head, "{name}: error grows from {head:e} to {tail:e}");
}

#[test]
fn pendulum_energy_error_is_bounded_without_drift_over_1e5_steps() {
    // E_0 = −m g l cos 2 ≈ 4.25; the error oscillates with an O(h²) amplitude.
    let (t, de) = energy_errors(Pendulum { ..PENDULUM }, Midpoint, 0.05, [2.0], [0.0], 100_000);
    assert_bounded_without_drift("midpoint", &t, &de, 5e-2);
    let (t, de) = energy_errors(Pendulum { ..PENDULUM }, Trapezoid, 0.05, [2.0], [0.0], 100_000);
    assert_bounded_without_drift("trapezoid", &t, &de, 1e-1);
}

#[test]
fn double_pendulum_energy_error_is_bounded() {
    let (t, de) = energy_errors(DoublePendulum { ..DOUBLE_PENDULUM }, Midpoint, 0.01, [0.6, -0.4], [0.0, 0.5], 100_000);
    assert_bounded_without_drift("double pendulum", &t, &de, 1e-2);
}

#[test]
fn charged_particle_energy_error_is_bounded() {
    let (t, de) = energy_errors(ChargedParticle { ..CHARGED }, Midpoint, 0.02, [0.5, 0.0], [0.0, 0.8], 100_000);
    assert_bounded_without_drift("charged particle", &t, &de, 1e-3);
}

/// Largest relative change of the angular momentum `p_φ` over 1e5 steps.
fn kepler_momentum_error<M: DiscreteLagrangian>(method: M) -> f64 {
    // e = 0.5, a = 1, μ = 1, starting at perihelion; about 160 orbits.
    let (mu, a, e): (f64, f64, f64) = (1.0, 1.0, 0.5);
    let r0 = a * (1.0 - e);
    let phi_dot = (mu * a * (1.0 - e * e)).sqrt() / (r0 * r0);
    let mut sim = Integrator::new(KeplerPolar { mu }, method, 0.01).start(0.0, [r0, 0.0], [0.0, phi_dot]).unwrap();
    let p0 = sim.state().p[1];
    let mut worst = 0.0f64;
    sim.run(100_000, |s| worst = worst.max((s.state().p[1] - p0).abs())).unwrap();
    worst / p0.abs()
}

#[test]
fn kepler_angular_momentum_is_conserved_to_round_off_over_1e5_steps() {
    assert_eq!(<KeplerPolar as Lagrangian<2>>::CYCLIC, [false, true]);
    let err = kepler_momentum_error(Midpoint);
    assert!(err <= 1e-13, "midpoint: angular momentum error {err:e}");
    let err = kepler_momentum_error(Trapezoid);
    assert!(err <= 1e-13, "trapezoid: angular momentum error {err:e}");
}

/// The defect `‖MᵀJM − J‖` of the step's tangent map along a trajectory.
fn worst_defect<S: Lagrangian<N>, M: DiscreteLagrangian, const N: usize>(
    system: S,
    method: M,
    h: f64,
    q0: [f64; N],
    v0: [f64; N],
) -> f64 {
    let mut sim = Integrator::new(system, method, h).start(0.0, q0, v0).unwrap();
    let mut worst = 0.0f64;
    sim.run(2_000, |s| {
        if s.state().step % 50 == 0 {
            let m = s.last_tangent_map().expect("regular step");
            worst = worst.max(m.symplecticity_defect());
        }
    })
    .unwrap();
    worst
}

#[test]
fn step_map_is_symplectic() {
    for h in [0.05, 0.01] {
        let d = worst_defect(Pendulum { ..PENDULUM }, Midpoint, h, [2.5], [0.3]);
        assert!(d <= 1e-12, "pendulum midpoint h={h}: defect {d:e}");
        let d = worst_defect(Pendulum { ..PENDULUM }, Trapezoid, h, [2.5], [0.3]);
        assert!(d <= 1e-12, "pendulum trapezoid h={h}: defect {d:e}");
        let d = worst_defect(DoublePendulum { ..DOUBLE_PENDULUM }, Midpoint, h, [1.0, -0.5], [0.2, 1.0]);
        assert!(d <= 1e-12, "double pendulum midpoint h={h}: defect {d:e}");
        let d = worst_defect(ChargedParticle { ..CHARGED }, Midpoint, h, [0.5, 0.0], [0.0, 0.8]);
        assert!(d <= 1e-12, "charged particle midpoint h={h}: defect {d:e}");
    }
}

#[test]
fn a_non_symplectic_map_has_a_visible_defect() {
    // Guards the defect measure itself: a map that scales momenta is caught.
    let m = lagrangian::TangentMap::<1> {
        dq_dq: nalgebra::SMatrix::identity(),
        dq_dp: nalgebra::SMatrix::zeros(),
        dp_dq: nalgebra::SMatrix::zeros(),
        dp_dp: nalgebra::SMatrix::identity() * 1.001,
    };
    assert!(m.symplecticity_defect() > 1e-4);
}
