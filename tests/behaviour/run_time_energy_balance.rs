//! Energy-balance steps on run-time-sized systems (docs/theory.md §6 on the
//! reverse-mode driver): the step size solves the discrete energy balance
//! `E_{k+1} − E_k = W_k` with the DEL, the work `W_k = w_{k−1}^+ + w_k^−`
//! of the discrete Lagrange–d'Alembert forces on the time variations. The
//! same states and step sizes as at a compile-time size (whose balance the
//! verification tests check at round-off), the balance's residual through
//! the compile-time integrator at every run-time step, the landing through
//! the problem, and a force that is not finite.

use lagrangian::prelude::*;
use lagrangian::{DynLagrangian, Error, PhasePoint, Scalar, StepBounds};

use super::run_time_forces::{Forced, ForcedDyn, shape};

/// The largest relative difference of two states, their times and the
/// sizes of their last steps.
fn difference<const N: usize>(a: &State<N>, a_h: f64, b: &PhasePoint, b_h: f64) -> f64 {
    let mut worst = ((a.t - b.t) / a.t).abs().max(((a_h - b_h) / a_h).abs());
    for (x, y) in a.q.iter().chain(&a.p).zip(b.q.iter().chain(&b.p)) {
        worst = worst.max((x - y).abs() / x.abs().max(1.0));
    }
    worst
}

/// `steps` energy-balance steps of the damped and driven chain of eight
/// masses at both sizes with the midpoint rule (the compile-time
/// trapezoid and α-β steps lose the root of the balance on this chain
/// within about a hundred steps, `NoEnergyStep`): the largest difference of the
/// states and step sizes along the way in units of `k·ε/h²` (the energy
/// equation fixes `h` through the `O(h²)` energy error of the rule, so a
/// rounding `ε` of its terms moves the root by `ε/h²` relative), and the
/// largest relative residual of the balance of the compile-time steps.
fn both_sizes(h: f64, steps: usize) -> (f64, f64) {
    let q0 = shape();
    let v0: [f64; 8] = core::array::from_fn(|i| 0.1 * (i as f64 - 3.5));
    let bounds = StepBounds::around(h);
    let mut a = Integrator::new(Forced, Midpoint, h).energy_preserving(bounds).start(0.0, q0, v0).unwrap();
    let problem = Problem::new(ForcedDyn { n: 8 }, 0.0, q0.to_vec(), v0.to_vec());
    let mut b = problem.stepper(&Scheme::MIDPOINT, Policy::EnergyBalance { h, bounds }).unwrap();
    let (mut worst, mut balance, mut smallest, mut largest) = (0.0f64, 0.0f64, f64::INFINITY, 0.0f64);
    for _ in 0..steps {
        a.step().unwrap();
        b.step().unwrap();
        let (ha, hb) = (a.last_step_size().unwrap(), b.last_step_size().unwrap());
        worst = worst.max(difference(a.state(), ha, b.state(), hb));
        (smallest, largest) = (smallest.min(ha), largest.max(ha));
        if let Some(e) = a.energy_balance() {
            let scale = e.energy_before.abs() + e.energy_after.abs() + e.variational_work.abs();
            balance = balance.max(e.variational_residual().abs() / scale);
        }
    }
    // The steps vary: the energy balance, not the guess, chose them.
    assert!(largest / smallest > 1.02, "steps in [{smallest}, {largest}]");
    // The run-time stepper conserves what the balance says: its discrete
    // energy is the compile-time one's.
    let (ea, eb) = (a.discrete_energy(), b.discrete_energy());
    assert!((ea - eb).abs() <= 1e-12 * ea.abs(), "{ea} against {eb}");
    let unit = steps as f64 * f64::EPSILON / (h * h);
    println!(
        "{steps} energy-balance steps, h in [{smallest:.4}, {largest:.4}]: largest difference {worst:.2e} \
         ({:.3} steps·ε/h²), balance residual {balance:.1e}, Newton iterations {} (compile-time size {})",
        worst / unit,
        b.stats().newton_iterations,
        a.stats().newton_iterations
    );
    (worst / unit, balance)
}

