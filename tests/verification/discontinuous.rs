//! A Lagrangian with a jump, declared with `#[lagrangian(discontinuous)]`:
//! the macro sets `Lagrangian::DISCONTINUOUS`, and the integrator reports the
//! jump of the discrete energy where the trajectory crosses it.
#![allow(missing_docs)]

use lagrangian::prelude::*;
use lagrangian::problem::OnePoint;
use lagrangian::structure::Separability;
use lagrangian::{DynLagrangian, Lagrangian, Scalar};

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

/// The step with its structure declared by hand (a user's own
/// `Lagrangian` impl: the macro proves no structure through a branch):
/// `½v² − V(q)` with a constant mass, so trapezoid steps are explicit.
pub struct ExplicitStep(PotentialStep);

impl Lagrangian<1> for ExplicitStep {
    const AUTONOMOUS: bool = true;
    const CYCLIC: [bool; 1] = [false];
    const SEPARABILITY: Separability = Separability::ConstantMass;
    const DISCONTINUOUS: bool = true;
    fn lagrangian<D: Scalar>(&self, t: D, q: [D; 1], v: [D; 1]) -> D {
        Lagrangian::<1>::lagrangian(&self.0, t, q, v)
    }
}

/// The same step on a chain of free particles sized at run time, its
/// structure declared by hand: explicit steps through [`Problem`].
#[derive(Clone)]
pub struct DynStep(usize);

impl DynLagrangian for DynStep {
    const AUTONOMOUS: bool = true;
    const DISCONTINUOUS: bool = true;
    const SEPARABILITY: Separability = Separability::ConstantMass;
    fn dimension(&self) -> usize {
        self.0
    }
    fn lagrangian<D: Scalar>(&self, _: D, q: &[D], v: &[D]) -> D {
        let mut l = D::from(0.0);
        for (q, v) in q.iter().zip(v) {
            let beyond = q.re() > 0.5;
            l += D::from(0.5) * *v * *v - D::from(if beyond { 0.3 } else { 0.0 });
        }
        l
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
fn a_composition_reports_the_jump_of_its_sub_steps() {
    // The same crossing under Yoshida 4: a discontinuous system's composed
    // steps are taken sub-step by sub-step so that the watch sees each one.
    let system = PotentialStep { h: 0.3, x0: 0.5 };
    let mut sim = Integrator::new(system, lagrangian::Composition::YOSHIDA4, 0.01).start(0.0, [0.0], [1.0]).unwrap();
    sim.run_until(1.0, |_| {}).unwrap();
    let stats = sim.stats();
    println!(
        "potential step, Yoshida 4: largest energy jump {:.3} at t = {:.3}",
        stats.largest_energy_jump, stats.largest_energy_jump_at
    );
    assert!(stats.largest_energy_jump > 0.1, "{stats:?}");
    assert!((0.47..0.55).contains(&stats.largest_energy_jump_at), "{stats:?}");
}

#[test]
fn explicit_and_reverse_mode_steps_report_the_jump_too() {
    // Explicit trapezoid steps (a constant mass: Störmer–Verlet, no Newton)
    // and compositions of them, in forward and in reverse mode; and the
    // branching form's Newton steps in reverse mode.
    fn jump<S: Lagrangian<1>, M: lagrangian::F64Readouts + Copy>(
        system: S,
        method: M,
        derivatives: lagrangian::Derivatives,
        explicit: bool,
    ) -> (f64, f64) {
        let mut sim = Integrator::new(system, method, 0.01).derivatives(derivatives).start(0.0, [0.0], [1.0]).unwrap();
        sim.run_until(1.0, |_| {}).unwrap();
        assert_eq!(sim.stats().newton_iterations == 0, explicit, "{:?}", sim.stats());
        (sim.stats().largest_energy_jump, sim.stats().largest_energy_jump_at)
    }
    use lagrangian::Composition;
    use lagrangian::Derivatives::{Forward, Reverse};
    let explicit = || ExplicitStep(PotentialStep { h: 0.3, x0: 0.5 });
    let branch = || PotentialStep { h: 0.3, x0: 0.5 };
    let cases = [
        ("declared, trapezoid, forward", jump(explicit(), Trapezoid, Forward, true)),
        ("declared, trapezoid, reverse", jump(explicit(), Trapezoid, Reverse, true)),
        ("declared, Yoshida 4, forward", jump(explicit(), Composition::YOSHIDA4, Forward, true)),
        ("declared, Yoshida 4, reverse", jump(explicit(), Composition::YOSHIDA4, Reverse, true)),
        ("branch, midpoint, reverse", jump(branch(), Midpoint, Reverse, false)),
        ("branch, Yoshida 4, reverse", jump(branch(), Composition::YOSHIDA4, Reverse, false)),
    ];
    fn dyn_jump(scheme: Scheme) -> (f64, f64) {
        let mut chain = Problem::new(DynStep(3), 0.0, vec![0.0; 3], vec![1.0; 3]).stepper(&scheme, 0.01).unwrap();
        chain.run_until(1.0).unwrap();
        assert_eq!(chain.stats().newton_iterations, 0);
        (chain.stats().largest_energy_jump, chain.stats().largest_energy_jump_at)
    }
    let dynamic = [
        ("declared, run-time-sized, trapezoid", dyn_jump(Scheme::TRAPEZOID)),
        // Sub-stepped (not fused) so that the watch sees each sub-step.
        (
            "declared, run-time-sized, Yoshida 4",
            dyn_jump(Scheme::composition(Composition::YOSHIDA4, OnePoint::Trapezoid)),
        ),
    ];
    for (name, (size, at)) in cases.into_iter().chain(dynamic) {
        println!("potential step, {name}: largest energy jump {size:.3} at t = {at:.3}");
        assert!(size > 0.1, "{name}: {size}");
        assert!((0.47..0.55).contains(&at), "{name}: {at}");
    }
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
