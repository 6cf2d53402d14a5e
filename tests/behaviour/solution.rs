//! The solution object: its rows equal the observer's trajectory (bit for
//! bit, node 0 included), thinning and save times, a failure mid-run keeps
//! the partial solution, bad plans are typed errors, CSV and JSON round-trip.

use super::run_time_systems::{DoublePendulum, PENDULUM};
use lagrangian::prelude::*;
use lagrangian::{DenseKind, Event, Plan, Solution, SolveError, Status};

/// `V = √q` pulls towards q = 0, reached from rest at q = 1 in finite time
/// (t = 4√2/3 ≈ 1.886, by energy); beyond it `L` is not defined and steps fail.
#[derive(Clone)]
struct Collapse;

#[lagrangian]
impl Collapse {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] - q[0].sqrt()
    }
}

fn midpoint() -> Integrator<DoublePendulum, Midpoint, 2> {
    Integrator::new(PENDULUM, Midpoint, 0.01).start(0.0, [1.0, -0.5], [0.0, 0.3]).unwrap()
}

/// `solve` with every node kept against `run_until` with an observer.
#[test]
fn rows_equal_the_observers_trajectory() {
    let mut reference = midpoint();
    let mut rows = vec![(reference.state().t, reference.state().q, reference.state().p, reference.velocity().unwrap())];
    reference.run_until(3.005, |s| rows.push((s.state().t, s.state().q, s.state().p, s.velocity().unwrap()))).unwrap();
    let mut sim = midpoint();
    let sol = sim.solve(Plan::until(3.005)).unwrap();
    assert!(sol.is_finished());
    assert_eq!(sol.len(), rows.len());
    assert_eq!(sol.len(), 302);
    for (i, (t, q, p, v)) in rows.iter().enumerate() {
        assert_eq!((sol.t[i], &sol.q[i], &sol.p[i], &sol.v[i]), (*t, &q[..], &p[..], &v[..]), "row {i}");
        assert_eq!(sol.step[i], Some(i as u64));
        assert_eq!(sol.energy[i], PENDULUM.energy(*t, *q, *v));
    }
    assert_eq!(sim.state(), reference.state());
    assert_eq!(sol.stats.steps, 301);
    assert_eq!(sol.stats.newton_iterations, reference.stats().newton_iterations);

    // The same for Galerkin.
    let start = || {
        GalerkinIntegrator::new(PENDULUM, Galerkin::<3, 3>::gauss(), 0.05).start(0.0, [1.0, -0.5], [0.0, 0.3]).unwrap()
    };
    let mut reference = start();
    let mut rows = vec![(reference.state().t, reference.state().q, reference.state().p)];
    reference.run_until(2.0, |s| rows.push((s.state().t, s.state().q, s.state().p))).unwrap();
    let sol = start().solve(Plan::until(2.0).without_velocities()).unwrap();
    assert!(sol.v.is_empty() && sol.energy.is_empty());
    assert_eq!(sol.stats.velocity_solves, 0);
    let got: Vec<_> = (0..sol.len()).map(|i| (sol.t[i], sol.q.array(i).unwrap(), sol.p.array(i).unwrap())).collect();
    assert_eq!(got, rows);
}

#[test]
fn every_n_and_save_times() {
    let mut sim = midpoint();
    let times = vec![0.0, 0.013, 0.5, 0.995, 1.0];
    let mut observed = Vec::new();
    let plan = Plan::until(1.0).every(30).save_at(times.clone()).observe_every(25, |n| observed.push(n.t));
    let sol = sim.solve(plan).unwrap();
    // Nodes 0, 30, 60, 90 and the last (100); the five save times.
    let nodes: Vec<u64> = sol.step.iter().flatten().copied().collect();
    assert_eq!(nodes, vec![0, 30, 60, 90, 100]);
    let saved: Vec<f64> = sol.t.iter().zip(&sol.step).filter(|(_, s)| s.is_none()).map(|(t, _)| *t).collect();
    assert_eq!(saved, times);
    assert!(sol.t.windows(2).all(|w| w[0] <= w[1]), "rows in time order");
    assert_eq!(observed.len(), 5);
    assert!((observed[1] - 0.25).abs() < 1e-12);
    // A save time on a node reads the node (the interpolant passes through it).
    let at_half = sol.t.iter().position(|&t| t == 0.5).unwrap();
    let mut reference = midpoint();
    reference.run_until(0.5, |_| {}).unwrap();
    assert!((sol.q[at_half][0] - reference.state().q[0]).abs() < 1e-15);
    // Interpolated momenta are ∂L/∂v of the interpolated state.
    let i = sol.t.iter().position(|&t| t == 0.013).unwrap();
    let p = PENDULUM.momentum(sol.t[i], sol.q.array(i).unwrap(), sol.v.array(i).unwrap());
    assert_eq!(sol.p[i], p);
}