#[test]
fn a_forced_chain_takes_the_same_energy_balance_steps_at_both_sizes() {
    for (name, (worst, balance)) in [("h = 0.05", both_sizes(0.05, 400)), ("h = 0.02", both_sizes(0.02, 400))] {
        assert!(worst < 2.0, "{name}: {worst}");
        assert!(balance < 1e-13, "{name}: {balance:e}");
    }
}

/// A damped oscillator (`ω = 1`, `c = 0.3`) over slices.
#[derive(Clone)]
struct Damped;

impl DynLagrangian for Damped {
    const AUTONOMOUS: bool = true;
    const HAS_DISSIPATION: bool = true;

    fn dimension(&self) -> usize {
        1
    }

    fn lagrangian<D: Scalar>(&self, _t: D, q: &[D], v: &[D]) -> D {
        (v[0] * v[0] - q[0] * q[0]) * 0.5
    }

    fn dissipation<D: Scalar>(&self, _q: &[D], v: &[D]) -> D {
        v[0] * v[0] * 0.15
    }
}

/// Through the problem: `run_until` and `solve` land on their targets, and
/// the energy falls as the damping says, `E(t) ≈ E(0) e^{−ct}` for a light
/// damping (to the `O(c²)` of the averaged decay, within 5 %).
#[test]
fn energy_balance_steps_land_and_follow_the_decay() {
    let problem = Problem::new(Damped, 0.0, vec![1.0], vec![0.0]);
    let policy = Policy::energy_balance(0.01);
    let mut sim = problem.stepper(&Scheme::MIDPOINT, policy).unwrap();
    sim.run_until(5.0).unwrap();
    assert_eq!(sim.state().t, 5.0);
    let decay = sim.energy().unwrap() / 0.5;
    let expected = (-0.3f64 * 5.0).exp();
    assert!((decay / expected - 1.0).abs() < 0.05, "{decay} against {expected}");
    let plan = Plan::until(5.0).every(0).save_at(vec![1.0, 2.5, 4.0]);
    let solution = problem.solve(&Scheme::MIDPOINT, policy, plan).unwrap();
    for t in [1.0, 2.5, 4.0] {
        assert!(solution.t.contains(&t), "{t} not in {:?}", solution.t);
    }
    assert!(solution.is_finished());
    assert!(sim.stats().steps > 100, "{:?}", sim.stats());
}

/// A dissipation that is not finite beyond `q = 2`.
#[derive(Clone)]
struct Blowing;

impl DynLagrangian for Blowing {
    const AUTONOMOUS: bool = true;
    const HAS_DISSIPATION: bool = true;

    fn dimension(&self) -> usize {
        1
    }

    fn lagrangian<D: Scalar>(&self, _t: D, q: &[D], v: &[D]) -> D {
        (v[0] * v[0] - q[0] * q[0]) * 0.5
    }

    fn dissipation<D: Scalar>(&self, q: &[D], v: &[D]) -> D {
        v[0] * v[0] * (D::from(2.0) - q[0]).sqrt() * 0.01
    }
}

/// The oscillator swings from `q = −2.5` through `q = 2`, where the
/// dissipation stops being finite: a typed error with the state, the
/// stepper unchanged.
#[test]
fn a_force_that_is_not_finite_leaves_the_stepper_as_it_was() {
    let problem = Problem::new(Blowing, 0.0, vec![-2.5], vec![0.0]);
    let mut sim = problem.stepper(&Scheme::MIDPOINT, Policy::energy_balance(0.05)).unwrap();
    for _ in 0..200 {
        let before = (sim.state().clone(), sim.discrete_energy().to_bits(), sim.stats().steps);
        match sim.step() {
            Ok(_) => continue,
            Err(error) => {
                let state = match &error {
                    Error::NonFinite { state, .. }
                    | Error::NewtonDidNotConverge { state, .. }
                    | Error::NoEnergyStep { state, .. } => state.clone(),
                    other => panic!("{other:?}"),
                };
                assert_eq!(state, before.0, "{error:?}");
                println!("{error}");
                assert_eq!((sim.state().clone(), sim.discrete_energy().to_bits(), sim.stats().steps), before);
                return;
            }
        }
    }
    panic!("the oscillator never reached q = 2");
}
