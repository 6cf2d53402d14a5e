//! FPU-β chains from 2 to 1 000 masses, stepped and solved with an event,
//! in a thread with the default 2 MiB stack, with a bounded energy error;
//! the derivatives of large systems' trajectories in such a thread
//! (`sensitivities.rs`: the forward sensitivities' size limit, the adjoint
//! of 1000 masses).
//!
//! A test binary of the facade, optimised as the other long tests: what
//! fits a default stack depends on the stack frames the optimiser leaves
//! (unoptimised, the composition and the solve with an event overflow
//! it), and the rest of `tests/systems/` and the small systems'
//! sensitivities in `tests/verification/` are built unoptimised
//! (`systems-tests/`, `verification-tests/`).

// `pub` items of the test modules are reachable only inside this test crate.
#![allow(unreachable_pub)]

#[path = "../systems/chains.rs"]
mod chains;
#[path = "../common/parametric_chain.rs"]
mod parametric_chain;
mod sensitivities;

use chains::{Fpu, chain_energy_error, chain_mode};
use lagrangian::prelude::*;
use lagrangian::{Action, Direction};

fn chains_in_a_default_thread<M: lagrangian::F64Readouts + Copy + Send + 'static>(method: M, name: &'static str) {
    // `std::thread::spawn` gives the default 2 MiB stack.
    std::thread::spawn(move || {
        let worst = |e: Vec<f64>| e.into_iter().fold(0.0f64, f64::max);
        let runs = [
            (2, worst(chain_energy_error::<M, 2>(method, 0.05, 200, 20))),
            (100, worst(chain_energy_error::<M, 100>(method, 0.05, 200, 20))),
            (1000, worst(chain_energy_error::<M, 1000>(method, 0.05, 100, 20))),
        ];
        for (n, e) in runs {
            println!("{name}: FPU-β N = {n}: relative energy error {e:.2e}");
            // O((ωh)²) for both rules, ω ≤ 2 and h = 0.05; and not zero.
            assert!(e < 2e-3 && e > 1e-12, "{name} N = {n}: {e:e}");
        }
    })
    .join()
    .expect("no stack overflow, no panic");
}

#[test]
fn chains_up_to_a_thousand_masses_run_in_a_default_thread_explicit() {
    chains_in_a_default_thread(Trapezoid, "trapezoid (explicit)");
}

#[test]
fn chains_up_to_a_thousand_masses_run_in_a_default_thread_newton() {
    chains_in_a_default_thread(Midpoint, "midpoint (banded Newton)");
}

/// A composition's integrator keeps the last step's sub-steps (inline, 15
/// segments) and, in reverse mode, steps the integrator's own fields: a
/// 1000-mass chain still fits a default thread.
#[test]
fn chains_up_to_a_thousand_masses_run_in_a_default_thread_composition() {
    chains_in_a_default_thread(lagrangian::Composition::YOSHIDA4, "Yoshida 4 (explicit sub-steps)");
}

/// `Problem::solve` on a chain of 1000 masses in a default thread, with
/// save times and a stopping event (the paths that keep a copy of the
/// stepper from before each step and redo a step to end on the event): the
/// copy lives on the heap, so the run fits a 2 MiB stack. From rest in
/// mode 100 (`ω = 2 sin(100π/2002) ≈ 0.31`), `q_0` first falls through zero
/// near a quarter period, `t ≈ 5`; the node the run ends on is one step of
/// the method from the dense output that located the crossing, so `q_0`
/// there is within a step's local error, `(ωh)³` of the amplitude.
#[test]
fn a_thousand_mass_chain_solves_with_an_event_in_a_default_thread() {
    const N: usize = 1000;
    std::thread::spawn(|| {
        let (h, omega) = (0.05, 2.0 * (100.0 * core::f64::consts::PI / 2002.0).sin());
        let q0 = chain_mode::<N>(N / 10, 0.3);
        let problem = Problem::new(Fpu::<N> { beta: 1.0 }, 0.0, q0, [0.0; N]);
        let yoshida = Scheme::composition(lagrangian::Composition::YOSHIDA4, OnePoint::Trapezoid);
        for scheme in [Scheme::MIDPOINT, yoshida] {
            let plan = Plan::until(8.0)
                .every(20)
                .save_at(vec![1.0, 2.0])
                .event(Event::new(|_t, q: &[f64], _v: &[f64]| q[0]).direction(Direction::Falling).action(Action::Stop));
            let sol = problem.solve(&scheme, h, plan).unwrap().into_result().unwrap();
            let event = sol.events.first().cloned().expect("q_0 changes sign before t = 8");
            let (t, q) = (*sol.t.last().unwrap(), sol.q.last().unwrap());
            println!("{scheme:?}: N = {N}, q_0 = 0 at t = {:.6}, {} rows, q_0 there {:.1e}", event.t, sol.len(), q[0]);
            assert!((4.0..6.0).contains(&event.t) && t == event.t, "{} {t}", event.t);
            assert!(sol.t.contains(&1.0) && sol.t.contains(&2.0));
            assert!(q[0].abs() <= (omega * h).powi(3) * q0[0], "{:e}", q[0]);
        }
    })
    .join()
    .expect("no stack overflow, no panic");
}

