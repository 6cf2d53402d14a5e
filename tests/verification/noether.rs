//! Verification: the discrete Noether theorem (docs/theory.md §7). Momentum maps of
//! translations, rotations and user generators are conserved to round-off
//! without forces, and balanced by the forcing impulse at every step with
//! them.
use crate::common;

use common::forced::*;
use lagrangian::noether::{self, Generator};
use lagrangian::prelude::*;
use lagrangian::{Symmetry, forcing};

/// Runs `n` steps and returns the largest `|J_k − J_0| / |J_0|`.
fn momentum_drift<S: Lagrangian<N>, M: DiscreteLagrangian, const N: usize>(
    system: S,
    method: M,
    h: f64,
    (q0, v0): ([f64; N], [f64; N]),
    symmetry: &impl Generator<N>,
    n: usize,
) -> f64 {
    let mut sim = Integrator::new(system, method, h).start(0.0, q0, v0).unwrap();
    let j0 = sim.momentum_map(symmetry);
    let mut worst = 0.0f64;
    sim.run(n, |s| worst = worst.max((s.momentum_map(symmetry) - j0).abs() / j0.abs())).unwrap();
    worst
}

/// Kepler, e = 0.5, from the pericentre.
fn kepler_initial() -> ([f64; 2], [f64; 2]) {
    let (a, e) = (1.0, 0.5);
    let r0 = a * (1.0 - e);
    ([r0, 0.0], [0.0, ((1.0 + e) / r0).sqrt()])
}

// Conservation without forces. The discrete Noether identity holds at every
// step to round-off; over 1e5 steps the momentum map then drifts by the sum
// of those round-off errors, which has a small one-signed part that depends
// on the bits of h (the step enters the action through h and fl(1/h)):
// measured with h = 0.01, 1.1e-13 (Cartesian Kepler, midpoint), 1.3e-13
// (trapezoid), 2.2e-13 (spherical pendulum), 1.4e-13 (Morse pair), nearly
// linear in k; with the exactly representable h = 2⁻⁷, 5.6e-14, 4.7e-14,
// 3.0e-14 and 8.9e-14. Asserted: ≤ 1e-13 with h = 2⁻⁷ and ≤ 3e-13 with
// h = 0.01. A tighter Newton tolerance does not change these (the last
// correction is already computed from a residual that is pure round-off).
const H_EXACT: f64 = 1.0 / 128.0;
const N_LONG: usize = 100_000;

fn assert_conserved(name: &str, exact_h: f64, decimal_h: f64) {
    eprintln!("{name}, 1e5 steps: max |J_k − J_0| / |J_0| = {exact_h:.2e} (h = 2⁻⁷), {decimal_h:.2e} (h = 0.01)");
    assert!(exact_h <= 1e-13, "{name}, h = 2⁻⁷: {exact_h:e}");
    assert!(decimal_h <= 3e-13, "{name}, h = 0.01: {decimal_h:e}");
}

#[test]
fn rotation_momentum_of_cartesian_kepler_is_conserved_over_1e5_steps() {
    // ξ(q) = (−y, x): J = x p_y − y p_x, the angular momentum. No coordinate
    // is cyclic in Cartesian form; the symmetry is declared.
    assert_eq!(<FreeKeplerCartesian as Lagrangian<2>>::CYCLIC, [false, false]);
    // Declared with `#[lagrangian(symmetry = rotation(0, 1))]`.
    let declared: Vec<Symmetry<2>> = Symmetry::declared::<FreeKeplerCartesian>().collect();
    assert_eq!(declared, [Symmetry::rotation(0, 1).unwrap()]);
    let rotation = declared[0];
    let kepler = || FreeKeplerCartesian { mu: 1.0 };
    let drift = |method, h| momentum_drift(kepler(), method, h, kepler_initial(), &rotation, N_LONG);
    assert_conserved("Cartesian Kepler, midpoint", drift(Midpoint, H_EXACT), drift(Midpoint, 0.01));
    let drift = |method, h| momentum_drift(kepler(), method, h, kepler_initial(), &rotation, N_LONG);
    assert_conserved("Cartesian Kepler, trapezoid", drift(Trapezoid, H_EXACT), drift(Trapezoid, 0.01));
}

