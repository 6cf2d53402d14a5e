//! Events located on dense output: pendulum zero crossings against the exact
//! times (a quarter period and every half period after it, the period from
//! the arithmetic–geometric mean), terminal events, landing, bad input.

use crate::common::galerkin_reference;

use galerkin_reference::pendulum_period;
use lagrangian::prelude::*;
use lagrangian::{Action, DenseKind, Direction, Event, Plan, SolveError, Status};

#[derive(Clone)]
struct Pendulum {
    omega2: f64,
}

#[lagrangian]
impl Pendulum {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] + self.omega2 * q[0].cos()
    }
}

const OMEGA2: f64 = 9.81;
const THETA0: f64 = 1.0;

fn period() -> f64 {
    pendulum_period(OMEGA2.sqrt(), THETA0)
}

fn galerkin(h: f64) -> GalerkinIntegrator<Pendulum, 1, 4, 4> {
    GalerkinIntegrator::new(Pendulum { omega2: OMEGA2 }, Galerkin::<4, 4>::gauss(), h)
        .start(0.0, [THETA0], [0.0])
        .unwrap()
}

/// Every zero of θ over ten periods within 1e-12 of `(2k + 1) T / 4`.
#[test]
fn pendulum_zero_crossings_match_the_exact_times() {
    let t = period();
    let mut sim = galerkin(0.01);
    let plan = Plan::until(10.0 * t).every(0).dense(DenseKind::Quintic).event(Event::new(|_, q, _| q[0]));
    let sol = sim.solve(plan).unwrap();
    assert!(sol.is_finished());
    assert_eq!(sol.events.len(), 20);
    let mut worst: f64 = 0.0;
    for (k, e) in sol.events.iter().enumerate() {
        let exact = (2 * k + 1) as f64 * t / 4.0;
        worst = worst.max((e.t - exact).abs());
        assert!((e.t - exact).abs() < 1e-12, "crossing {k}: {} against {exact}", e.t);
        assert_eq!(e.rising, k % 2 == 1);
        assert!(e.q[0].abs() < 1e-11);
    }
    println!("largest error of 20 crossings: {worst:.2e} (T = {t})");
    // Direction filters keep every other one.
    let mut sim = galerkin(0.01);
    let plan = Plan::until(10.0 * t)
        .every(0)
        .dense(DenseKind::Quintic)
        .event(Event::new(|_, q, _| q[0]).direction(Direction::Rising));
    let rising = sim.solve(plan).unwrap();
    assert_eq!(rising.events.len(), 10);
    assert!(rising.events.iter().zip(sol.events.iter().skip(1).step_by(2)).all(|(a, b)| a.t == b.t));
}

/// A terminal event ends the run with the integrator at a node on the event
/// time; continuing from there finds the next crossing as accurately.
#[test]
fn a_terminal_event_stops_exactly_at_the_crossing() {
    let t = period();
    let mut sim = galerkin(0.01);
    let stop = |sim: &mut GalerkinIntegrator<Pendulum, 1, 4, 4>| {
        let plan = Plan::until(100.0).dense(DenseKind::Quintic).event(Event::new(|_, q, _| q[0]).action(Action::Stop));
        sim.solve(plan).unwrap()
    };
    let sol = stop(&mut sim);
    let first = &sol.events[0];
    assert_eq!(sol.status, Status::Stopped { event: 0, t: first.t });
    assert_eq!(sim.state().t, first.t);
    assert_eq!(*sol.t.last().unwrap(), first.t);
    assert!((first.t - t / 4.0).abs() < 1e-12, "{} against {}", first.t, t / 4.0);
    // The node at the event is the integrator's own: θ is zero there to the
    // local error of the shortened step.
    assert!(sim.state().q[0].abs() < 1e-12, "{}", sim.state().q[0]);
    assert_eq!(sol.stats.redone_steps, 1);
    let next = stop(&mut sim);
    assert!((next.events[0].t - 0.75 * t).abs() < 1e-12, "{} against {}", next.events[0].t, 0.75 * t);
    assert!(next.events[0].rising);
}

/// Landing puts a node on each event and keeps the fixed-step grid.
#[test]
fn landing_puts_nodes_on_events_and_keeps_the_grid() {
    let t = period();
    let h = 0.01;
    let mut sim = galerkin(h);
    let plan = Plan::until(2.0 * t).dense(DenseKind::Quintic).event(Event::new(|_, q, _| q[0]).action(Action::Land));
    let sol = sim.solve(plan).unwrap();
    assert!(sol.is_finished());
    assert_eq!(sol.events.len(), 4);
    for e in &sol.events {
        assert!(sol.t.contains(&e.t), "no node at {}", e.t);
    }
    // Every other node is on the grid k h.
    let off_grid: Vec<f64> =
        sol.t.iter().copied().filter(|&s| (s / h - (s / h).round()).abs() > 1e-9 && s != 2.0 * t).collect();
    assert_eq!(off_grid, sol.events.iter().map(|e| e.t).collect::<Vec<_>>());
    assert_eq!(sol.stats.redone_steps, 4);
}

/// The midpoint rule with its cubic Hermite: events at the accuracy of the
/// method (order 2), and the same crossings whether recorded or landed.
#[test]
fn midpoint_events_have_the_methods_accuracy() {
    let t = period();
    let mut errors = Vec::new();
    for h in [0.01, 0.005] {
        let mut sim = Integrator::new(Pendulum { omega2: OMEGA2 }, Midpoint, h).start(0.0, [THETA0], [0.0]).unwrap();
        let sol = sim.solve(Plan::until(t).every(0).event(Event::new(|_, q, _| q[0]))).unwrap();
        assert_eq!(sol.events.len(), 2);
        errors.push((sol.events[1].t - 0.75 * t).abs());
    }
    let order = (errors[0] / errors[1]).log2();
    assert!((order - 2.0).abs() < 0.1, "{errors:?}: order {order}");
}

#[test]
fn bad_event_input_is_a_typed_error() {
    // g becomes NaN once θ < 0.5: the run ends there, with what it had.
    let mut sim = galerkin(0.01);
    let plan = Plan::until(1.0).event(Event::new(|_, q, _| if q[0] < 0.5 { f64::NAN } else { q[0] }));
    let sol = sim.solve(plan).unwrap();
    assert!(matches!(sol.error, Some(SolveError::NonFiniteEvent { event: 0, .. })), "{:?}", sol.error);
    assert!(matches!(sol.status, Status::Failed { .. }));
    assert!(!sol.is_empty() && sol.t.last().unwrap() < &1.0);
    let failed = sol.clone().into_result().unwrap_err();
    assert_eq!(failed.solution.len(), sol.len());
    // Bad tolerances and sample counts are refused before anything runs.
    let mut sim = galerkin(0.01);
    let plan = Plan::until(1.0).event(Event::new(|_, q, _| q[0]).tolerance(0.0));
    assert!(matches!(sim.solve(plan), Err(SolveError::InvalidEvent { event: 0, .. })));
    let plan = Plan::until(1.0).event(Event::new(|_, q, _| q[0])).event(Event::new(|_, q, _| q[0]).samples(0));
    assert!(matches!(sim.solve(plan), Err(SolveError::InvalidEvent { event: 1, .. })));
    assert_eq!(sim.state().step, 0);
}
