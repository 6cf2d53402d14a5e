//! `solve` after a failure: the integrator is at the solution's last node
//! row, bit-identical to one that took the same good steps, for a one-point
//! rule and a Galerkin integrator.
#![allow(missing_docs)]

use lagrangian_runtime::galerkin::{Galerkin, GalerkinIntegrator};
use lagrangian_runtime::solution::{Plan, Stepping};
use lagrangian_runtime::{Action, Event, Integrator, Lagrangian, Midpoint, Scalar, SolveError, Status};

#[derive(Clone)]
struct Oscillator;
impl Lagrangian<1> for Oscillator {
    const AUTONOMOUS: bool = true;
    const CYCLIC: [bool; 1] = [false];
    fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 1], v: [D; 1]) -> D {
        (v[0] * v[0] - q[0] * q[0]) * 0.5
    }
}

/// An event function that is fine up to t = 1 and NaN after it.
fn nan_after_one<'a>() -> Event<'a> {
    Event::new(|t, q: &[f64], _| if t > 1.0 { f64::NAN } else { q[0] - 2.0 })
}

/// Asserts that `sim` failed on the first step past t = 1 and is at the
/// solution's last row, a node, in the same state as `reference` after as
/// many steps (the next step of both agrees to the bit).
macro_rules! assert_left_at_last_node {
    ($sim:expr, $reference:expr, $solution:expr) => {{
        let (sim, mut reference, solution) = ($sim, $reference, $solution);
        assert!(matches!(solution.status, Status::Failed { .. }), "{:?}", solution.status);
        assert!(matches!(solution.error, Some(SolveError::NonFiniteEvent { event: 0, .. })), "{:?}", solution.error);
        let state = *sim.state();
        assert_eq!(solution.t.last(), Some(&state.t));
        assert_eq!(solution.step.last(), Some(&Some(state.step)));
        assert!(state.t <= 1.0 && state.t > 0.99, "{state:?}");
        reference.run(state.step as usize, |_| {}).unwrap();
        assert_eq!(*reference.state(), state);
        let (mut a, mut b) = (sim.clone(), reference.clone());
        assert_eq!(a.step().unwrap(), b.step().unwrap());
    }};
}

#[test]
fn a_non_finite_event_leaves_a_one_point_rule_at_the_last_node() {
    let build = || Integrator::new(Oscillator, Midpoint, 0.01).start(0.0, [1.0], [0.0]).unwrap();
    let mut sim = build();
    let solution = sim.solve(Plan::until(2.0).event(nan_after_one())).unwrap();
    assert_left_at_last_node!(&sim, build(), &solution);
    assert_eq!(solution.len(), 101);
}

#[test]
fn a_non_finite_event_leaves_a_galerkin_integrator_at_the_last_node() {
    let build =
        || GalerkinIntegrator::new(Oscillator, Galerkin::<3, 3>::gauss(), 0.01).start(0.0, [1.0], [0.0]).unwrap();
    let mut sim = build();
    let solution = sim.solve(Plan::until(2.0).event(nan_after_one())).unwrap();
    assert_left_at_last_node!(&sim, build(), &solution);
}

/// Between the nodes `every` keeps, the last good node becomes a row; the
/// save times and events of the undone step are dropped.
#[test]
fn the_last_good_node_is_kept_between_every_nth_node() {
    let build = || Integrator::new(Oscillator, Midpoint, 0.01).start(0.0, [1.0], [0.0]).unwrap();
    let mut sim = build();
    // q ≈ cos t crosses 0.5361 near t = 1.005, inside the step that fails.
    let record = Event::new(|_, q: &[f64], _| q[0] - 0.5361);
    let plan = Plan::until(2.0).every(7).save_at(vec![0.5, 1.005, 1.5]).event(nan_after_one()).event(record);
    let solution = sim.solve(plan).unwrap();
    assert_left_at_last_node!(&sim, build(), &solution);
    assert_eq!(solution.step.iter().filter(|k| k.is_some()).count(), 1 + 100 / 7 + 1);
    assert_eq!(solution.t.iter().filter(|&&t| t == 0.5).count(), 1);
    assert!(solution.t.iter().all(|&t| t <= 1.0), "{:?}", solution.t);
    assert!(solution.events.iter().all(|e| e.t <= 1.0), "{:?}", solution.events);
    assert_eq!(solution.v.len(), solution.len());
}

/// A stop event located inside a step, then an event function that fails
/// only at the node the step is redone to: the landing is undone too.
#[test]
fn a_failure_after_a_stop_landing_leaves_the_step_start() {
    let build = || Integrator::new(Oscillator, Midpoint, 0.01).start(0.0, [1.0], [0.0]).unwrap();
    let mut sim = build();
    // q ≈ cos t = 0.5361 near t = 1.005: stop there.
    let stop = Event::new(|_, q: &[f64], _| q[0] - 0.5361).action(Action::Stop);
    let window = Event::new(|t, _: &[f64], _| if t > 1.003 && t < 1.007 { f64::NAN } else { 1.0 });
    let solution = sim.solve(Plan::until(2.0).event(stop).event(window)).unwrap();
    assert!(matches!(solution.error, Some(SolveError::NonFiniteEvent { event: 1, .. })), "{:?}", solution.error);
    let state = *sim.state();
    assert_eq!(solution.t.last(), Some(&state.t));
    assert_eq!(solution.step.last(), Some(&Some(state.step)));
    assert_eq!(state.step, 100);
    // The step was redone to the event (and then undone with the record).
    assert_eq!(solution.stats.redone_steps, 1);
    assert!(solution.events.is_empty(), "{:?}", solution.events);
    let mut reference = build();
    reference.run(100, |_| {}).unwrap();
    assert_eq!(*reference.state(), state);
}

/// Two identical stop events (and a recording one at the same time) are
/// all recorded; the run stops at their time, named by the first.
#[test]
fn identical_stop_events_each_get_their_record() {
    let mut sim = Integrator::new(Oscillator, Midpoint, 0.01).start(0.0, [1.0], [0.0]).unwrap();
    let zero = || Event::new(|_, q: &[f64], _| q[0]);
    let plan = Plan::until(10.0).event(zero().action(Action::Stop)).event(zero().action(Action::Stop)).event(zero());
    let solution = sim.solve(plan).unwrap();
    let t = solution.events[0].t;
    assert!((t - std::f64::consts::FRAC_PI_2).abs() < 1e-4, "{t}");
    assert_eq!(solution.events.iter().map(|e| e.event).collect::<Vec<_>>(), [0, 1, 2]);
    assert!(solution.events.iter().all(|e| e.t == t), "{:?}", solution.events);
    assert_eq!(solution.status, Status::Stopped { event: 0, t });
    assert_eq!(sim.state().t, t);
}
