//! A Lagrangian with a jump, declared with `#[lagrangian(discontinuous)]`:
//! the macro sets `Lagrangian::DISCONTINUOUS`, and the integrator reports the
//! jump of the discrete energy where the trajectory crosses it.
#![allow(missing_docs)]

use lagrangian::Lagrangian;
use lagrangian::prelude::*;

/// A free particle of unit mass with a potential step of height `h` at
/// `q = x0`.
pub struct PotentialStep {
    pub h: f64,
    pub x0: f64,
}

#[lagrangian(discontinuous)]
impl PotentialStep {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        let beyond = q[0] > self.x0;
        0.5 * v[0] * v[0] - if beyond { self.h } else { 0.0 }
    }
}

/// A smooth oscillator, not declared.
pub struct Oscillator;

#[lagrangian]
impl Oscillator {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] - 0.5 * q[0] * q[0]
    }
}

/// The same oscillator, declared discontinuous although it is smooth: the
/// attribute only turns the record on.
pub struct DeclaredOscillator;

#[lagrangian(discontinuous)]
impl DeclaredOscillator {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] - 0.5 * q[0] * q[0]
    }
}

/// `Lagrangian::DISCONTINUOUS` of `S`, read through a generic function as the
/// runtime reads it.
fn discontinuous<S: Lagrangian<1>>() -> bool {
    S::DISCONTINUOUS
}

#[test]
fn the_attribute_sets_the_constant() {
    assert!(discontinuous::<PotentialStep>());
    assert!(discontinuous::<DeclaredOscillator>());
    assert!(!discontinuous::<Oscillator>());
}

#[test]
fn crossing_the_step_shows_as_an_energy_jump_at_the_crossing() {
    // From q = 0 at speed 1, E = 0.5; the step at q = 0.5 is reached at
    // t = 0.5. It lowers L by 0.3, i.e. raises the potential by 0.3: a
    // relative jump of about 0.6 in one step.
    let mut sim = Integrator::new(PotentialStep { h: 0.3, x0: 0.5 }, Midpoint, 0.01).start(0.0, [0.0], [1.0]).unwrap();
    sim.run_until(1.0, |_| {}).unwrap();
    let stats = sim.stats();
    println!(
        "potential step: largest energy jump {:.3} at t = {:.3}",
        stats.largest_energy_jump, stats.largest_energy_jump_at
    );
    assert!(stats.largest_energy_jump > 0.1, "{stats:?}");
    // Within a few steps of the crossing.
    assert!((0.48..0.54).contains(&stats.largest_energy_jump_at), "{stats:?}");
}

#[test]
fn smooth_systems_show_no_jump() {
    let mut sim = Integrator::new(Oscillator, Midpoint, 0.01).start(0.0, [1.0], [0.0]).unwrap();
    sim.run_until(2.0, |_| {}).unwrap();
    // Not declared: not measured.
    assert_eq!(sim.stats().largest_energy_jump, 0.0);

    let mut sim = Integrator::new(DeclaredOscillator, Midpoint, 0.01).start(0.0, [1.0], [0.0]).unwrap();
    sim.run_until(2.0, |_| {}).unwrap();
    let jump = sim.stats().largest_energy_jump;
    println!("declared smooth oscillator: largest energy jump {jump:.3e}");
    // The midpoint rule's energy error for the oscillator is O(h²) ≈ 1e-5
    // of E; far below the step's 0.6.
    assert!(jump < 1e-4, "{:?}", sim.stats());
}
