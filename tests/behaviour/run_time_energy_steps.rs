//! Energy-preserving steps on run-time-sized systems (docs/theory.md §9 on
//! the reverse-mode driver): the same states and step sizes as at a
//! compile-time size, the discrete energy conserved to round-off on an
//! FPU-β chain, `run_until` and `solve` landing on their targets, the
//! typed refusals, and a failed step that leaves the stepper bit-identical.

use lagrangian::prelude::*;
use lagrangian::problem::Capability;
use lagrangian::{DynLagrangian, EnergyFallback, Error, PhasePoint, StepBounds};

use super::run_time_systems::{Chain, Chain4, DoublePendulum, DoublePendulumDyn, Pumped, PumpedDyn};

/// A pendulum over slices: trapezoid energy steps from rest lose the root
/// of the energy equation within a swing.
#[derive(Clone)]
struct Pendulum;

#[lagrangian]
impl Pendulum {
    fn dimension(&self) -> usize {
        1
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        0.5 * v[0] * v[0] + q[0].cos()
    }
}

/// The largest relative difference of two states, their times and the
/// sizes of their last steps.
fn difference<const N: usize>(a: &State<N>, a_h: f64, b: &PhasePoint, b_h: f64) -> f64 {
    let mut worst = ((a.t - b.t) / a.t).abs().max(((a_h - b_h) / a_h).abs());
    for (x, y) in a.q.iter().chain(&a.p).zip(b.q.iter().chain(&b.p)) {
        worst = worst.max((x - y).abs() / x.abs().max(1.0));
    }
    worst
}

/// Steps `steps` energy-preserving steps at both sizes and returns the
/// largest difference of the states and step sizes along the way, in
/// units of the rounding of the step size: the energy equation fixes `h`
/// through the `O(h²)` energy error of the rule, so a rounding `ε` of its
/// terms moves the root by `ε/h²` relative, and these add up over the steps.
fn both_sizes<S, D, const N: usize>(fixed: S, dynamic: D, (q0, v0): ([f64; N], [f64; N]), h: f64, steps: usize) -> f64
where
    S: Lagrangian<N>,
    D: DynLagrangian + Clone,
{
    let bounds = StepBounds::around(h);
    let mut a = Integrator::new(fixed, Midpoint, h).energy_preserving(bounds).start(0.0, q0, v0).unwrap();
    let problem = Problem::new(dynamic, 0.0, q0.to_vec(), v0.to_vec());
    let mut b = problem.stepper(&Scheme::MIDPOINT, Policy::EnergyPreserving { h, bounds }).unwrap();
    let (mut worst, mut smallest, mut largest) = (0.0f64, f64::INFINITY, 0.0f64);
    for _ in 0..steps {
        a.step().unwrap();
        b.step().unwrap();
        let (ha, hb) = (a.last_step_size().unwrap(), b.last_step_size().unwrap());
        worst = worst.max(difference(a.state(), ha, b.state(), hb));
        (smallest, largest) = (smallest.min(ha), largest.max(ha));
    }
    // The steps vary: the energy equation, not the guess, chose them.
    assert!(largest / smallest > 1.05, "steps in [{smallest}, {largest}]");
    let unit = steps as f64 * f64::EPSILON / (h * h);
    println!(
        "{steps} energy steps, h in [{smallest:.4}, {largest:.4}]: largest difference {worst:.2e} ({:.3} steps·ε/h²)",
        worst / unit
    );
    worst / unit
}

#[test]
fn a_chain_takes_the_same_energy_steps_at_both_sizes() {
    let q0 = [0.9, -0.3, 0.5, 0.2];
    let worst = both_sizes(Chain4, Chain { n: 4, walls: true }, (q0, [0.0, 0.4, 0.0, -0.2]), 0.05, 400);
    assert!(worst < 2.0, "{worst}");
}

#[test]
fn a_double_pendulum_takes_the_same_energy_steps_at_both_sizes() {
    let worst =
        both_sizes(DoublePendulum { g: 1.0 }, DoublePendulumDyn { g: 1.0 }, ([0.5, 0.3], [0.0, 0.0]), 0.01, 400);
    assert!(worst < 2.0, "{worst}");
}

/// A time-dependent `L`: the energy equation is the discrete energy
/// balance of de León & Martín de Diego, with the seed on `t_k`.
#[test]
fn a_time_dependent_oscillator_takes_the_same_energy_steps_at_both_sizes() {
    let worst = both_sizes(Pumped, PumpedDyn, ([1.0], [0.3]), 0.05, 400);
    assert!(worst < 2.0, "{worst}");
}

