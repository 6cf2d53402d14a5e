//! The tolerance-driven solve (`lagrangian::Auto`) on the report's problems
//! and three more (Toda lattice, spring pendulum, charged particle in a
//! magnetic field) against exact or double-double references: the error
//! achieved against the tolerance, the estimate against the largest true
//! error at eight nodes spread over the run (and, printed, against the error
//! at the end), and the energy of conservative problems.
//!
//! By default a representative subset runs; `AUTO_GRID=full` runs every
//! problem at every tolerance `1e-4 … 1e-12` and prints the table
//! (`AUTO_GRID=full cargo test --release -p lagrangian-bench --test integration auto:: -- --nocapture`;
//! `AUTO_PROBLEMS=pendulum,toda` keeps only these problems).

use lagrangian::prelude::*;
use lagrangian_bench::calibrate::error_of;
use lagrangian_bench::methods::{Method, Setting};
use lagrangian_bench::problem::{self, Problem};
use lagrangian_bench::run::AUTO_NODES;

type Dd = DoubleDouble;

fn full() -> bool {
    std::env::var("AUTO_GRID").is_ok_and(|v| v == "full")
}

/// One case of the grid.
#[derive(Debug)]
struct Case {
    problem: String,
    rtol: f64,
    method: String,
    /// Achieved error over the error asked for (`rtol · Q`).
    achieved: f64,
    /// Estimate over the achieved error at the end.
    honesty: f64,
    /// Estimate over the largest error at evenly spread nodes of the run
    /// (the end among them): the estimate is a running maximum.
    envelope: f64,
    seconds: f64,
    /// The pilot's measured growth, its steps, and the final step.
    detail: String,
}

fn print(cases: &[Case]) {
    eprintln!(
        "| problem | rtol | method | error / requested | estimate / error at the end | estimate / largest error | seconds | growth, pilot steps, step |"
    );
    eprintln!("| --- | --- | --- | --- | --- | --- | --- | --- |");
    for c in cases {
        eprintln!(
            "| {} | {:.0e} | {} | {:.2} | {:.2} | {:.2} | {:.3} | {} |",
            c.problem, c.rtol, c.method, c.achieved, c.honesty, c.envelope, c.seconds, c.detail
        );
    }
}

/// The grid's acceptance: ≤ 10× the request in ≥ 95% of the cases, ≤ 100×
/// in all; the estimate within a factor 10 of the largest error along the
/// run, which it estimates (an error below 100 ε of the scale is round-off,
/// which the estimate need not follow). The error at the end alone is
/// printed: an oscillation's error passes near zero twice a period, and
/// the end may fall there.
fn check(cases: &[Case]) {
    print(cases);
    let within10 = cases.iter().filter(|c| c.achieved <= 10.0).count();
    assert!(within10 as f64 >= 0.95 * cases.len() as f64, "{within10} of {} within 10×", cases.len());
    let end = cases.iter().filter(|c| c.honesty.is_nan() || (0.1..=10.0).contains(&c.honesty)).count();
    eprintln!("estimate within 10× of the error at the end in {end} of {}", cases.len());
    for c in cases {
        assert!(c.achieved <= 100.0, "{c:?}");
        assert!(c.envelope.is_nan() || (0.1..=10.0).contains(&c.envelope), "{c:?}");
    }
}

/// `estimate / max_k error(t_k)` over `(t_k, q_k)` with `reference(t_k)`;
/// NaN when that error is round-off (below 100 ε of `scale`).
fn envelope(estimate: f64, nodes: &[(f64, Vec<f64>)], reference: impl Fn(f64) -> Vec<f64>, scale: f64) -> f64 {
    // A run of fewer nodes than `AUTO_NODES` repeats the start, which has no error.
    let largest =
        nodes.iter().filter(|(t, _)| *t > 0.0).map(|(t, q)| error_of(q, &reference(*t)).unwrap()).fold(0.0, f64::max);
    if largest < 100.0 * f64::EPSILON * scale { f64::NAN } else { estimate / largest }
}

fn big_stack(f: impl FnOnce() + Send + 'static) {
    std::thread::Builder::new().stack_size(256 << 20).spawn(f).unwrap().join().unwrap();
}

fn report_case(p: &dyn Problem, t_end: f64, rtol: f64, reference: &[f64]) -> Case {
    // Every node kept: the error along the run at `AUTO_NODES` of them.
    let run = p.run(Method::Auto, Setting::Tolerance(rtol), t_end, 1);
    let auto = run.auto.clone().unwrap_or_else(|| panic!("{} rtol {rtol:e}: {:?}", p.id(), run.failure));
    assert!(run.failure.is_none(), "{} rtol {rtol:e}: {:?}", p.id(), run.failure);
    let error = error_of(&run.q, reference).unwrap();
    let scale = reference.iter().fold(1.0f64, |m, x| m.max(x.abs()));
    Case {
        problem: p.id().into(),
        rtol,
        method: auto.method,
        achieved: error / auto.requested,
        honesty: if error < 100.0 * f64::EPSILON * scale { f64::NAN } else { auto.estimate / error },
        envelope: envelope(
            auto.estimate,
            &auto.nodes,
            |t| if t == t_end { reference.to_vec() } else { p.reference(t, 1e-14).unwrap().q },
            scale,
        ),
        seconds: run.seconds,
        detail: format!("{}, {} of {}, {:.3e}; {}", auto.growth, auto.pilot_steps, run.steps, auto.step, auto.reason),
    }
}