/// The FPU-β chain with its size known at run time, fixed ends.
#[derive(Clone)]
struct DynFpu {
    n: usize,
}

#[lagrangian]
impl DynFpu {
    fn dimension(&self) -> usize {
        self.n
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        let n = q.len();
        let mut kinetic = 0.0;
        for i in 0..n {
            kinetic += 0.5 * v[i] * v[i];
        }
        let (first, last) = (q[0], q[n - 1]);
        let mut potential = 0.5 * first * first + 0.25 * first.powi(4) + 0.5 * last * last + 0.25 * last.powi(4);
        for i in 0..n - 1 {
            let d = q[i + 1] - q[i];
            potential += 0.5 * d * d + 0.25 * d.powi(4);
        }
        kinetic - potential
    }
}

/// A Galerkin rule (s = 2) on a run-time-sized chain of 100 000 masses, in
/// a default thread: the tape, its sweeps and the banded Newton block of
/// the `2N` node unknowns live on the heap. From mode `N/10` (strain 0.3),
/// three steps of `h = 0.05` keep the energy to `O((ωh)⁴)`, `ω ≤ 2`.
#[test]
fn a_run_time_sized_chain_of_100_000_takes_galerkin_steps_in_a_default_thread() {
    std::thread::spawn(|| {
        let n = 100_000;
        let k = n / 10;
        let a = 0.3 * (n + 1) as f64 / (k as f64 * core::f64::consts::PI);
        let q0: Vec<f64> =
            (0..n).map(|i| a * ((i + 1) as f64 * k as f64 * core::f64::consts::PI / (n + 1) as f64).sin()).collect();
        let problem = Problem::new(DynFpu { n }, 0.0, q0, vec![0.0; n]);
        let mut sim = problem.stepper(&Scheme::galerkin(2), 0.05).unwrap();
        let e0 = sim.energy().unwrap();
        sim.run(3, |_| {}).unwrap();
        let error = (sim.energy().unwrap() - e0).abs() / e0;
        let state = sim.state();
        println!("FPU-β N = 100 000, Galerkin s = 2, 3 steps: relative energy error {error:.2e}");
        assert!(state.q.iter().chain(&state.p).all(|x| x.is_finite()));
        assert!(error < 1e-4 && error > 1e-15, "{error:e}");
    })
    .join()
    .expect("no stack overflow, no panic");
}

/// Energy-preserving midpoint steps on a run-time-sized chain of 100 000
/// masses, in a default thread: each trial step is the banded Newton solve
/// of the DEL on the heap, the slope of the energy equation one more banded
/// solve. From mode `N/10` with a velocity, the discrete energy after the
/// first step holds to round-off over three steps whose sizes the energy
/// equation chose.
#[test]
fn a_run_time_sized_chain_of_100_000_takes_energy_steps_in_a_default_thread() {
    std::thread::spawn(|| {
        let n = 100_000;
        let k = n / 10;
        let a = 0.3 * (n + 1) as f64 / (k as f64 * core::f64::consts::PI);
        let q0: Vec<f64> =
            (0..n).map(|i| a * ((i + 1) as f64 * k as f64 * core::f64::consts::PI / (n + 1) as f64).sin()).collect();
        let v0: Vec<f64> = (0..n).map(|i| 0.1 * (0.7 * i as f64).cos()).collect();
        let problem = Problem::new(DynFpu { n }, 0.0, q0, v0);
        let mut sim = problem.stepper(&Scheme::MIDPOINT, Policy::energy_preserving(0.05)).unwrap();
        sim.step().unwrap();
        let e1 = sim.discrete_energy();
        sim.run(3, |_| {}).unwrap();
        let error = (sim.discrete_energy() - e1).abs() / e1;
        let state = sim.state();
        println!("FPU-β N = 100 000, energy-preserving midpoint, 3 steps: relative discrete energy error {error:.2e}");
        assert!(state.q.iter().chain(&state.p).all(|x| x.is_finite()));
        assert!(error < 1e-13, "{error:e}");
        assert_ne!(state.t, 0.2, "the energy equation chose the steps");
    })
    .join()
    .expect("no stack overflow, no panic");
}