/// A free FPU-β chain of 32 masses: the discrete energy after the first
/// step is conserved to round-off, `|E_k − E_1| / |E_1|` within a few
/// `ε·√k`, while the steps vary.
#[test]
fn a_free_chain_conserves_its_discrete_energy_to_round_off() {
    let n = 32;
    let q0: Vec<f64> = (0..n).map(|i| 0.4 * (2.0 * core::f64::consts::PI * i as f64 / n as f64).sin()).collect();
    let v0: Vec<f64> = (0..n).map(|i| 0.1 * (i as f64 * 0.7).cos()).collect();
    let h = 0.05;
    let policy = Policy::EnergyPreserving { h, bounds: StepBounds::around(h) };
    let mut sim = Problem::new(Chain { n, walls: false }, 0.0, q0, v0).stepper(&Scheme::MIDPOINT, policy).unwrap();
    sim.step().unwrap();
    let e1 = sim.discrete_energy();
    let steps = 1000;
    let (mut worst, mut smallest, mut largest) = (0.0f64, f64::INFINITY, 0.0f64);
    for _ in 0..steps {
        sim.step().unwrap();
        worst = worst.max((sim.discrete_energy() - e1).abs() / e1.abs());
        let h = sim.last_step_size().unwrap();
        (smallest, largest) = (smallest.min(h), largest.max(h));
    }
    let bound = 4.0 * f64::EPSILON * (steps as f64).sqrt();
    println!(
        "free FPU-β N = {n}, {steps} energy steps (h in [{smallest:.4}, {largest:.4}]): max |E − E₁|/|E₁| = {worst:.2e} ({:.2} ε√k)",
        worst / (f64::EPSILON * (steps as f64).sqrt())
    );
    assert!(worst < bound, "{worst:e} against {bound:e}");
    assert!(largest / smallest > 1.002, "steps in [{smallest}, {largest}]");
    // The steps are those of the energy equation, not of a fallback.
    assert_eq!(sim.stats().energy_fallbacks, 0);
}

/// `run_until` and `solve` through the one way in land on their targets,
/// the steps between energy steps.
#[test]
fn energy_steps_land_on_targets_through_the_problem() {
    let (q0, v0) = (vec![0.9, -0.3, 0.5, 0.2], vec![0.0, 0.4, 0.0, -0.2]);
    let problem = Problem::new(Chain { n: 4, walls: true }, 0.0, q0, v0);
    let policy = Policy::energy_preserving(0.05);
    assert!(problem.supports(&Scheme::MIDPOINT, policy, Capability::Solve).is_ok());
    let mut sim = problem.stepper(&Scheme::MIDPOINT, policy).unwrap();
    for k in 1..=20 {
        let target = 0.37 * k as f64;
        sim.run_until(target).unwrap();
        assert_eq!(sim.state().t, target);
    }
    let plan = Plan::until(3.0).every(5).save_at(vec![1.234]).event(Event::new(|_t, q, _v| q[0]));
    let solution = problem.solve(&Scheme::MIDPOINT, policy, plan).unwrap().into_result().unwrap();
    assert_eq!(solution.t.last(), Some(&3.0));
    assert!(solution.t.contains(&1.234));
    assert!(!solution.events.is_empty());
    // The α-β rule too (the trapezoid's energy equation loses its root on
    // this chain within three steps: `NoEnergyStep`, as at a compile-time size).
    let mut sim = problem.stepper(&Scheme::alpha_beta(0.5).unwrap(), policy).unwrap();
    sim.run_until(1.0).unwrap();
    assert_eq!(sim.state().t, 1.0);
    let mut sim = problem.stepper(&Scheme::TRAPEZOID, policy).unwrap();
    assert!(matches!(sim.run_until(1.0), Err(Error::NoEnergyStep { .. })));
}

