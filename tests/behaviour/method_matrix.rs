//! One way in: every method family through the same [`Stepping`] trait, the
//! same [`Plan`] and the same [`Solution`].
//!
//! Each row is one method on the double pendulum (non-separable: every
//! method solves its step by Newton; the time-transformed ones with the
//! curvature monitor), and the explicit time-transformed splitting on
//! Kepler (e = 0.5), which needs a separable system; each column is one
//! workflow:
//! - `land`: 100 targets reached exactly (the node's time is the target's bits);
//! - `solve`: nodes every 5 steps, 7 save times by dense output, a `Record`
//!   event (`q₀ = 0`) and a `Stop` event (`t = 1.7`); the saved values and
//!   the event time are checked against a reference to the method's
//!   accuracy, the run ends on the stop time with the integrator there;
//! - `files`: the solution written as CSV and JSON and read back bit for bit.
//!
//! `cargo test --test behaviour method_matrix -- --nocapture` prints the
//! matrix with each cell's checked number.

use lagrangian::prelude::*;
use lagrangian::{Action, Status};

#[derive(Clone)]
struct DoublePendulum;

#[lagrangian]
impl DoublePendulum {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let kinetic = v[0] * v[0] + 0.5 * v[1] * v[1] + v[0] * v[1] * (q[0] - q[1]).cos();
        kinetic + 2.0 * 9.81 * q[0].cos() + 9.81 * q[1].cos()
    }
}

const Q0: [f64; 2] = [1.0, -0.5];
const V0: [f64; 2] = [0.0, 0.3];
const T_STOP: f64 = 1.7;
const T_END: f64 = 2.0;
const SAVE: [f64; 7] = [0.0, 0.1234, 0.5, 0.77, 1.0, 1.333, 1.6];

/// Kepler, μ = 1: separable with a constant mass matrix, for the explicit
/// time-transformed splitting.
#[derive(Clone)]
struct Kepler;

#[lagrangian]
impl Kepler {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) + 1.0 / (q[0] * q[0] + q[1] * q[1]).sqrt()
    }
}

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
    let rows = (0..sol.len()).filter(|&i| sol.step[i].is_none()).map(|i| sol.q[i]).collect();
    Reference { rows, crossings: sol.events.iter().map(|e| e.t).collect() }
}

/// What a row of the matrix checked.
struct Row {
    name: &'static str,
    land: String,
    solve: String,
    files: String,
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

