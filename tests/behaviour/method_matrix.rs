//! One way in: every method family as a [`Scheme`] value on one
//! [`Problem`], through one [`Stepper`], one [`Plan`] and one [`Solution`],
//! with the system's size known at compile time and at run time.
//!
//! Each row is one method on the double pendulum (non-separable: every
//! method solves its step by Newton; the time-transformed ones with the
//! curvature monitor), and the explicit time-transformed splitting on
//! Kepler (e = 0.5), which needs a separable system; each column is one
//! workflow, for `Problem` at a compile-time `N` and at a run-time size:
//! - `land`: 100 targets reached exactly (the node's time is the target's
//!   bits); at run time also the agreement with the compile-time run;
//! - `solve`: nodes every 5 steps, 7 save times by dense output, a `Record`
//!   event (`q₀ = 0`) and a `Stop` event (`t = 1.7`); the saved values and
//!   the event time are checked against a reference to the method's
//!   accuracy, the run ends on the stop time with the stepper there;
//! - `files`: the solution written as CSV and JSON and read back bit for bit.
//!
//! At run time `solve` and `files` are the same checks, and the rows are
//! also those of the compile-time solution to round-off (the same times and
//! nodes, the values within `1e-10`).
//!
//! A cell that is not defined is the typed refusal of
//! `lagrangian::problem::supports`, checked to be exactly that text (the
//! capability page lists them). `cargo test --test behaviour method_matrix
//! -- --nocapture` prints the matrix with each cell's checked number.

use super::run_time_systems::{Kepler, KeplerDyn, PENDULUM, PENDULUM_DYN};
use crate::common::schemes::families;
use lagrangian::prelude::*;
use lagrangian::problem::supports;
use lagrangian::{Action, Status};

const Q0: [f64; 2] = [1.0, -0.5];
const V0: [f64; 2] = [0.0, 0.3];
const T_STOP: f64 = 1.7;
const T_END: f64 = 2.0;
const SAVE: [f64; 7] = [0.0, 0.1234, 0.5, 0.77, 1.0, 1.333, 1.6];

/// Kepler e = 0.5 from pericentre.
const KEPLER_Q0: [f64; 2] = [0.5, 0.0];
const KEPLER_V0: [f64; 2] = [0.0, 1.732_050_807_568_877_2];

/// A reference run: the save rows and the crossings of `q₀ = 0` up to the
/// stop time.
struct Reference {
    rows: Vec<[f64; 2]>,
    crossings: Vec<f64>,
}

/// The reference: Galerkin s = 6 (order 12) at h = 0.01.
fn reference<S: Lagrangian<2> + Clone>(system: S, q0: [f64; 2], v0: [f64; 2]) -> Reference {
    let mut sim = GalerkinIntegrator::new(system, Galerkin::<6, 6>::gauss(), 0.01).start(0.0, q0, v0).unwrap();
    let plan = Plan::until(T_STOP).every(0).save_at(SAVE.to_vec()).event(Event::new(|_, q, _| q[0]));
    let sol = sim.solve(plan).unwrap();
    let rows = (0..sol.len()).filter(|&i| sol.step[i].is_none()).map(|i| sol.q.array(i).unwrap()).collect();
    Reference { rows, crossings: sol.events.iter().map(|e| e.t).collect() }
}

/// What a row of the matrix checked.
struct Row {
    name: &'static str,
    land: String,
    solve: String,
    files: String,
    /// The solution of the `solve` column.
    solution: Solution,
}

/// Runs the three columns for one method, `start` giving a fresh integrator
/// at `(0, Q0, V0)`; `tolerance` bounds the dense output's error (and the
/// event time's) against the reference.
fn row<I: Stepping<2> + Clone>(
    name: &'static str,
    reference: &Reference,
    start: impl Fn() -> I,
    tolerance: f64,
) -> Row {
    // Land on 100 targets, not on the step grid.
    let mut sim = start();
    for i in 1..=100 {
        let target = T_END * f64::from(i) / 100.0 * (1.0 - 1e-3 / std::f64::consts::PI);
        sim.land(target).unwrap();
        assert_eq!(sim.state().t.to_bits(), target.to_bits(), "{name}: target {i}");
    }
    let land = format!("100/100 exact, {} steps", sim.stats().steps);
    let mut sim = start();
    let (solve, files, solution) = solve_cells(name, reference, tolerance, |plan| {
        let sol = sim.solve(plan).unwrap();
        (sol, sim.state().t, sim.state().q.to_vec())
    });
    Row { name, land, solve, files, solution }
}