#[test]
fn bad_bounds_and_undefined_combinations_are_typed_errors() {
    let chain = Chain { n: 4, walls: true };
    let (q0, v0) = ([0.1; 4], [0.0; 4]);
    let problem = Problem::new(chain.clone(), 0.0, q0.to_vec(), v0.to_vec());
    let start = |bounds: StepBounds, h: f64| {
        problem.stepper(&Scheme::MIDPOINT, Policy::EnergyPreserving { h, bounds }).map(|_| ())
    };
    let good = StepBounds::around(0.1);
    for bounds in [
        StepBounds { h_min: 0.2, h_max: 0.1, ..good },
        StepBounds { max_ratio: 1.0, ..good },
        StepBounds { h_min: f64::NAN, ..good },
        StepBounds { h_min: 0.0, ..good },
    ] {
        assert!(matches!(start(bounds, 0.1), Err(Error::InvalidStepBounds { .. })), "{bounds:?}");
    }
    assert!(matches!(start(good, 1e3), Err(Error::InvalidStepSize { .. })));
    assert!(matches!(start(good.with_accuracy(1e-3), 0.1), Err(Error::Unsupported { .. })));
    // The driver's own refusal (named directly: the problem refuses this
    // combination before the driver is built, below).
    use lagrangian_runtime::DynIntegrator;
    let composition = DynIntegrator::new(chain.clone(), Composition::YOSHIDA4, 0.1).energy_preserving(good);
    assert!(matches!(composition.start(0.0, &q0, &v0), Err(Error::Unsupported { .. })));
    // Through the problem: compositions refused by name (the Galerkin
    // rules' energy steps: `run_time_galerkin_energy.rs`).
    let policy = Policy::energy_preserving(0.1);
    let scheme = Scheme::composition(Composition::YOSHIDA4, lagrangian::problem::OnePoint::Trapezoid);
    let Err(Error::Unsupported { what }) = problem.stepper(&scheme, policy) else { panic!("{scheme:?} accepted") };
    assert!(what.contains("composition"), "{what}");
    // A guess outside the bounds of a stepper that takes energy steps.
    let mut sim = problem.stepper(&Scheme::MIDPOINT, Policy::EnergyPreserving { h: 0.1, bounds: good }).unwrap();
    assert!(matches!(sim.set_step_size(1e3), Err(Error::InvalidStepSize { .. })));
}

/// The bits of everything a step may change.
fn bits(sim: &impl RunTimeStepping) -> Vec<u64> {
    let PhasePoint { step, t, q, p } = sim.state();
    let mut out = vec![*step, t.to_bits(), sim.discrete_energy().to_bits(), sim.step_size().to_bits()];
    out.extend(q.iter().chain(p).map(|x| x.to_bits()));
    out.extend(sim.last_step_size().map(f64::to_bits));
    out
}

/// Trapezoid energy steps of a pendulum from rest lose the root of the
/// energy equation within a swing: a typed `NoEnergyStep` with the state,
/// the stepper bit-identical after it, and the step of least mismatch under
/// the least-squares fallback.
#[test]
fn no_energy_step_leaves_the_stepper_bit_identical() {
    let problem = Problem::new(Pendulum, 0.0, vec![1.0], vec![0.0]);
    let mut sim = problem.stepper(&Scheme::TRAPEZOID, Policy::energy_preserving(0.05)).unwrap();
    let start = |fallback| {
        problem.clone().energy_fallback(fallback).stepper(&Scheme::TRAPEZOID, Policy::energy_preserving(0.05)).unwrap()
    };
    for _ in 0..1000 {
        let before = bits(&sim);
        let stats = sim.stats();
        match sim.step() {
            Ok(_) => continue,
            Err(Error::NoEnergyStep { state, h_lo, h_hi, h_best, mismatch, .. }) => {
                assert_eq!(bits(&sim), before, "the failed step changed the stepper");
                assert_eq!(sim.stats().failed_steps, stats.failed_steps + 1);
                assert_eq!(sim.stats().steps, stats.steps);
                assert_eq!(state, *sim.state());
                assert!(h_lo < h_hi && (h_lo..=h_hi).contains(&h_best) && mismatch > 0.0);
                // Again from the same state: the same error, the same bits.
                let again = sim.step().unwrap_err();
                assert!(matches!(again, Error::NoEnergyStep { .. }));
                assert_eq!(bits(&sim), before);
                let mut fallback = start(EnergyFallback::LeastSquares);
                fallback.run(state.step as usize + 1, |_| {}).unwrap();
                assert_eq!(fallback.stats().energy_fallbacks, 1);
                return;
            }
            Err(other) => panic!("{other:?}"),
        }
    }
    panic!("the swing found an energy root at every step");
}

/// Energy-balance steps are for forced systems.
#[test]
fn energy_balance_steps_without_forces_are_refused_with_their_reason() {
    let problem = Problem::new(Chain { n: 4, walls: true }, 0.0, vec![0.1; 4], vec![0.0; 4]);
    let Err(Error::Unsupported { what }) = problem.stepper(&Scheme::MIDPOINT, Policy::energy_balance(0.1)) else {
        panic!("energy balance without forces accepted")
    };
    assert!(what.contains("without forces"), "{what}");
}
