//! Energy-preserving steps of the Galerkin rules on run-time-sized systems
//! (docs/theory.md §3, §9, through `Problem<S, Dyn>`): the same steps and
//! states as at a compile-time size, the discrete energy conserved to
//! round-off over long runs, the typed refusals, and a failed step that
//! leaves the stepper bit-identical.

use lagrangian::prelude::*;
use lagrangian::problem::Capability;
use lagrangian::{Error, PhasePoint, StepBounds};

use super::run_time_forces::ForcedDyn;
use super::run_time_systems::{Chain, Chain4, DoublePendulum, DoublePendulumDyn, PumpedDyn};

/// The largest relative difference of two states.
fn difference<const N: usize>(a: &State<N>, b: &PhasePoint) -> f64 {
    let mut worst = ((a.t - b.t) / a.t).abs();
    for (x, y) in a.q.iter().chain(&a.p).zip(b.q.iter().chain(&b.p)) {
        worst = worst.max((x - y).abs() / x.abs().max(1.0));
    }
    worst
}

/// Takes `steps` energy-preserving steps of the Galerkin rule of degree
/// `s` at both sizes; returns the largest relative difference of the
/// states and of the step sizes along the way, in units of the rounding of
/// the step size, and the ratio of the largest step to the smallest. The
/// energy equation fixes `h` through the `O(h^{2s+1})` energy error of the
/// rule, so a rounding `ε` of its terms moves the root by about
/// `ε/h^{2s+1}` relative (the two sizes sum the terms in different
/// orders), and these add up over the steps.
fn both_sizes<F, D, const N: usize>(
    (fixed, dynamic): (F, D),
    (q0, v0): ([f64; N], [f64; N]),
    (s, h, steps): (usize, f64, usize),
) -> (f64, f64, f64)
where
    F: Lagrangian<N> + Clone,
    D: DynLagrangian + Clone,
    lagrangian::Dim<N>: lagrangian::problem::Extended<N>,
{
    let scheme = Scheme::galerkin(s);
    let policy = Policy::energy_preserving(h);
    let mut a = Problem::new(fixed, 0.0, q0, v0).stepper(&scheme, policy).unwrap();
    let problem = Problem::new(dynamic, 0.0, q0.to_vec(), v0.to_vec());
    assert!(problem.supports(&scheme, policy, Capability::Solve).is_ok());
    let mut b = problem.stepper(&scheme, policy).unwrap();
    let (mut worst, mut worst_h, mut smallest, mut largest) = (0.0f64, 0.0f64, f64::INFINITY, 0.0f64);
    let (mut ta, mut tb) = (0.0, 0.0);
    for _ in 0..steps {
        let (sa, sb) = (a.step().unwrap(), b.step().unwrap().clone());
        let (ha, hb) = (sa.t - ta, sb.t - tb);
        (ta, tb) = (sa.t, sb.t);
        worst = worst.max(difference(&sa, &sb));
        worst_h = worst_h.max(((ha - hb) / ha).abs());
        (smallest, largest) = (smallest.min(ha), largest.max(ha));
    }
    let unit = steps as f64 * f64::EPSILON / smallest.powi(2 * s as i32 + 1);
    let worst = worst.max(worst_h);
    println!(
        "s = {s}, {steps} energy steps, h in [{smallest:.5}, {largest:.5}]: states and steps differ by {worst:.2e} ({:.2} steps·ε/h^(2s+1))",
        worst / unit
    );
    (worst / unit, worst, largest / smallest)
}

/// Degree 2: an FPU-β chain and a double pendulum (a mass matrix that
/// depends on `q`), 20 steps each.
#[test]
fn galerkin_energy_steps_are_the_same_at_both_sizes_for_degree_2() {
    let (q0, v0) = ([0.9, -0.3, 0.5, 0.2], [0.0, 0.4, 0.0, -0.2]);
    let (worst, _, spread) = both_sizes((Chain4, Chain { n: 4, walls: true }), (q0, v0), (2, 0.2, 20));
    assert!(spread > 1.1 && worst < 100.0, "chain: {worst} units, spread {spread}");
    let (worst, _, spread) =
        both_sizes((DoublePendulum { g: 1.0 }, DoublePendulumDyn { g: 1.0 }), ([0.5, 0.3], [0.0, 0.0]), (2, 0.1, 20));
    assert!(spread > 1.1 && worst < 100.0, "double pendulum: {worst} units, spread {spread}");
}

/// Degree 3 on polar Kepler, the first steps. The energy error is
/// `O(h⁷)` here, and `g'` so small that each size accepts a step anywhere
/// in the band `|g| ≤ 64 ε |E|` (the compile-time Newton on `h` and the
/// run-time search stop at different points of it): `2.3e-5` apart at the
/// first energy step, `7e-4` after four (measured). A wrong energy or slope
/// would take other roots or none.
#[test]
fn galerkin_energy_steps_are_the_same_at_both_sizes_for_degree_3() {
    let (_, worst, spread) = both_sizes((Kepler, KeplerDyn), ([1.0, 0.0], [0.0, 0.8]), (3, 0.1, 4));
    assert!(spread > 1.1 && worst < 2e-3, "Kepler: {worst:e}, spread {spread}");
}

/// Polar Kepler (μ = 1): `L = ½(ṙ² + r²φ̇²) + 1/r`.
#[derive(Clone)]
struct Kepler;

#[lagrangian]
impl Kepler {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + q[0] * q[0] * v[1] * v[1]) + 1.0 / q[0]
    }
}