#[test]
fn bad_plans_are_refused_before_running() {
    let mut sim = midpoint();
    type Case<'a> = (Plan<'a>, fn(&SolveError) -> bool);
    let cases: Vec<Case<'_>> = vec![
        (Plan::until(f64::NAN), |e| matches!(e, SolveError::InvalidEnd { .. })),
        (Plan::until(-1.0), |e| matches!(e, SolveError::InvalidEnd { .. })),
        (Plan::until(1.0).save_at(vec![0.5, 0.2]), |e| matches!(e, SolveError::InvalidSaveTime { index: 1, .. })),
        (Plan::until(1.0).save_at(vec![0.5, 1.5]), |e| matches!(e, SolveError::InvalidSaveTime { index: 1, .. })),
        (Plan::until(1.0).save_at(vec![-0.1]), |e| matches!(e, SolveError::InvalidSaveTime { index: 0, .. })),
        (Plan::until(1.0).save_at(vec![f64::NAN]), |e| matches!(e, SolveError::InvalidSaveTime { index: 0, .. })),
        (Plan::until(1.0).observe_every(0, |_| {}), |e| matches!(e, SolveError::InvalidPlan { .. })),
        (Plan::until(1.0).energy_tolerance(-1.0), |e| matches!(e, SolveError::InvalidPlan { .. })),
    ];
    for (plan, expected) in cases {
        let text = format!("{plan:?}");
        let err = sim.solve(plan).unwrap_err();
        assert!(expected(&err), "{text}: {err}");
    }
    assert_eq!(sim.state().step, 0, "nothing ran");
    // The end equal to the current time is an empty run with one row.
    let sol = sim.solve(Plan::until(0.0)).unwrap();
    assert_eq!((sol.len(), sol.status.clone()), (1, Status::Finished));
}

/// A step that fails mid-run: the partial solution, the typed error, the
/// integrator at the last row.
#[test]
fn a_failure_mid_run_keeps_the_partial_solution() {
    let mut sim = Integrator::new(Collapse, Midpoint, 0.01).start(0.0, [1.0], [0.0]).unwrap();
    let sol = sim.solve(Plan::until(10.0).save_at(vec![0.5, 9.0])).unwrap();
    let Some(SolveError::Step(error)) = &sol.error else { panic!("{:?}", sol.status) };
    assert!(matches!(sol.status, Status::Failed { ref message } if *message == error.to_string()));
    let last = *sol.t.last().unwrap();
    assert!(last > 1.8 && last < 1.9, "{last}");
    assert_eq!(sim.state().t, last);
    assert_eq!(sol.q.last().unwrap(), &sim.state().q);
    assert!(sol.t.contains(&0.5) && !sol.t.contains(&9.0));
    println!("failed at t = {last}: {error}");
    let failed = sol.into_result().unwrap_err();
    assert!(failed.to_string().contains("partial solution ends at t"));
}

#[test]
fn the_energy_watch_warns_when_the_step_is_too_large() {
    // ωh ≈ 2.2 for the fast mode of the double pendulum: a warning.
    let mut coarse = Integrator::new(PENDULUM, Midpoint, 0.25).start(0.0, [1.0, -0.5], [0.0, 0.3]).unwrap();
    let sol = coarse.solve(Plan::until(20.0).every(0).energy_tolerance(1e-3)).unwrap();
    let watch = sol.energy_watch.unwrap();
    assert!(watch.exceeded_at.is_some() && watch.largest > 1e-3, "{watch:?}");
    assert!(sol.energy_warning().unwrap().contains("step size"));
    let mut fine = midpoint();
    let sol = fine.solve(Plan::until(20.0).every(0).energy_tolerance(1e-3)).unwrap();
    let watch = sol.energy_watch.unwrap();
    assert!(watch.exceeded_at.is_none() && watch.largest < 1e-3 && watch.largest > 0.0, "{watch:?}");
    assert_eq!(sol.energy_warning(), None);
}

#[test]
fn csv_and_json_round_trip() {
    let mut sim = midpoint();
    let plan = Plan::until(1.0)
        .every(7)
        .save_at(vec![0.123, 0.77])
        .dense(DenseKind::Quintic)
        .event(Event::new(|_, q, _| q[1]));
    let sol = sim.solve(plan).unwrap();
    assert!(!sol.events.is_empty());

    let mut csv = Vec::new();
    sol.write_csv(&mut csv).unwrap();
    let text = String::from_utf8(csv.clone()).unwrap();
    assert!(text.starts_with("t,step,q0,q1,p0,p1,v0,v1,energy\n0.0,0,1.0,-0.5,"), "{}", &text[..80]);
    let back = Solution::read_csv(csv.as_slice()).unwrap();
    assert_eq!(
        (&back.t, &back.step, &back.q, &back.p, &back.v, &back.energy),
        (&sol.t, &sol.step, &sol.q, &sol.p, &sol.v, &sol.energy)
    );
    assert_eq!(back.width(), 2, "the number of coordinates comes from the header");

    let mut json = Vec::new();
    sol.write_json(&mut json).unwrap();
    assert_eq!(Solution::read_json(json.as_slice()).unwrap(), sol);

    // Without velocities, and a failed run (whose typed error stays behind).
    let mut sim = Integrator::new(Collapse, Midpoint, 0.01).start(0.0, [1.0], [0.0]).unwrap();
    let sol = sim.solve(Plan::until(2.0).every(10).without_velocities()).unwrap();
    let mut csv = Vec::new();
    sol.write_csv(&mut csv).unwrap();
    let back = Solution::read_csv(csv.as_slice()).unwrap();
    assert_eq!((&back.t, &back.q, &back.p), (&sol.t, &sol.q, &sol.p));
    let mut json = Vec::new();
    sol.write_json(&mut json).unwrap();
    let back = Solution::read_json(json.as_slice()).unwrap();
    assert_eq!(back.status, sol.status);
    assert_eq!(back.error, None);
    assert_eq!(Solution { error: None, ..sol }, back);
}