/// The `solve` and `files` cells of one method at either size: `solve`
/// runs the plan and returns the solution and where its stepper ended
/// (`t`, `q`). Returns the two cells and the solution.
fn solve_cells(
    name: &str,
    reference: &Reference,
    tolerance: f64,
    solve: impl FnOnce(Plan<'static>) -> (Solution, f64, Vec<f64>),
) -> (String, String, Solution) {
    // Solve with thinning, save times, a record and a stop event.
    let Reference { rows: reference, crossings } = reference;
    let plan = Plan::until(T_END)
        .every(5)
        .save_at(SAVE.to_vec())
        .event(Event::new(|_, q, _| q[0]))
        .event(Event::new(|t, _, _| t - T_STOP).action(Action::Stop));
    let (sol, t_sim, q_sim) = solve(plan);
    assert!(matches!(sol.status, Status::Stopped { event: 1, .. }), "{name}: {:?}", sol.status);
    let end = *sol.t.last().unwrap();
    assert!((end - T_STOP).abs() <= 1e-13, "{name}: the stop event ends the run ({end})");
    assert_eq!(t_sim, end, "{name}: the integrator is at the stop");
    assert_eq!(sol.q.last().unwrap(), &q_sim[..], "{name}: the last row is its node");
    let saved: Vec<usize> = (0..sol.len()).filter(|&i| sol.step[i].is_none()).collect();
    assert_eq!(saved.iter().map(|&i| sol.t[i]).collect::<Vec<_>>(), SAVE, "{name}: save times");
    let nodes: Vec<u64> = sol.step.iter().flatten().copied().collect();
    assert!(nodes[..nodes.len() - 1].iter().all(|k| k % 5 == 0), "{name}: every 5th node and the last: {nodes:?}");
    let dense_error = saved
        .iter()
        .zip(reference)
        .flat_map(|(&i, r)| {
            let q = &sol.q[i];
            (0..2).map(move |j| (q[j] - r[j]).abs())
        })
        .fold(0.0, f64::max);
    assert!(dense_error <= tolerance, "{name}: dense output error {dense_error:e} > {tolerance:e}");
    let records: Vec<f64> = sol.events.iter().filter(|e| e.event == 0).map(|e| e.t).collect();
    assert_eq!(records.len(), crossings.len(), "{name}: the crossings of q₀ = 0 before the stop");
    let event_error = records.iter().zip(crossings).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
    assert!(event_error <= tolerance, "{name}: event time error {event_error:e}");
    assert_eq!(sol.events.last().unwrap().event, 1, "{name}: the stop is recorded last");
    let solve = format!("dense {dense_error:.0e}, event {event_error:.0e}, {} rows", sol.len());

    // CSV and JSON, bit for bit.
    let bits = |s: &Solution| {
        let rows = |a: &Rows| a.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
        let t: Vec<u64> = s.t.iter().map(|x| x.to_bits()).collect();
        let e: Vec<u64> = s.energy.iter().map(|x| x.to_bits()).collect();
        (t, s.step.clone(), rows(&s.q), rows(&s.p), rows(&s.v), e)
    };
    let mut csv = Vec::new();
    sol.write_csv(&mut csv).unwrap();
    assert_eq!(bits(&Solution::read_csv(csv.as_slice()).unwrap()), bits(&sol), "{name}: csv");
    let mut json = Vec::new();
    sol.write_json(&mut json).unwrap();
    let back = Solution::read_json(json.as_slice()).unwrap();
    assert_eq!(bits(&back), bits(&sol), "{name}: json");
    assert_eq!(back.events, sol.events, "{name}: json events");
    let files = format!("csv {} B, json {} B", csv.len(), json.len());
    (solve, files, sol)
}

/// Step size and dense-output tolerance of each family, in the order of
/// [`families`].
const STEPS: [(f64, f64); 14] = [
    (0.005, 2e-4),
    (0.005, 1e-3),
    (0.005, 2e-4),
    (0.02, 2e-5),
    (0.02, 1e-7),
    (0.02, 1e-8),
    (0.01, 2e-4),
    (0.02, 2e-5),
    (0.04, 1e-5),
    (0.03, 3e-4),
    (0.1, 2e-5),
    (0.05, 2e-7),
    (0.02, 2e-5),
    (0.02, 5e-5),
];

/// The run-time-sized cells of one family: landing on the same 100 targets
/// as the compile-time run (agreeing with its final `q` to `1e-10`), and
/// `solve` and the files as at compile time, with the rows of the
/// compile-time solution `compiled_rows` to round-off; or, for a family the
/// run-time driver does not have, its refusal in every cell.
fn dynamic_row<S: DynLagrangian + Clone>(
    problem: &Problem<S, Dyn>,
    (scheme, h, tolerance): (&Scheme, f64, f64),
    reference: &Reference,
    compiled: [f64; 2],
    compiled_rows: &Row,
) -> [String; 3] {
    let refusal = |e: Error| {
        let Error::Unsupported { what } = e else { panic!("not a typed refusal: {e}") };
        format!("refused: {what}")
    };
    let mut sim = match problem.stepper(scheme, h) {
        Ok(sim) => sim,
        Err(e) => {
            let text = refusal(e);
            return [text.clone(), text.clone(), text];
        }
    };
    for i in 1..=100 {
        let target = T_END * f64::from(i) / 100.0 * (1.0 - 1e-3 / std::f64::consts::PI);
        sim.run_until(target).unwrap();
        assert_eq!(sim.state().t.to_bits(), target.to_bits(), "run-time target {i}");
    }
    let gap = (0..2).map(|j| (sim.state().q[j] - compiled[j]).abs()).fold(0.0, f64::max);
    assert!(gap <= 1e-10, "run-time and compile-time runs differ by {gap:e}");
    let land = format!("100/100 exact, {} steps, Δq {gap:.0e} to compile-time", sim.stats().steps);
    let name = compiled_rows.name;
    let mut sim = problem.stepper(scheme, h).unwrap();
    let (solve, files, sol) = solve_cells(name, reference, tolerance, |plan| {
        let sol = sim.solve(plan).unwrap();
        (sol, sim.state().t, sim.state().q.clone())
    });
    // The rows of the compile-time solution: the same nodes and times, the
    // values to round-off.
    let compiled = &compiled_rows.solution;
    assert_eq!((sol.width(), &sol.step), (2, &compiled.step), "{name}: the same rows at both sizes");
    let gap = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
    let times = gap(&sol.t, &compiled.t);
    let values = [(&sol.q, &compiled.q), (&sol.p, &compiled.p), (&sol.v, &compiled.v)]
        .iter()
        .map(|(a, b)| gap(a.as_flat(), b.as_flat()))
        .fold(0.0, f64::max);
    assert!(times <= 1e-13 && values <= 1e-10, "{name}: rows differ from compile-time by {times:e} (t), {values:e}");
    [land, format!("{solve}, Δ {values:.0e} to compile-time"), files]
}

#[test]
fn every_method_through_one_problem() {
    let references = [reference(PENDULUM, Q0, V0), reference(Kepler, KEPLER_Q0, KEPLER_V0)];
    let pendulum = Problem::new(PENDULUM, 0.0, Q0, V0);
    let kepler = Problem::new(Kepler, 0.0, KEPLER_Q0, KEPLER_V0);
    let pendulum_dyn = Problem::new(PENDULUM_DYN, 0.0, Q0.to_vec(), V0.to_vec());
    let kepler_dyn = Problem::new(KeplerDyn, 0.0, KEPLER_Q0.to_vec(), KEPLER_V0.to_vec());
    let mut table = Vec::new();
    for ((name, scheme, separable), (h, tolerance)) in families().into_iter().zip(STEPS) {
        let (compiled, last_q) = if separable {
            let r = row(name, &references[1], || kepler.stepper(&scheme, h).unwrap(), tolerance);
            let mut sim = kepler.stepper(&scheme, h).unwrap();
            (r, land_all(&mut sim))
        } else {
            let r = row(name, &references[0], || pendulum.stepper(&scheme, h).unwrap(), tolerance);
            let mut sim = pendulum.stepper(&scheme, h).unwrap();
            (r, land_all(&mut sim))
        };
        let runtime = if separable {
            dynamic_row(&kepler_dyn, (&scheme, h, tolerance), &references[1], last_q, &compiled)
        } else {
            dynamic_row(&pendulum_dyn, (&scheme, h, tolerance), &references[0], last_q, &compiled)
        };
        table.push((compiled, runtime));
    }
    println!("{:<36} | {:<26} | {:<34} | {:<26} | run-time N", "method", "land", "solve", "files");
    for (r, d) in &table {
        let runtime =
            if d[0] == d[1] { "refused (every cell)".to_string() } else { format!("{}; {}; {}", d[0], d[1], d[2]) };
        println!("{:<36} | {:<26} | {:<34} | {:<26} | {runtime}", r.name, r.land, r.solve, r.files);
    }
    // What the run-time-sized drivers have: every family steps, lands and
    // solves (the one-point rules, the Galerkin rules, the compositions of
    // trapezoid, midpoint and Galerkin sub-steps, the implicit time
    // transformation and the explicit splitting); a refusal would carry
    // exactly the text of `supports`.
    let stepping: Vec<bool> = table.iter().map(|(_, d)| !d[0].starts_with("refused")).collect();
    assert_eq!(stepping, [true; 14]);
    for ((_, scheme, _), (_, d)) in families().iter().zip(&table) {
        let query = |capability| lagrangian::problem::Combination {
            scheme,
            policy: Policy::fixed(0.01),
            size: lagrangian::problem::Size::Dynamic,
            forced: false,
            constraints: 0,
            capability,
        };
        match supports(&query(Capability::Solve)) {
            Err(solve) => assert_eq!(d[1], format!("refused: {solve}")),
            Ok(()) => assert!(!d[1].starts_with("refused") && !d[2].starts_with("refused")),
        }
        if let Err(step) = supports(&query(Capability::Step)) {
            assert_eq!(d[0], format!("refused: {step}"));
        }
    }
}

/// The damped oscillator of `common::forced` (`m = k = 1`, `c = 0.1`) with
/// its size known at run time.
#[derive(Clone)]
struct DampedDyn;

#[lagrangian]
impl DampedDyn {
    fn dimension(&self) -> usize {
        1
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        0.5 * v[0] * v[0] - 0.5 * q[0] * q[0]
    }

    fn dissipation(&self, _q: &[f64], v: &[f64]) -> f64 {
        0.05 * v[0] * v[0]
    }
}

/// The forced run-time-sized cells: every family that steps at run-time
/// size steps and solves a damped oscillator (against its analytic
/// solution, and the same oscillator at compile-time size to round-off);
/// the others are refused with exactly the text of `supports`.
#[test]
fn forced_run_time_cells() {
    use crate::common::forced::DampedOscillator;
    let oscillator = DampedOscillator { m: 1.0, k: 1.0, c: 0.1 };
    let dynamic = Problem::new(DampedDyn, 0.0, vec![1.0], vec![0.0]);
    let compiled = Problem::new(DampedOscillator { m: 1.0, k: 1.0, c: 0.1 }, 0.0, [1.0], [0.0]);
    let (h, t_end) = (0.01, 4.0);
    let mut stepping = Vec::new();
    for (name, scheme, _) in families() {
        let query = lagrangian::problem::Combination {
            scheme: &scheme,
            policy: Policy::fixed(h),
            size: lagrangian::problem::Size::Dynamic,
            forced: true,
            constraints: 0,
            capability: Capability::Solve,
        };
        let mut sim = match dynamic.stepper(&scheme, h) {
            Ok(sim) => sim,
            Err(Error::Unsupported { what }) => {
                assert_eq!(supports(&query), Err(what), "{name}");
                stepping.push(false);
                continue;
            }
            Err(e) => panic!("{name}: not a typed refusal: {e}"),
        };
        assert_eq!(supports(&query), Ok(()), "{name}");
        let sol = sim.solve(Plan::until(t_end).every(10)).unwrap().into_result().unwrap();
        let exact = oscillator.exact(1.0, t_end);
        let (q, v) = (sol.q.last().unwrap()[0], sol.v.last().unwrap()[0]);
        assert!((q - exact[0]).abs() < 1e-4 && (v - exact[1]).abs() < 1e-4, "{name}: {q} {v} against {exact:?}");
        let mut reference = compiled.stepper(&scheme, h).unwrap();
        reference.run_until(t_end).unwrap();
        let gap = (q - reference.state().q[0]).abs().max((sol.p.last().unwrap()[0] - reference.state().p[0]).abs());
        assert!(gap < 1e-13, "{name}: {gap:e} from the compile-time size");
        println!("{name:<36} | forced, run-time N: Δq {:.0e} to exact, {gap:.0e} to compile-time", q - exact[0]);
        stepping.push(true);
    }
    // Forced at run-time size: every family but the splitting (separable,
    // unforced systems).
    let expected = [true, true, true, true, true, true, true, true, true, true, true, false, true, true];
    assert_eq!(stepping, expected);
}

/// Lands on the 100 targets of the matrix and returns the final `q`.
fn land_all<I: Stepping<2>>(sim: &mut I) -> [f64; 2] {
    for i in 1..=100 {
        sim.land(T_END * f64::from(i) / 100.0 * (1.0 - 1e-3 / std::f64::consts::PI)).unwrap();
    }
    sim.state().q
}