/// Polar Kepler over slices.
#[derive(Clone)]
struct KeplerDyn;

#[lagrangian]
impl KeplerDyn {
    fn dimension(&self) -> usize {
        2
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        0.5 * (v[0] * v[0] + q[0] * q[0] * v[1] * v[1]) + 1.0 / q[0]
    }
}

/// An FPU-β chain of 16 masses between walls, 10⁴ energy steps of degree
/// 2: the discrete energy after the first step is conserved to round-off
/// while the steps vary.
#[test]
fn a_chain_conserves_its_discrete_energy_over_ten_thousand_galerkin_energy_steps() {
    let n = 16;
    let q0: Vec<f64> = (0..n).map(|i| 0.5 * (core::f64::consts::PI * (i + 1) as f64 / (n + 1) as f64).sin()).collect();
    let v0: Vec<f64> = (0..n).map(|i| 0.1 * (i as f64 * 0.7).cos()).collect();
    let problem = Problem::new(Chain { n, walls: true }, 0.0, q0, v0);
    let mut sim = problem.stepper(&Scheme::galerkin(2), Policy::energy_preserving(0.1)).unwrap();
    sim.step().unwrap();
    let e1 = sim.discrete_energy();
    let steps = 10_000;
    let (mut worst, mut smallest, mut largest, mut t) = (0.0f64, f64::INFINITY, 0.0f64, sim.state().t);
    for _ in 0..steps {
        let h = sim.step().unwrap().t - t;
        t += h;
        worst = worst.max((sim.discrete_energy() - e1).abs() / e1.abs());
        (smallest, largest) = (smallest.min(h), largest.max(h));
    }
    let stats = sim.stats();
    println!(
        "FPU-β N = {n}, s = 2, {steps} energy steps (h in [{smallest:.4}, {largest:.4}]): max |E − E₁|/|E₁| = {worst:.2e}, {:.2} Newton iterations per step",
        stats.newton_iterations as f64 / stats.steps as f64
    );
    // As at a compile-time size (`galerkin_energy_steps.rs`: 1e-12 over
    // 1e5 steps of a pendulum): each step meets the energy equation to
    // 64 ε of its terms, and the target is never re-read.
    assert!(worst < 1e-12, "{worst:e}");
    assert!(largest / smallest > 1.01, "steps in [{smallest}, {largest}]");
    assert_eq!(stats.energy_fallbacks, 0);
}

/// The bits of everything a step may change.
fn bits(sim: &Stepper<KeplerDyn, lagrangian::Dyn>) -> Vec<u64> {
    let PhasePoint { step, t, q, p } = sim.state();
    let mut out = vec![*step, t.to_bits(), sim.discrete_energy().to_bits()];
    out.extend(q.iter().chain(p).map(|x| x.to_bits()));
    out
}

/// Polar Kepler at degree 3 loses the root of its energy equation within a
/// few steps: a typed `NoEnergyStep` with the state, the stepper
/// bit-identical after it (and after the same failure again).
#[test]
fn no_galerkin_energy_step_leaves_the_stepper_bit_identical() {
    let problem = Problem::new(KeplerDyn, 0.0, vec![1.0, 0.0], vec![0.0, 1.2]);
    let mut sim = problem.stepper(&Scheme::galerkin(3), Policy::energy_preserving(0.1)).unwrap();
    for _ in 0..100 {
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
                assert!(matches!(sim.step(), Err(Error::NoEnergyStep { .. })));
                assert_eq!(bits(&sim), before);
                return;
            }
            Err(other) => panic!("{other:?}"),
        }
    }
    panic!("every step found an energy root");
}

/// What is refused at a compile-time size is refused here, typed: forced
/// and time-dependent systems, bad bounds, a guess outside them.
#[test]
fn undefined_galerkin_energy_steps_are_typed_errors() {
    let galerkin = Scheme::galerkin(2);
    let forced = Problem::new(ForcedDyn { n: 4 }, 0.0, vec![0.1; 4], vec![0.0; 4]);
    for policy in [Policy::energy_preserving(0.1), Policy::energy_balance(0.1)] {
        let Err(Error::Unsupported { what }) = forced.stepper(&galerkin, policy) else { panic!("{policy:?} accepted") };
        assert!(what.contains("forces") || what.contains("Galerkin"), "{what}");
    }
    let pumped = Problem::new(PumpedDyn, 0.0, vec![1.0], vec![0.0]);
    let Err(Error::Unsupported { what }) = pumped.stepper(&galerkin, Policy::energy_preserving(0.1)) else {
        panic!("a time-dependent system accepted")
    };
    assert!(what.contains("time-dependent"), "{what}");
    let chain = Problem::new(Chain { n: 4, walls: true }, 0.0, vec![0.1; 4], vec![0.0; 4]);
    let good = StepBounds::around(0.1);
    let policy = |h, bounds| Policy::EnergyPreserving { h, bounds };
    let bad = StepBounds { h_min: 0.2, h_max: 0.1, ..good };
    assert!(matches!(chain.stepper(&galerkin, policy(0.1, bad)), Err(Error::InvalidStepBounds { .. })));
    assert!(matches!(chain.stepper(&galerkin, policy(1e3, good)), Err(Error::InvalidStepSize { .. })));
    assert!(matches!(chain.stepper(&Scheme::galerkin(17), policy(0.1, good)), Err(Error::Unsupported { .. })));
}
