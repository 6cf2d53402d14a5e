//! Verification: compositions of explicit Störmer–Verlet sub-steps run fused
//! (one check, one compensated sum and one commit per composed step), in
//! forward mode on `[f64; N]` arrays and in reverse mode on the heap with
//! the same operations. They agree to round-off with the same compositions
//! taken sub-step by sub-step (a system declared discontinuous keeps that
//! path: its energy watch needs every sub-step), forward and reverse mode
//! agree with each other, their readouts are rebuilt from the kept sub-step
//! increments, and a failed fused step leaves no trace.
use crate::common;

use common::{PENDULUM, Pendulum};
use lagrangian::prelude::*;
use lagrangian::{Composition, Derivatives};

/// `L = ½|v|² + 1/|q|`: separable, diagonal constant mass.
#[derive(Clone)]
struct Kepler;

#[lagrangian]
impl Kepler {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) + 1.0 / (q[0] * q[0] + q[1] * q[1]).sqrt()
    }
}

/// [`Kepler`] declared discontinuous: its compositions are taken sub-step
/// by sub-step.
#[derive(Clone)]
struct KeplerSubstepped;

#[lagrangian(discontinuous)]
impl KeplerSubstepped {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) + 1.0 / (q[0] * q[0] + q[1] * q[1]).sqrt()
    }
}

/// [`Coupled`] declared discontinuous (sub-stepped compositions).
#[derive(Clone)]
struct CoupledSubstepped;

#[lagrangian(discontinuous)]
impl CoupledSubstepped {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (2.0 * v[0] * v[0] + v[0] * v[1] + v[1] * v[1]) - 0.5 * (q[0] * q[0] + q[1] * q[1]) - 0.25 * q[0].powi(4)
    }
}

/// Two anharmonic oscillators with a constant, non-diagonal mass matrix
/// (the dense `M⁻¹` product of the explicit path).
#[derive(Clone)]
struct Coupled;

#[lagrangian]
impl Coupled {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (2.0 * v[0] * v[0] + v[0] * v[1] + v[1] * v[1]) - 0.5 * (q[0] * q[0] + q[1] * q[1]) - 0.25 * q[0].powi(4)
    }
}

/// Max |difference| of the states, discrete energies and velocities of two
/// runs after `steps` steps.
fn difference<A: Lagrangian<N>, B: Lagrangian<N>, const N: usize>(
    a: &mut Integrator<A, Composition, N>,
    b: &mut Integrator<B, Composition, N>,
    steps: usize,
) -> (f64, f64, f64) {
    a.run(steps, |_| {}).unwrap();
    b.run(steps, |_| {}).unwrap();
    let diff = |x: &[f64], y: &[f64]| x.iter().zip(y).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max);
    let (s, t) = (a.state(), b.state());
    let state = diff(&s.q, &t.q).max(diff(&s.p, &t.p));
    let energy = (a.discrete_energy() - b.discrete_energy()).abs();
    let velocity = diff(&a.velocity().unwrap(), &b.velocity().unwrap());
    (state, energy, velocity)
}

/// `(fused forward against sub-stepped, fused reverse against fused
/// forward)` differences (see [`difference`]) after `steps` steps of
/// `system`, whose discontinuous twin `substepped` takes the sub-steps one
/// by one.
fn fused_runs<S: Lagrangian<2> + Clone, T: Lagrangian<2>>(
    (system, substepped): (S, T),
    method: Composition,
    h: f64,
    (q0, v0): ([f64; 2], [f64; 2]),
    steps: usize,
) -> [(f64, f64, f64); 2] {
    let start = |d| Integrator::new(system.clone(), method, h).derivatives(d).start(0.0, q0, v0).unwrap();
    let mut fused = start(Derivatives::Forward);
    let mut sub = Integrator::new(substepped, method, h).start(0.0, q0, v0).unwrap();
    let against_sub_steps = difference(&mut fused, &mut sub, steps);
    let (mut forward, mut reverse) = (start(Derivatives::Forward), start(Derivatives::Reverse));
    let modes = difference(&mut forward, &mut reverse, steps);
    for it in [&fused, &forward] {
        assert_eq!(it.stats().newton_iterations, 0);
        assert_eq!(it.stats().steps, steps as u64);
    }
    assert_eq!(reverse.stats().newton_iterations, 0);
    assert_eq!(reverse.stats().steps, steps as u64);
    [against_sub_steps, modes]
}

