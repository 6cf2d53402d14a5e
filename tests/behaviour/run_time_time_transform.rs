//! The implicit time transformation (Sundman–Poincaré, curvature monitor)
//! on run-time-sized systems, through `Problem<S, Dyn>`: the same steps as
//! at a compile-time size, the order of the method in `s` against Kepler's
//! analytic solution, the energy without drift, landing and `solve`, and
//! the typed refusals of bad input with the stepper left as it was.

use lagrangian::prelude::*;
use lagrangian::{Action, Status};

use super::run_time_systems::{Kepler, KeplerDyn};

/// A short FPU-β chain between fixed walls at a compile-time size.
#[derive(Clone)]
struct Chain;

#[lagrangian]
impl Chain {
    fn lagrangian(&self, q: [f64; 4], v: [f64; 4]) -> f64 {
        let mut l = 0.0;
        for i in 0..4 {
            l += 0.5 * v[i] * v[i];
        }
        l -= 0.5 * q[0] * q[0] + 0.25 * q[0] * q[0] * q[0] * q[0];
        l -= 0.5 * q[3] * q[3] + 0.25 * q[3] * q[3] * q[3] * q[3];
        for i in 0..3 {
            let d = q[i + 1] - q[i];
            l -= 0.5 * d * d + 0.25 * d * d * d * d;
        }
        l
    }
}

/// The same chain with its size known at run time.
#[derive(Clone)]
struct ChainDyn {
    n: usize,
}

#[lagrangian]
impl ChainDyn {
    fn dimension(&self) -> usize {
        self.n
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        let n = q.len();
        let mut l = 0.0;
        for i in 0..n {
            l += 0.5 * v[i] * v[i];
        }
        l -= 0.5 * q[0] * q[0] + 0.25 * q[0] * q[0] * q[0] * q[0];
        l -= 0.5 * q[n - 1] * q[n - 1] + 0.25 * q[n - 1] * q[n - 1] * q[n - 1] * q[n - 1];
        for i in 0..n - 1 {
            let d = q[i + 1] - q[i];
            l -= 0.5 * d * d + 0.25 * d * d * d * d;
        }
        l
    }
}

/// A pendulum on a circle of radius 1 written with `√(1 − x²)`: its
/// potential, hence the curvature monitor, is NaN beyond `|x| = 1`.
#[derive(Clone)]
struct Bowl;

#[lagrangian]
impl Bowl {
    fn dimension(&self) -> usize {
        1
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        0.5 * v[0] * v[0] + (1.0 - q[0] * q[0]).sqrt()
    }
}

const E: f64 = 0.9;

fn kepler_start() -> ([f64; 2], [f64; 2]) {
    ([1.0 - E, 0.0], [0.0, ((1.0 + E) / (1.0 - E)).sqrt()])
}

fn curvature() -> Curvature {
    Curvature::new(1.0).unwrap()
}

/// Kepler's orbit from pericentre at time `t` (`a = 1`, period `2π`): the
/// eccentric anomaly from Kepler's equation by Newton's method.
fn kepler_exact(t: f64) -> [f64; 2] {
    let m = t.rem_euclid(2.0 * std::f64::consts::PI);
    let mut u = m + E * m.sin() / (1.0 - (m + E).sin() + m.sin()).max(0.5);
    for _ in 0..100 {
        let du = (u - E * u.sin() - m) / (1.0 - E * u.cos());
        u -= du;
        if du.abs() < 1e-16 {
            break;
        }
    }
    [u.cos() - E, (1.0 - E * E).sqrt() * u.sin()]
}

fn gap(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max)
}