#[test]
fn translation_momenta_are_conserved_over_1e5_steps() {
    // A coordinate the macro proves cyclic: the azimuth of the spherical
    // pendulum, J = p_φ.
    let cyclic: Vec<Symmetry<2>> = Symmetry::cyclic::<SphericalPendulum>().collect();
    assert_eq!(cyclic, [Symmetry::translation(1).unwrap()]);
    let pendulum = || SphericalPendulum { m: 1.0, l: 1.0, g: 9.81 };
    let initial = ([1.0, 0.0], [0.0, 2.0]);
    let drift = |h| momentum_drift(pendulum(), Midpoint, h, initial, &cyclic[0], N_LONG);
    assert_conserved("spherical pendulum p_φ", drift(H_EXACT), drift(0.01));
    // A translation of both bodies together, declared as a generator in the
    // attribute: the total momentum of a Morse pair, J = p_1 + p_2.
    let both = <MorsePair as Lagrangian<2>>::SYMMETRIES[0];
    assert_eq!(both.generator(&[0.3, -2.0]), [1.0, 1.0]);
    let pair = || MorsePair { m1: 1.0, m2: 2.0, d: 1.0, w: 1.5, r0: 1.0 };
    let initial = ([0.0, 1.3], [0.7, -0.1]);
    let drift = |h| momentum_drift(pair(), Midpoint, h, initial, &both, N_LONG);
    assert_conserved("Morse pair p_1 + p_2", drift(H_EXACT), drift(0.01));
}

/// Runs `n` steps and returns the largest
/// `|J_{k+1} − J_k − impulse_k| / max(|J_k|, |J_{k+1}|, |impulse_k|)`.
fn impulse_balance<S: Lagrangian<N>, M: DiscreteLagrangian, const N: usize>(
    system: S,
    method: M,
    h: f64,
    (q0, v0): ([f64; N], [f64; N]),
    symmetry: &impl Generator<N>,
    n: usize,
) -> (f64, f64) {
    let mut sim = Integrator::new(system, method, h).start(0.0, q0, v0).unwrap();
    let j0 = sim.momentum_map(symmetry);
    let mut j = j0;
    let (mut worst, mut total) = (0.0f64, 0.0f64);
    sim.run(n, |s| {
        let next = s.momentum_map(symmetry);
        let impulse = s.forcing_impulse(symmetry).unwrap();
        let scale = j.abs().max(next.abs()).max(impulse.abs());
        worst = worst.max((next - j - impulse).abs() / scale);
        total += impulse.abs();
        j = next;
    })
    .unwrap();
    assert!(total > 1e-2 * j0.abs(), "the forces must change J for the test to mean anything");
    (worst, (j - j0).abs() / j0.abs())
}

#[test]
fn with_forces_the_momentum_map_changes_by_the_forcing_impulse() {
    // Kepler with drag ½ c |v|² and a tangential thrust: J changes (the
    // thrust wins and J grows 90-fold), by exactly the impulse of each step.
    // Asserted: |J_{k+1} − J_k − impulse| ≤ 1e-13 max(|J_k|, |J_{k+1}|, |impulse|).
    let rotation = Symmetry::rotation(0, 1).unwrap();
    let n = 20_000;
    let system = || KeplerCartesian { mu: 1.0, c: 0.01, s: 0.02 };
    for (name, (worst, change)) in [
        ("midpoint", impulse_balance(system(), Midpoint, 0.01, kepler_initial(), &rotation, n)),
        ("trapezoid", impulse_balance(system(), Trapezoid, 0.01, kepler_initial(), &rotation, n)),
        ("α = 0.3", impulse_balance(system(), AlphaBeta::new(0.3).unwrap(), 0.01, kepler_initial(), &rotation, n)),
    ] {
        eprintln!("forced kepler, {name}: J changed by {change:.3} (relative); worst step balance {worst:.2e}");
        assert!(worst <= 1e-13, "{name}: {worst:e}");
    }
    // The sensor's charge, a cyclic coordinate, under the battery and the resistor.
    let charge = Symmetry::translation(1).unwrap();
    let (worst, _) =
        impulse_balance(Sensor { ..SENSOR_VARIABLE }, Midpoint, 0.001, ([0.0, 0.0], [0.0, 0.1]), &charge, n);
    eprintln!("sensor (variable L1), charge translation: worst step balance {worst:.2e}");
    assert!(worst <= 1e-13, "{worst:e}");
}