/// `(problem, horizon scale)`: long enough for Kepler e = 0.9 to show its
/// step density (two orbits), short enough for the references; Kepler in
/// polar coordinates over 20 orbits (10 in the default subset), its angle
/// counted on, a mass matrix that depends on the configuration.
fn report_problems() -> Vec<(&'static str, f64)> {
    if full() {
        vec![
            ("pendulum", 0.2),
            ("kepler-0.5", 0.2),
            ("kepler-0.9", 0.2),
            ("henon-heiles", 0.05),
            ("outer-solar-system", 0.02),
            ("double-pendulum", 0.5),
            ("fpu-beta", 0.05),
            ("perturbed-pendulum", 0.1),
            ("sensor", 0.1),
            ("kepler-polar", 0.02),
        ]
    } else {
        vec![
            ("pendulum", 0.1),
            ("kepler-0.9", 0.2),
            ("perturbed-pendulum", 0.05),
            ("sensor", 0.05),
            ("kepler-polar", 0.01),
        ]
    }
}

/// `AUTO_PROBLEMS=id,id`: only these problems of the grid.
fn selected(id: &str) -> bool {
    std::env::var("AUTO_PROBLEMS").map_or(true, |v| v.split(',').any(|p| p.trim() == id))
}

fn tolerances() -> Vec<f64> {
    if full() { vec![1e-4, 1e-6, 1e-8, 1e-10, 1e-12] } else { vec![1e-6, 1e-10] }
}

#[test]
fn the_report_problems_meet_their_tolerances() {
    big_stack(|| {
        let mut cases = Vec::new();
        for (id, scale) in report_problems().into_iter().filter(|(id, _)| selected(id)) {
            let Some(p) = problem::all(scale).into_iter().find(|p| p.id() == id) else {
                panic!("no problem {id}: {:?}", problem::all(1.0).iter().map(|p| p.id()).collect::<Vec<_>>())
            };
            let t_end = p.horizon();
            let reference = p.reference(t_end, 1e-14).unwrap().q;
            for rtol in tolerances() {
                cases.push(report_case(p.as_ref(), t_end, rtol, &reference));
            }
        }
        check(&cases);
    });
}

/// Conservative problems: the energy error of the auto solve stays bounded
/// (its second half no larger than a few times its first: no drift).
#[test]
fn energy_is_bounded_where_conserved() {
    big_stack(|| {
        for (id, scale) in [("pendulum", 0.2), ("kepler-0.5", 0.2)] {
            let p = problem::all(scale).into_iter().find(|p| p.id() == id).unwrap();
            assert!(p.conservative());
            let run = p.run(Method::Auto, Setting::Tolerance(1e-8), p.horizon(), 200);
            assert!(run.failure.is_none(), "{id}: {:?}", run.failure);
            let half = p.horizon() / 2.0;
            let max = |first: bool| {
                run.energy.iter().filter(|(t, _)| (*t <= half) == first).map(|s| s.1.abs()).fold(0.0, f64::max)
            };
            let (a, b) = (max(true), max(false));
            assert!(b <= 3.0 * a + 1e-13, "{id}: energy error {a:e} in the first half, {b:e} in the second");
            assert!(b < 1e-6, "{id}: energy error {b:e}");
        }
    });
}

// ------------------------------------------------------------ new problems

/// The periodic Toda lattice of three particles.
#[derive(Clone, Copy)]
pub(crate) struct Toda;

#[lagrangian]
impl Toda {
    fn lagrangian(&self, q: [f64; 3], v: [f64; 3]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
            - (q[0] - q[1]).exp()
            - (q[1] - q[2]).exp()
            - (q[2] - q[0]).exp()
    }
}

/// The elastic pendulum in polar coordinates `(r, θ)`: unit mass,
/// `k = 40`, rest length 1, `g = 9.81` (a mass matrix depending on `r`).
#[derive(Clone, Copy)]
pub(crate) struct SpringPendulum;

#[lagrangian]
impl SpringPendulum {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + q[0] * q[0] * v[1] * v[1]) + 9.81 * q[0] * q[1].cos() - 20.0 * (q[0] - 1.0) * (q[0] - 1.0)
    }
}

/// A unit charge of unit mass in the uniform field `B = 2 ẑ` (symmetric
/// gauge `A = B/2 (−y, x)`): circles of angular frequency 2.
#[derive(Clone, Copy)]
pub(crate) struct Gyration;