    // Solve with thinning, save times, a record and a stop event.
    let Reference { rows: reference, crossings } = reference;
    let mut sim = start();
    let plan = Plan::until(T_END)
        .every(5)
        .save_at(SAVE.to_vec())
        .event(Event::new(|_, q, _| q[0]))
        .event(Event::new(|t, _, _| t - T_STOP).action(Action::Stop));
    let sol = sim.solve(plan).unwrap();
    assert!(matches!(sol.status, Status::Stopped { event: 1, .. }), "{name}: {:?}", sol.status);
    let end = *sol.t.last().unwrap();
    assert!((end - T_STOP).abs() <= 1e-13, "{name}: the stop event ends the run ({end})");
    assert_eq!(sim.state().t, end, "{name}: the integrator is at the stop");
    assert_eq!(sol.q.last().unwrap(), &sim.state().q, "{name}: the last row is its node");
    let saved: Vec<usize> = (0..sol.len()).filter(|&i| sol.step[i].is_none()).collect();
    assert_eq!(saved.iter().map(|&i| sol.t[i]).collect::<Vec<_>>(), SAVE, "{name}: save times");
    let nodes: Vec<u64> = sol.step.iter().flatten().copied().collect();
    assert!(nodes[..nodes.len() - 1].iter().all(|k| k % 5 == 0), "{name}: every 5th node and the last: {nodes:?}");
    let dense_error = saved
        .iter()
        .zip(reference)
        .flat_map(|(&i, r)| {
            let q = sol.q[i];
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
    let bits = |s: &Solution<2>| {
        let rows = |a: &[[f64; 2]]| a.iter().flat_map(|r| r.map(f64::to_bits)).collect::<Vec<_>>();
        let t: Vec<u64> = s.t.iter().map(|x| x.to_bits()).collect();
        let e: Vec<u64> = s.energy.iter().map(|x| x.to_bits()).collect();
        (t, s.step.clone(), rows(&s.q), rows(&s.p), rows(&s.v), e)
    };
    let mut csv = Vec::new();
    sol.write_csv(&mut csv).unwrap();
    assert_eq!(bits(&Solution::<2>::read_csv(csv.as_slice()).unwrap()), bits(&sol), "{name}: csv");
    let mut json = Vec::new();
    sol.write_json(&mut json).unwrap();
    let back = Solution::<2>::read_json(json.as_slice()).unwrap();
    assert_eq!(bits(&back), bits(&sol), "{name}: json");
    assert_eq!(back.events, sol.events, "{name}: json events");
    let files = format!("csv {} B, json {} B", csv.len(), json.len());

    Row { name, land, solve, files }
}

#[test]
fn every_method_through_one_stepper_trait() {
    let pendulum = &reference(DoublePendulum, Q0, V0);
    let kepler = &reference(Kepler, KEPLER_Q0, KEPLER_V0);
    let rows = [
        row(
            "midpoint",
            pendulum,
            || Integrator::new(DoublePendulum, Midpoint, 0.005).start(0.0, Q0, V0).unwrap(),
            2e-4,
        ),
        row(
            "trapezoid",
            pendulum,
            || Integrator::new(DoublePendulum, Trapezoid, 0.005).start(0.0, Q0, V0).unwrap(),
            1e-3,
        ),
        row(
            "α-β (α = 0.5)",
            pendulum,
            || Integrator::new(DoublePendulum, AlphaBeta::new(0.5).unwrap(), 0.005).start(0.0, Q0, V0).unwrap(),
            2e-4,
        ),
        row(
            "Galerkin s = 2",
            pendulum,
            || Integrator::new(DoublePendulum, Galerkin::<2, 2>::gauss(), 0.02).start(0.0, Q0, V0).unwrap(),
            2e-5,
        ),
        row(
            "Galerkin s = 3",
            pendulum,
            || Integrator::new(DoublePendulum, Galerkin::<3, 3>::gauss(), 0.02).start(0.0, Q0, V0).unwrap(),
            1e-7,
        ),
        row(
            "Galerkin s = 4",
            pendulum,
            || Integrator::new(DoublePendulum, Galerkin::<4, 4>::gauss(), 0.02).start(0.0, Q0, V0).unwrap(),
            1e-8,
        ),
        row(
            "Yoshida 4",
            pendulum,
            || Integrator::new(DoublePendulum, Composition::YOSHIDA4, 0.01).start(0.0, Q0, V0).unwrap(),
            2e-4,
        ),
        row(
            "Yoshida 6",
            pendulum,
            || Integrator::new(DoublePendulum, Composition::YOSHIDA6, 0.02).start(0.0, Q0, V0).unwrap(),
            2e-5,
        ),
        row(
            "Kahan–Li 8",
            pendulum,
            || Integrator::new(DoublePendulum, Composition::KAHAN_LI8, 0.04).start(0.0, Q0, V0).unwrap(),
            1e-5,
        ),
        row(
            "time-transformed midpoint",
            pendulum,
            || {
                TimeTransformed::new(DoublePendulum, Curvature::new(1.0).unwrap())
                    .rule(Midpoint, 0.03)
                    .start::<3>(0.0, Q0, V0)
                    .unwrap()
            },
            3e-4,
        ),
        row(
            "time-transformed Galerkin s = 2",
            pendulum,
            || {
                TimeTransformed::new(DoublePendulum, Curvature::new(1.0).unwrap())
                    .galerkin(Galerkin::<2, 2>::gauss(), 0.1)
                    .start::<3>(0.0, Q0, V0)
                    .unwrap()
            },
            2e-5,
        ),
        row(
            "explicit time-transformed Kahan–Li 8",
            kepler,
            || {
                ExplicitTimeTransformed::new(Kepler, TimeFunction::Logarithmic, 0.05)
                    .composition(Composition::KAHAN_LI8)
                    .start(0.0, KEPLER_Q0, KEPLER_V0)
                    .unwrap()
            },
            2e-7,
        ),
    ];
    println!("{:<36} | {:<26} | {:<34} | files", "method", "land", "solve");
    for r in &rows {
        println!("{:<36} | {:<26} | {:<34} | {}", r.name, r.land, r.solve, r.files);
    }
}