/// Kepler `e = 0.9` and a chain of four FPU-β masses, stepped at both
/// sizes with the midpoint rule and Galerkin `s = 2` in `s`: the same
/// states (time, positions, momenta) to round-off after hundreds of steps.
#[test]
fn both_sizes_take_the_same_steps() {
    let (q0, v0) = kepler_start();
    let kepler = Problem::new(Kepler, 0.0, q0, v0);
    let kepler_dyn = Problem::new(KeplerDyn, 0.0, q0.to_vec(), v0.to_vec());
    let chain_q0 = [0.3, -0.2, 0.5, 0.1];
    let chain_v0 = [0.0, 0.4, -0.1, 0.2];
    let chain = Problem::new(Chain, 0.0, chain_q0, chain_v0);
    let chain_dyn = Problem::new(ChainDyn { n: 4 }, 0.0, chain_q0.to_vec(), chain_v0.to_vec());
    for (name, inner, sigma, steps) in
        [("midpoint", Scheme::MIDPOINT, 0.02, 600), ("Galerkin s = 2", Scheme::galerkin(2), 0.1, 300)]
    {
        let scheme = inner.time_transformed(curvature());
        let mut a = kepler.stepper(&scheme, sigma).unwrap();
        let mut b = kepler_dyn.stepper(&scheme, sigma).unwrap();
        a.run(steps, |_| {}).unwrap();
        b.run(steps, |_| {}).unwrap();
        let (sa, sb) = (a.state(), b.state());
        assert_eq!(sa.step, sb.step);
        let d = gap(&sa.q, &sb.q).max(gap(&sa.p, &sb.p)).max((sa.t - sb.t).abs());
        assert!(d < 1e-11, "Kepler, {name}: the sizes differ by {d:e} after {steps} steps (t = {})", sa.t);
        assert!(sa.t > 2.0, "Kepler, {name}: more than a pericentre passage ({})", sa.t);
        let mut a = chain.stepper(&scheme, sigma).unwrap();
        let mut b = chain_dyn.stepper(&scheme, sigma).unwrap();
        a.run(steps, |_| {}).unwrap();
        b.run(steps, |_| {}).unwrap();
        let (sa, sb) = (a.state(), b.state());
        let d = gap(&sa.q, &sb.q).max(gap(&sa.p, &sb.p)).max((sa.t - sb.t).abs());
        assert!(d < 1e-12, "chain, {name}: the sizes differ by {d:e}");
        let de = (a.energy().unwrap() - b.energy().unwrap()).abs();
        assert!(de < 1e-12, "chain, {name}: energies differ by {de:e}");
        println!("{name}: Kepler and chain agree to {d:.0e} over {steps} steps");
    }
}

/// The order in `σ` of the map in `s` is the method's: 2 for the midpoint
/// rule, 4 for Galerkin `s = 2`, fitted from the error at `t = 8.2` (past
/// a pericentre passage) against Kepler's analytic solution.
#[test]
fn the_order_in_sigma_is_the_methods() {
    let (q0, v0) = kepler_start();
    let problem = Problem::new(KeplerDyn, 0.0, q0.to_vec(), v0.to_vec());
    let t_end = 8.2;
    let exact = kepler_exact(t_end);
    for (inner, sigmas, order) in
        [(Scheme::MIDPOINT, [0.02, 0.01, 0.005], 2.0), (Scheme::galerkin(2), [0.1, 0.05, 0.025], 4.0)]
    {
        let scheme = inner.time_transformed(curvature());
        let errors: Vec<f64> = sigmas
            .iter()
            .map(|&sigma| {
                let mut sim = problem.stepper(&scheme, sigma).unwrap();
                sim.run_until(t_end).unwrap();
                assert_eq!(sim.state().t, t_end);
                gap(&sim.state().q, &exact)
            })
            .collect();
        let fitted = (errors[0] / errors[2]).log2() / 2.0;
        println!("{}: errors {errors:?}, fitted order {fitted:.2}", scheme.name());
        assert!((fitted - order).abs() < 0.25, "{}: fitted order {fitted} (errors {errors:?})", scheme.name());
    }
}