#[test]
fn fused_steps_agree_with_sub_steps_to_round_off() {
    let start = ([0.5, 0.0], [0.0, 3f64.sqrt()]);
    let kepler = |m| fused_runs((Kepler, KeplerSubstepped), m, 0.05, start, 1000);
    let coupled = |m| fused_runs((Coupled, CoupledSubstepped), m, 0.05, ([1.0, -0.5], [0.0, 0.3]), 1000);
    for (name, method) in [
        ("Yoshida 4", Composition::YOSHIDA4),
        ("Yoshida 6", Composition::YOSHIDA6),
        ("Kahan–Li 8", Composition::KAHAN_LI8),
    ] {
        for (system, [sub, modes]) in [("Kepler", kepler(method)), ("coupled", coupled(method))] {
            let (state, energy, velocity) = sub;
            println!(
                "{name}, {system}: fused / sub-stepped: max |Δ(q, p)| {state:.1e}, |ΔE_d| {energy:.1e}, |Δv| {velocity:.1e}"
            );
            // Round-off over 1000 steps (the orbit's period is 3.6, so about 14 orbits).
            assert!(state < 1e-11, "{name}, {system}: states differ by {state:e}");
            assert!(energy < 1e-11, "{name}, {system}: discrete energies differ by {energy:e}");
            assert!(velocity < 1e-11, "{name}, {system}: velocities differ by {velocity:e}");
            let (state, energy, velocity) = modes;
            println!(
                "{name}, {system}: forward / reverse: max |Δ(q, p)| {state:.1e}, |ΔE_d| {energy:.1e}, |Δv| {velocity:.1e}"
            );
            // The same operations but for `M⁻¹`: a product with forward
            // mode's inverse, reverse mode's reciprocals of a diagonal or
            // its LU solve.
            assert!(state < 1e-12, "{name}, {system}: states differ by {state:e}");
            assert!(energy < 1e-12, "{name}, {system}: discrete energies differ by {energy:e}");
            assert!(velocity < 1e-12, "{name}, {system}: velocities differ by {velocity:e}");
        }
    }
}

/// A driven anharmonic oscillator: separable with a constant mass and a
/// time-dependent potential, so every sub-node's force is taken at its own
/// time.
#[derive(Clone)]
struct Driven;

#[lagrangian]
impl Driven {
    fn lagrangian(&self, t: f64, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] - 0.5 * q[0] * q[0] - 0.25 * q[0].powi(4) + q[0] * (2.0 * t).sin()
    }
}

#[test]
fn time_dependent_fused_steps_agree_in_both_modes() {
    for (name, method) in [("Yoshida 4", Composition::YOSHIDA4), ("Kahan–Li 8", Composition::KAHAN_LI8)] {
        let start = |d| Integrator::new(Driven, method, 0.05).derivatives(d).start(0.0, [0.5], [0.0]).unwrap();
        let (mut forward, mut reverse) = (start(Derivatives::Forward), start(Derivatives::Reverse));
        let (state, energy, velocity) = difference(&mut forward, &mut reverse, 1000);
        println!(
            "driven oscillator, {name}: forward / reverse: |Δ(q, p)| {state:.1e}, |ΔE_d| {energy:.1e}, |Δv| {velocity:.1e}"
        );
        assert_eq!(forward.stats().newton_iterations + reverse.stats().newton_iterations, 0);
        assert!(state < 1e-13 && energy < 1e-13 && velocity < 1e-13, "{name}: {state:e} {energy:e} {velocity:e}");
        assert_eq!(forward.state().t, reverse.state().t);
    }
}

#[test]
fn a_failed_fused_step_leaves_no_trace() {
    let h = 0.01;
    let start =
        || Integrator::new(Pendulum { ..PENDULUM }, Composition::KAHAN_LI8, h).start(0.0, [1.0], [0.0]).unwrap();
    let mut sim = start();
    sim.run(10, |_| {}).unwrap();
    let snapshot = |s: &Integrator<Pendulum, Composition, 1>| {
        let tangent = s.last_tangent_map().unwrap().matrix();
        (
            *s.state(),
            s.discrete_energy().to_bits(),
            s.velocity().unwrap()[0].to_bits(),
            tangent.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
            s.last_step_size(),
        )
    };
    let before = snapshot(&sim);
    // A step so large that the positions overflow.
    sim.set_step_size(1e300).unwrap();
    let err = sim.step().unwrap_err();
    assert!(matches!(err, Error::NonFinite { .. }), "{err:?}");
    assert_eq!(sim.stats().failed_steps, 1);
    sim.set_step_size(h).unwrap();
    let after = snapshot(&sim);
    assert_eq!(before.0.q.map(f64::to_bits), after.0.q.map(f64::to_bits));
    assert_eq!(before.0.p.map(f64::to_bits), after.0.p.map(f64::to_bits));
    assert_eq!((before.1, before.2, &before.3, before.4), (after.1, after.2, &after.3, after.4));
    // Continuing gives the run that never failed, bit for bit.
    sim.run(10, |_| {}).unwrap();
    let mut clean = start();
    clean.run(20, |_| {}).unwrap();
    assert_eq!(sim.state().q[0].to_bits(), clean.state().q[0].to_bits());
    assert_eq!(sim.state().p[0].to_bits(), clean.state().p[0].to_bits());
    assert_eq!(sim.discrete_energy().to_bits(), clean.discrete_energy().to_bits());
}