#[test]
fn a_broken_symmetry_shows_up_as_the_defect() {
    // The armature translation x ↦ x + ε is no symmetry of the sensor (the
    // spring and gravity break it): J = p_x changes by the forcing impulse
    // (zero: no force acts on x) plus the symmetry defect
    // ∂A/∂q_k·ξ + ∂A/∂q_{k+1}·ξ = −h k x̄ + h m g + h ½ L1'(x̄) q̇² (midpoint).
    let translation = Symmetry::translation(0).unwrap();
    let mut sim =
        Integrator::new(Sensor { ..SENSOR_VARIABLE }, Midpoint, 0.001).start(0.0, [0.0, 0.0], [0.0, 0.0]).unwrap();
    let mut j = sim.momentum_map(&translation);
    let mut worst = 0.0f64;
    let mut largest_defect = 0.0f64;
    sim.run(5_000, |s| {
        let seg = s.last_step().unwrap();
        let defect = noether::symmetry_defect(s.system(), s.method(), seg, &translation);
        let impulse = s.forcing_impulse(&translation).unwrap();
        let next = s.momentum_map(&translation);
        worst = worst.max((next - j - impulse - defect).abs() / j.abs().max(next.abs()).max(defect.abs()));
        largest_defect = largest_defect.max(defect.abs());
        j = next;
    })
    .unwrap();
    eprintln!("sensor, x translation: largest defect {largest_defect:.3e}, worst balance {worst:.2e}");
    assert!(largest_defect > 1e-4);
    assert!(worst <= 1e-12, "{worst:e}");
}

#[test]
fn symmetries_are_checked_and_their_generators_are_what_they_say() {
    assert!(Symmetry::<2>::translation(2).is_none());
    assert!(Symmetry::<3>::rotation(1, 1).is_none());
    assert!(Symmetry::<3>::rotation(0, 3).is_none());
    assert_eq!(Symmetry::<3>::translation(2).unwrap().generator(&[5.0, 6.0, 7.0]), [0.0, 0.0, 1.0]);
    assert_eq!(Symmetry::<3>::rotation(2, 0).unwrap().generator(&[5.0, 6.0, 7.0]), [7.0, 0.0, -5.0]);
    assert_eq!(noether::momentum_map(&Symmetry::<2>::rotation(0, 1).unwrap(), &[1.0, 2.0], &[3.0, 4.0]), 4.0 - 6.0);
    assert_eq!(Symmetry::cyclic::<FreeKeplerCartesian>().count(), 0);
    // A closure as a generator, directly (it may capture data).
    let axis = [0.6, 0.8];
    let along = move |_: &[f64; 2]| axis;
    assert_eq!(noether::momentum_map(&along, &[0.0, 0.0], &[1.0, 2.0]), 0.6 + 1.6);
    assert_eq!(Symmetry::declared::<Sensor>().count(), 0);
    assert_eq!(Symmetry::cyclic::<Sensor>().collect::<Vec<_>>(), [Symmetry::translation(1).unwrap()]);
    // Without forces the impulse is zero, before any step there is none.
    let mut sim = Integrator::new(FreeKeplerCartesian { mu: 1.0 }, Midpoint, 0.01)
        .start(0.0, kepler_initial().0, kepler_initial().1)
        .unwrap();
    let rotation = Symmetry::rotation(0, 1).unwrap();
    assert_eq!(sim.forcing_impulse(&rotation), None);
    sim.step().unwrap();
    assert_eq!(sim.forcing_impulse(&rotation), Some(0.0));
    let seg = *sim.last_step().unwrap();
    assert!(noether::symmetry_defect(sim.system(), sim.method(), &seg, &rotation).abs() < 1e-15);
    assert_eq!(forcing::discrete_forces(sim.system(), sim.method(), &seg), lagrangian::forcing::DiscreteForces::ZERO);
}