/// Over 40 orbits of Kepler `e = 0.9` the energy error of the midpoint rule
/// in `s` stays bounded: the largest error of the last 10 orbits is that
/// of the first 10 within a factor 1.5, and `p_t` is conserved to round-off.
#[test]
fn the_energy_is_bounded_without_drift() {
    let (q0, v0) = kepler_start();
    let problem = Problem::new(KeplerDyn, 0.0, q0.to_vec(), v0.to_vec());
    let mut sim = problem.stepper(&Scheme::MIDPOINT.time_transformed(curvature()), 0.05).unwrap();
    let e0 = sim.energy().unwrap();
    let p_t0 = sim.discrete_energy();
    let period = 2.0 * std::f64::consts::PI;
    let mut worst = Vec::new();
    for orbit in 1..=40 {
        let mut largest: f64 = 0.0;
        while sim.state().t < period * f64::from(orbit) {
            sim.step().unwrap();
            largest = largest.max((sim.energy().unwrap() - e0).abs());
        }
        worst.push(largest);
    }
    let first = worst[..10].iter().copied().fold(0.0, f64::max);
    let last = worst[30..].iter().copied().fold(0.0, f64::max);
    println!("energy error: first 10 orbits {first:.2e}, last 10 {last:.2e}, {} steps", sim.stats().steps);
    assert!(first < 1e-2 && last <= 1.5 * first, "first {first:e}, last {last:e}");
    let drift = (sim.discrete_energy() - p_t0).abs();
    assert!(drift < 1e-11, "p_t drifted by {drift:e}");
}

/// `run_until` lands on each target exactly, and `solve` keeps every 10th
/// node, the save times by dense output (against the analytic solution),
/// records the crossings of `y = 0` (at half periods) and stops at `t = 9`.
#[test]
fn landing_and_solve_in_physical_time() {
    let (q0, v0) = kepler_start();
    let problem = Problem::new(KeplerDyn, 0.0, q0.to_vec(), v0.to_vec());
    let scheme = Scheme::galerkin(2).time_transformed(curvature());
    let mut sim = problem.stepper(&scheme, 0.05).unwrap();
    for i in 1..=50 {
        let target = 0.2137 * f64::from(i);
        sim.run_until(target).unwrap();
        assert_eq!(sim.state().t.to_bits(), target.to_bits(), "target {i}");
    }
    let error = gap(&sim.state().q, &kepler_exact(sim.state().t));
    assert!(error < 1e-4, "after landing: {error:e}");

    let save = vec![0.5, 1.7, 3.3, 6.0];
    let plan = Plan::until(20.0)
        .every(10)
        .save_at(save.clone())
        .event(Event::new(|_t, q, _v| q[1]))
        .event(Event::new(|t, _q, _v| t - 9.0).action(Action::Stop));
    let mut sim = problem.stepper(&scheme, 0.05).unwrap();
    let sol = sim.solve(plan).unwrap();
    assert!(matches!(sol.status, Status::Stopped { event: 1, .. }), "{:?}", sol.status);
    assert_eq!(*sol.t.last().unwrap(), 9.0);
    assert_eq!(sim.state().t, 9.0);
    let saved: Vec<usize> = (0..sol.len()).filter(|&i| sol.step[i].is_none()).collect();
    assert_eq!(saved.iter().map(|&i| sol.t[i]).collect::<Vec<_>>(), save);
    for &i in &saved {
        let error = gap(&sol.q[i], &kepler_exact(sol.t[i]));
        assert!(error < 1e-3, "save time {}: {error:e}", sol.t[i]);
    }
    let nodes: Vec<u64> = sol.step.iter().flatten().copied().collect();
    assert!(nodes[..nodes.len() - 1].iter().all(|k| k % 10 == 0), "{nodes:?}");
    // `y = 0` at every half period: π, 2π (the pericentre at 2π counts once).
    let crossings: Vec<f64> = sol.events.iter().filter(|e| e.event == 0).map(|e| e.t).collect();
    let half = std::f64::consts::PI;
    assert_eq!(crossings.len(), 2, "{crossings:?}");
    for (k, t) in crossings.iter().enumerate() {
        assert!((t - half * (k + 1) as f64).abs() < 1e-3, "crossing {k}: {t}");
    }
    let energy = sol.energy.iter().map(|e| (e - sol.energy[0]).abs()).fold(0.0, f64::max);
    assert!(energy < 1e-3, "energy along the rows: {energy:e}");
}

