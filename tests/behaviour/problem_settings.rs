//! The settings a `Problem` hands to its drivers: the summation of the
//! state's updates and the energy steps' fallback, at both sizes, the same
//! steps as the drivers configured by hand.

use lagrangian::prelude::*;
use lagrangian::{EnergyFallback, Error};

/// A free particle far from the origin, its size known at compile time:
/// each step adds an increment 1e-7 times the coordinate, so plain sums
/// lose a rounding of `ulp(1e4)` per step where compensated ones keep it.
#[derive(Clone)]
struct Drift;

#[lagrangian]
impl Drift {
    fn lagrangian(&self, _q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0]
    }
}

/// The same particle with its size known at run time.
#[derive(Clone)]
struct DriftDyn;

#[lagrangian]
impl DriftDyn {
    fn dimension(&self) -> usize {
        1
    }

    fn lagrangian(&self, _q: &[f64], v: &[f64]) -> f64 {
        0.5 * v[0] * v[0]
    }
}

/// A pendulum: trapezoid energy steps from near the top lose the root of
/// the energy equation within a swing.
#[derive(Clone)]
struct Pendulum;

#[lagrangian]
impl Pendulum {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] + q[0].cos()
    }
}

const STEPS: usize = 100_000;
/// `q0 + STEPS·h·v0`, exact in binary: the compensated sums end within one
/// rounding of it.
const EXACT: f64 = 1e4 + 1e5 * (0.3 * 0.01);

/// `Summation::Plain` through `Problem` takes the plain-summed steps of
/// the driver (the same bits at both sizes), and `Compensated`, the
/// default, the compensated ones: 1e5 roundings to `ulp(1e4)` all one way
/// against the exact sum.
#[test]
fn the_summation_reaches_the_driver_at_both_sizes() {
    for summation in [Summation::Plain, Summation::Compensated] {
        let fixed = Problem::new(Drift, 0.0, [1e4], [0.3]).summation(summation);
        let mut a = fixed.stepper(&Scheme::TRAPEZOID, 0.01).unwrap();
        a.run(STEPS, |_| {}).unwrap();
        let dynamic = Problem::new(DriftDyn, 0.0, vec![1e4], vec![0.3]).summation(summation);
        let mut b = dynamic.stepper(&Scheme::TRAPEZOID, 0.01).unwrap();
        b.run(STEPS, |_| {}).unwrap();
        let mut by_hand =
            Integrator::new(Drift, Trapezoid, 0.01).summation(summation).start(0.0, [1e4], [0.3]).unwrap();
        by_hand.run(STEPS, |_| {}).unwrap();
        assert_eq!(a.state().q[0].to_bits(), by_hand.state().q[0].to_bits(), "{summation:?}");
        assert_eq!(a.state().q[0].to_bits(), b.state().q[0].to_bits(), "{summation:?}");
        let error = (a.state().q[0] - EXACT).abs();
        match summation {
            Summation::Compensated => assert!(error <= 2e-12, "{error:e}"),
            _ => assert!(error > 1e-9, "plain sums as exact as compensated ones: {error:e}"),
        }
    }
}

/// The default fallback fails with `NoEnergyStep` where the energy
/// equation has no root; `EnergyFallback::LeastSquares` takes the step of
/// least mismatch there, counts it, and goes on.
#[test]
fn the_energy_fallback_reaches_the_driver() {
    let problem = Problem::new(Pendulum, 0.0, [3.0], [0.0]);
    let policy = Policy::energy_preserving(0.05);
    let mut strict = problem.stepper(&Scheme::TRAPEZOID, policy).unwrap();
    let failed_at = loop {
        match strict.step() {
            Ok(_) if strict.state().step < 10_000 => continue,
            Ok(_) => panic!("the swing found an energy root at every step"),
            Err(Error::NoEnergyStep { state, .. }) => break state.step,
            Err(other) => panic!("{other:?}"),
        }
    };
    let mut lenient =
        problem.energy_fallback(EnergyFallback::LeastSquares).stepper(&Scheme::TRAPEZOID, policy).unwrap();
    lenient.run(failed_at as usize + 1, |_| {}).unwrap();
    assert!(lenient.stats().energy_fallbacks >= 1);
    assert_eq!(strict.stats().energy_fallbacks, 0);
}