#[lagrangian]
impl Gyration {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) + (q[0] * v[1] - q[1] * v[0])
    }
}

/// The closed form of [`Gyration`] from `(q0, v0)`.
fn gyration_exact(q0: [f64; 2], v0: [f64; 2], t: f64) -> [f64; 2] {
    let b = 2.0;
    let (s, c) = (b * t).sin_cos();
    [q0[0] + (v0[0] * s - v0[1] * c + v0[1]) / b, q0[1] + (v0[0] * c - v0[0] + v0[1] * s) / b]
}

/// `q(t_end)` by double-double Galerkin `s = 8` (Newton to 1e-30).
fn dd_reference<S: Lagrangian<N>, const N: usize>(
    sys: S,
    q0: [f64; N],
    v0: [f64; N],
    t_end: f64,
    n: usize,
) -> [f64; N] {
    let h = Dd::from(t_end) / n as f64;
    let mut sim = GalerkinIntegrator::new(sys, Galerkin::<8, 8, Dd>::gauss(), h)
        .newton(NewtonOptions { rtol: 1e-30, ..NewtonOptions::default() })
        .start(Dd::from(0.0), q0.map(Dd::from), v0.map(Dd::from))
        .unwrap();
    sim.run(n, |_| {}).unwrap();
    sim.state().q.map(|x| x.to_f64())
}

/// One case of a new problem; `reference(t)` is `q(t)`.
fn new_case<S: Lagrangian<N> + Clone, const N: usize>(
    name: &str,
    sys: S,
    (q0, v0): ([f64; N], [f64; N]),
    t_end: f64,
    rtol: f64,
    reference: impl Fn(f64) -> [f64; N],
) -> Case {
    let clock = std::time::Instant::now();
    let solved = Auto::new(sys, 0.0, q0, v0)
        .tolerance(Tolerance::relative(rtol))
        .solve(Plan::until(t_end).without_velocities())
        .unwrap_or_else(|e| panic!("{name} rtol {rtol:e}: {e}"));
    let seconds = clock.elapsed().as_secs_f64();
    let solution = solved.solution.into_result().unwrap();
    let at_end = reference(t_end);
    let error = error_of(solution.q.last().unwrap(), &at_end).unwrap();
    let est = solved.estimate;
    let scale = at_end.iter().fold(1.0f64, |m, x| m.max(x.abs()));
    let n = solution.t.len() - 1;
    let nodes: Vec<(f64, Vec<f64>)> =
        (1..=AUTO_NODES).map(|k| n * k / AUTO_NODES).map(|i| (solution.t[i], solution.q[i].to_vec())).collect();
    Case {
        problem: name.into(),
        rtol,
        method: est.method_name,
        achieved: error / est.requested,
        honesty: if error < 100.0 * f64::EPSILON * scale { f64::NAN } else { est.error / error },
        envelope: envelope(est.error, &nodes, |t| reference(t).to_vec(), scale),
        seconds,
        detail: format!("{:?}, {}, {:.3e}; {}", est.growth, est.pilot.steps, est.step, est.reason),
    }
}

#[test]
fn three_new_problems_meet_their_tolerances() {
    big_stack(|| {
        let mut cases = Vec::new();
        let toda = ([0.0, 0.5, -0.3], [0.6, -0.2, -0.4]);
        let spring = ([1.2, 0.8], [0.0, 0.0]);
        let charge = ([0.3, -0.2], [0.7, 0.4]);
        let (t_toda, t_spring, t_charge) = (20.0, 10.0, 20.0);
        // Double-double steps of 0.01 (Toda) and 0.0025 (spring pendulum).
        let r_toda = |t: f64| dd_reference(Toda, toda.0, toda.1, t, (t / 0.01).ceil() as usize);
        let r_spring = |t: f64| dd_reference(SpringPendulum, spring.0, spring.1, t, (t / 0.0025).ceil() as usize);
        let r_charge = |t: f64| gyration_exact(charge.0, charge.1, t);
        for rtol in if full() { vec![1e-4, 1e-6, 1e-8, 1e-10, 1e-12] } else { vec![1e-8] } {
            if selected("toda") {
                cases.push(new_case("toda", Toda, toda, t_toda, rtol, r_toda));
            }
            if selected("spring-pendulum") {
                cases.push(new_case("spring-pendulum", SpringPendulum, spring, t_spring, rtol, r_spring));
            }
            if selected("charge-in-b") {
                cases.push(new_case("charge-in-b", Gyration, charge, t_charge, rtol, r_charge));
            }
        }
        check(&cases);
    });
}

#[test]
fn the_closed_form_of_the_gyration_is_a_solution() {
    // The reference itself against double-double Galerkin.
    let (q0, v0) = ([0.3, -0.2], [0.7, 0.4]);
    let dd = dd_reference(Gyration, q0, v0, 3.0, 300);
    let exact = gyration_exact(q0, v0, 3.0);
    assert!(error_of(&dd, &exact).unwrap() < 1e-14, "{dd:?} {exact:?}");
}