/// What is not defined at a run-time size is refused as at a compile-time
/// size, with the text of `supports`: variable steps, a composition in
/// `s`, and sensitivities.
#[test]
fn undefined_combinations_are_refused() {
    let (q0, v0) = kepler_start();
    let problem = Problem::new(KeplerDyn, 0.0, q0.to_vec(), v0.to_vec());
    let scheme = Scheme::MIDPOINT.time_transformed(curvature());
    let refusal = |r: Result<(), Error>| match r {
        Err(Error::Unsupported { what }) => what,
        other => panic!("not a typed refusal: {other:?}"),
    };
    assert!(
        refusal(problem.supports(&scheme, Policy::energy_preserving(0.1), Capability::Step))
            .starts_with("variable steps under a time transformation")
    );
    let composed = Scheme::composition(Composition::YOSHIDA4, OnePoint::Trapezoid).time_transformed(curvature());
    assert!(refusal(problem.supports(&composed, 0.1, Capability::Step)).starts_with("time transformation around"));
    assert!(matches!(problem.stepper(&composed, 0.1), Err(Error::Unsupported { .. })));
    assert!(refusal(problem.supports(&scheme, 0.1, Capability::Sensitivities)).starts_with("sensitivities"));
    assert!(problem.supports(&scheme, 0.1, Capability::Solve).is_ok());
}

/// A density that is not finite and positive: at the initial data a typed
/// error at construction; inside a step the typed error with the state the
/// step started from, the stepper bit for bit as it was. A Newton solve
/// that fails (one iteration allowed): the typed error with the state, the
/// stepper unchanged, and the step retried with enough iterations.
#[test]
fn bad_input_is_a_typed_error_and_leaves_the_stepper_as_it_was() {
    let scheme = Scheme::MIDPOINT.time_transformed(curvature());
    // Outside the bowl the monitor is NaN.
    let outside = Problem::new(Bowl, 0.0, vec![1.5], vec![0.0]);
    match outside.stepper(&scheme, 0.1) {
        Err(Error::InvalidDensity { state, value }) => {
            assert!(value.is_nan());
            assert_eq!((state.t, &state.q[..]), (0.0, &[1.5][..]));
        }
        other => panic!("{:?}", other.map(|s| s.state().clone())),
    }
    // Moving fast toward the rim: a step ends beyond it.
    let inside = Problem::new(Bowl, 0.0, vec![0.9], vec![3.0]);
    let mut sim = inside.stepper(&scheme, 0.2).unwrap();
    let snapshot = |s: &Stepper<Bowl, Dyn>| {
        let p = s.state();
        (p.step, p.t.to_bits(), p.q[0].to_bits(), p.p[0].to_bits(), s.stats().steps, s.discrete_energy().to_bits())
    };
    let mut failure = None;
    for _ in 0..20 {
        let before = snapshot(&sim);
        let state = sim.state().clone();
        match sim.step() {
            Ok(_) => continue,
            Err(e) => {
                assert_eq!(snapshot(&sim), before, "the failed step changed the stepper");
                match &e {
                    Error::InvalidDensity { state: at, .. } | Error::OrbitLost { state: at, .. } => {
                        assert_eq!(at, &state)
                    }
                    Error::NewtonDidNotConverge { state: at, .. } | Error::NonFinite { state: at, .. } => {
                        assert_eq!(at, &state)
                    }
                    other => panic!("unexpected error {other}"),
                }
                failure = Some(e);
                break;
            }
        }
    }
    let failure = failure.expect("a step meets the rim");
    println!("at the rim: {failure}");

    // One Newton iteration cannot converge.
    let (q0, v0) = kepler_start();
    let one = NewtonOptions { max_iterations: 1, ..NewtonOptions::default() };
    let strict = Problem::new(KeplerDyn, 0.0, q0.to_vec(), v0.to_vec()).newton(one);
    let mut sim = strict.stepper(&scheme, 0.02).unwrap();
    let before = sim.state().clone();
    let stats = sim.stats();
    match sim.step() {
        Err(Error::NewtonDidNotConverge { state, .. }) => assert_eq!(state, before),
        other => panic!("{:?}", other.cloned()),
    }
    assert_eq!(sim.state(), &before);
    assert_eq!(sim.stats(), stats);
}
