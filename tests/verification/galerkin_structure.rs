//! Verification: long-time structure of the Galerkin integrators (s = 2, 4):
//! symplecticity of the step map to round-off, bounded energy error without
//! drift over 1e5 steps, and the Kepler angular momentum.
use crate::common;
use crate::common::galerkin_reference;

use common::*;
use galerkin_reference::kepler_start;
use lagrangian::{Galerkin, GalerkinIntegrator, Lagrangian};

/// `max |MᵀJM − J|` over the first `n` steps, `M` the tangent map of the step
/// (implicit function theorem on the block system, docs/theory.md §8).
fn worst_defect<Sys: Lagrangian<N>, const N: usize, const S: usize>(
    system: Sys,
    h: f64,
    q0: [f64; N],
    v0: [f64; N],
    n: usize,
) -> f64 {
    let mut sim = GalerkinIntegrator::new(system, Galerkin::<S, S>::gauss(), h).start(0.0, q0, v0).unwrap();
    assert!(sim.last_tangent_map().is_none());
    let mut worst = 0.0f64;
    sim.run(n, |s| worst = worst.max(s.last_tangent_map().unwrap().symplecticity_defect())).unwrap();
    worst
}

#[test]
fn step_map_is_symplectic_to_round_off() {
    let (kq, kv) = kepler_start(0.5);
    for h in [0.02, 0.05, 0.1] {
        let cases = [
            ("pendulum s=2", worst_defect::<_, 1, 2>(Pendulum { ..PENDULUM }, h, [2.0], [0.0], 50)),
            ("pendulum s=4", worst_defect::<_, 1, 4>(Pendulum { ..PENDULUM }, h, [2.0], [0.0], 50)),
            (
                "double pendulum s=2",
                worst_defect::<_, 2, 2>(DoublePendulum { ..DOUBLE_PENDULUM }, h, [1.0, -0.5], [0.0, 0.5], 50),
            ),
            (
                "double pendulum s=4",
                worst_defect::<_, 2, 4>(DoublePendulum { ..DOUBLE_PENDULUM }, h, [1.0, -0.5], [0.0, 0.5], 50),
            ),
            ("kepler s=2", worst_defect::<_, 2, 2>(KeplerPolar { mu: 1.0 }, 0.5 * h, kq, kv, 50)),
            ("kepler s=4", worst_defect::<_, 2, 4>(KeplerPolar { mu: 1.0 }, 0.5 * h, kq, kv, 50)),
            (
                "charged particle s=4",
                worst_defect::<_, 2, 4>(ChargedParticle { ..CHARGED }, h, [0.5, 0.0], [0.0, 0.8], 50),
            ),
        ];
        for (name, d) in cases {
            println!("{name}, h = {h}: defect {d:.1e}");
            assert!(d <= 1e-12, "{name}, h = {h}: symplecticity defect {d:e}");
        }
    }
}

#[test]
fn a_wrong_tangent_map_would_show() {
    // The defect is not trivially small: perturbing one entry of M shows it.
    let mut sim = GalerkinIntegrator::new(Pendulum { ..PENDULUM }, Galerkin::<4, 4>::gauss(), 0.3)
        .start(0.0, [2.0], [0.0])
        .unwrap();
    sim.step().unwrap();
    let mut m = sim.last_tangent_map().unwrap();
    m.dq_dp[(0, 0)] *= 1.0 + 1e-6;
    assert!(m.symplecticity_defect() > 1e-8);
}

/// `(t_k, E_L(t_k) − E_0)` at every step of `n`.
fn energy_errors<Sys: Lagrangian<N>, const N: usize, const S: usize>(
    system: Sys,
    h: f64,
    q0: [f64; N],
    v0: [f64; N],
    n: usize,
) -> (Vec<f64>, Vec<f64>) {
    let mut sim = GalerkinIntegrator::new(system, Galerkin::<S, S>::gauss(), h).start(0.0, q0, v0).unwrap();
    let e0 = sim.energy().unwrap();
    let (mut t, mut de) = (Vec::with_capacity(n), Vec::with_capacity(n));
    sim.run(n, |s| {
        t.push(s.state().t);
        de.push(s.energy().unwrap() - e0);
    })
    .unwrap();
    (t, de)
}

/// Bounded by `bound`, least-squares trend over the run below 1% of the
/// amplitude, and the last tenth no worse than the first (with 10% margin):
/// a method whose energy drifts (RK4, explicit Euler) fails all three.
fn assert_bounded_without_drift(name: &str, t: &[f64], de: &[f64], bound: f64) {
    let amplitude = de.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let (_, slope) = linear_fit(t, de);
    let drift = slope * (t[t.len() - 1] - t[0]);
    let tenth = de.len() / 10;
    let head = de[..tenth].iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let tail = de[de.len() - tenth..].iter().fold(0.0f64, |m, v| m.max(v.abs()));
    println!("{name}: amplitude {amplitude:.2e}, drift {drift:.1e}, first tenth {head:.2e}, last tenth {tail:.2e}");
    assert!(amplitude <= bound, "{name}: energy error {amplitude:e} above {bound:e}");
    assert!(drift.abs() <= 0.01 * amplitude, "{name}: drift {drift:e} over the run, amplitude {amplitude:e}");
    assert!(tail <= 1.1 * head, "{name}: error grows from {head:e} to {tail:e}");
}

#[test]
fn energy_error_is_bounded_without_drift_over_1e5_steps() {
    // Pendulum from 2 rad (E_0 ≈ 4.25), about 2800 periods at h = 0.05; the
    // step sizes keep the O(h^{2s}) oscillation of the energy far above round-off.
    let (t, de) = energy_errors::<_, 1, 2>(Pendulum { ..PENDULUM }, 0.05, [2.0], [0.0], 100_000);
    assert_bounded_without_drift("pendulum s = 2, h = 0.05", &t, &de, 5e-5);
    let (t, de) = energy_errors::<_, 1, 4>(Pendulum { ..PENDULUM }, 0.2, [2.0], [0.0], 100_000);
    assert_bounded_without_drift("pendulum s = 4, h = 0.2", &t, &de, 5e-5);
    // Kepler e = 0.5 (E = −½), about 8000 orbits at h = 0.5 for s = 4.
    let (q0, v0) = kepler_start(0.5);
    let (t, de) = energy_errors::<_, 2, 2>(KeplerPolar { mu: 1.0 }, 0.05, q0, v0, 100_000);
    assert_bounded_without_drift("kepler s = 2, h = 0.05", &t, &de, 1e-6);
    let (t, de) = energy_errors::<_, 2, 4>(KeplerPolar { mu: 1.0 }, 0.2, q0, v0, 100_000);
    assert_bounded_without_drift("kepler s = 4, h = 0.2", &t, &de, 2e-7);
}

#[test]
fn kepler_angular_momentum_is_conserved_to_round_off_over_1e5_steps() {
    let (q0, v0) = kepler_start(0.5);
    let mut sim =
        GalerkinIntegrator::new(KeplerPolar { mu: 1.0 }, Galerkin::<4, 4>::gauss(), 0.2).start(0.0, q0, v0).unwrap();
    let l0 = sim.state().p[1];
    let mut worst = 0.0f64;
    sim.run(100_000, |s| worst = worst.max((s.state().p[1] - l0).abs() / l0)).unwrap();
    println!("kepler s = 4: angular momentum error {worst:.1e}");
    assert!(worst <= 1e-13, "angular momentum error {worst:e}");
}
