//! The explicit time-transformed splitting (`Scheme::Splitting`) on
//! run-time-sized systems, through `Problem<S, Dyn>`: the same steps as at a
//! compile-time size to round-off (Kepler `e = 0.9` in Cartesian
//! coordinates, three gravitating bodies with unequal masses), the fitted
//! order in `σ` against the analytic Kepler orbit, the energy without drift
//! over many orbits, exact landings, `solve` with thinning, save times and
//! events, and typed refusals that leave the stepper as it was.

use lagrangian::prelude::*;
use lagrangian::{Action, Status};
use std::f64::consts::PI;

use super::run_time_systems::{Kepler, KeplerDyn};

/// The masses of the three bodies (G = 1).
const MASSES: [f64; 3] = [1.0, 0.01, 0.003];

/// Three gravitating bodies in the plane, `q = (x₀, y₀, x₁, y₁, x₂, y₂)`:
/// `L = Σ ½ mᵢ|vᵢ|² + Σ_{i<j} mᵢmⱼ/|qᵢ − qⱼ|`, a diagonal mass matrix.
#[derive(Clone)]
struct Bodies;

#[lagrangian]
impl Bodies {
    fn lagrangian(&self, q: [f64; 6], v: [f64; 6]) -> f64 {
        let mut l = 0.0;
        for i in 0..3 {
            l += 0.5 * MASSES[i] * (v[2 * i] * v[2 * i] + v[2 * i + 1] * v[2 * i + 1]);
        }
        for i in 0..3 {
            for j in i + 1..3 {
                let (dx, dy) = (q[2 * i] - q[2 * j], q[2 * i + 1] - q[2 * j + 1]);
                l += MASSES[i] * MASSES[j] / (dx * dx + dy * dy).sqrt();
            }
        }
        l
    }
}

/// The three bodies with their number known at run time.
#[derive(Clone)]
struct BodiesDyn;

#[lagrangian]
impl BodiesDyn {
    fn dimension(&self) -> usize {
        6
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        let mut l = 0.0;
        for i in 0..3 {
            l += 0.5 * MASSES[i] * (v[2 * i] * v[2 * i] + v[2 * i + 1] * v[2 * i + 1]);
        }
        for i in 0..3 {
            for j in i + 1..3 {
                let (dx, dy) = (q[2 * i] - q[2 * j], q[2 * i + 1] - q[2 * j + 1]);
                l += MASSES[i] * MASSES[j] / (dx * dx + dy * dy).sqrt();
            }
        }
        l
    }
}

/// Kepler `e = 0.9` from pericentre (`a = 1`, period `2π`).
fn kepler_start(e: f64) -> ([f64; 2], [f64; 2]) {
    ([1.0 - e, 0.0], [0.0, ((1.0 + e) / (1.0 - e)).sqrt()])
}

/// A star and two planets on near-circular orbits, the star at rest.
fn bodies_start() -> ([f64; 6], [f64; 6]) {
    let (r1, r2): (f64, f64) = (1.0, 1.6);
    let (w1, w2) = ((1.0 / r1).sqrt(), (1.0 / r2).sqrt());
    ([0.0, 0.0, r1, 0.0, 0.0, r2], [0.0, 0.0, 0.0, w1, -w2, 0.0])
}

fn splitting(composition: Option<Composition>) -> Scheme {
    Scheme::splitting(TimeFunction::Logarithmic, composition)
}

/// Steps both sizes `steps` times and returns the largest difference of
/// `t`, `q` and `p` over all nodes, relative to the largest entry.
fn largest_gap<const N: usize, A, B>(
    compiled: &Problem<A, Dim<N>>,
    run_time: &Problem<B, Dyn>,
    scheme: &Scheme,
    sigma: f64,
    steps: usize,
) -> f64
where
    A: Lagrangian<N> + Clone,
    B: DynLagrangian + Clone,
    Dim<N>: lagrangian::problem::Extended<N>,
{
    let mut a = compiled.stepper(scheme, sigma).unwrap();
    let mut b = run_time.stepper(scheme, sigma).unwrap();
    let mut gap: f64 = 0.0;
    for _ in 0..steps {
        let x = a.step().unwrap();
        let y = b.step().unwrap();
        assert_eq!(x.step, y.step);
        let scale = x.q.iter().chain(&x.p).fold(x.t.abs(), |m, v| m.max(v.abs()));
        let d =
            x.q.iter().zip(&y.q).chain(x.p.iter().zip(&y.p)).fold((x.t - y.t).abs(), |m, (u, v)| m.max((u - v).abs()));
        gap = gap.max(d / scale);
    }
    gap
}

#[test]
fn the_same_steps_at_both_sizes() {
    let (q0, v0) = kepler_start(0.9);
    let kepler = Problem::new(Kepler, 0.0, q0, v0);
    let kepler_dyn = Problem::new(KeplerDyn, 0.0, q0.to_vec(), v0.to_vec());
    let (b0, w0) = bodies_start();
    let bodies = Problem::new(Bodies, 0.0, b0, w0);
    let bodies_dyn = Problem::new(BodiesDyn, 0.0, b0.to_vec(), w0.to_vec());
    for (composition, sigma) in [(None, 0.05), (Some(Composition::KAHAN_LI8), 0.2)] {
        // `dt ≈ σ/|V|`: the bodies' potential is 1/80 of Kepler's.
        let scheme = splitting(composition);
        let kepler_gap = largest_gap(&kepler, &kepler_dyn, &scheme, sigma, 400);
        let bodies_gap = largest_gap(&bodies, &bodies_dyn, &scheme, sigma / 50.0, 400);
        println!(
            "{}: largest relative gap over 400 steps: Kepler {kepler_gap:.1e}, three bodies {bodies_gap:.1e}",
            scheme.name()
        );
        assert!(kepler_gap < 1e-13 && bodies_gap < 1e-13, "{kepler_gap:e} {bodies_gap:e}");
    }
}

/// The error after one period (`t = 2π`, landed exactly) against the
/// start, the analytic state there.
fn period_error(scheme: &Scheme, sigma: f64) -> f64 {
    let (q0, v0) = kepler_start(0.9);
    let mut sim = Problem::new(KeplerDyn, 0.0, q0.to_vec(), v0.to_vec()).stepper(scheme, sigma).unwrap();
    sim.run_until(2.0 * PI).unwrap();
    assert_eq!(sim.state().t, 2.0 * PI);
    let s = sim.state();
    (0..2).map(|i| (s.q[i] - q0[i]).abs().max((s.p[i] - v0[i]).abs())).fold(0.0, f64::max)
}

#[test]
fn fitted_orders_on_kepler() {
    let cases = [
        (None, 2.0, [0.02, 0.01]),
        (Some(Composition::YOSHIDA4), 4.0, [0.08, 0.04]),
        (Some(Composition::YOSHIDA6), 6.0, [0.2, 0.1]),
        (Some(Composition::KAHAN_LI8), 8.0, [0.4, 0.2]),
    ];
    for (composition, order, [coarse, fine]) in cases {
        let scheme = splitting(composition);
        let (e1, e2) = (period_error(&scheme, coarse), period_error(&scheme, fine));
        let fitted = (e1 / e2).log2();
        println!("{}: errors {e1:.2e} (σ = {coarse}), {e2:.2e} (σ = {fine}): order {fitted:.2}", scheme.name());
        assert!((fitted - order).abs() < 0.3, "{}: fitted order {fitted}", scheme.name());
    }
}

#[test]
fn energy_without_drift_over_many_orbits() {
    // `f'(x) = x^{−3/2}`: its nodes are not on the orbit (as the logarithmic
    // drift–kick–drift ones are), so the energy error is the method's.
    let (q0, v0) = kepler_start(0.9);
    let problem = Problem::new(KeplerDyn, 0.0, q0.to_vec(), v0.to_vec());
    let mut sim = problem.stepper(&Scheme::splitting(TimeFunction::Power(1.5), None), 0.05).unwrap();
    let e0 = sim.energy().unwrap();
    // The largest relative energy error at the nodes of each orbit.
    let orbits = 100;
    let mut largest = vec![0.0f64; orbits];
    while sim.state().t < 2.0 * PI * orbits as f64 {
        sim.step().unwrap();
        let orbit = ((sim.state().t / (2.0 * PI)) as usize).min(orbits - 1);
        largest[orbit] = largest[orbit].max(((sim.energy().unwrap() - e0) / e0).abs());
    }
    let first = largest[..10].iter().copied().fold(0.0, f64::max);
    let last = largest[orbits - 10..].iter().copied().fold(0.0, f64::max);
    println!("relative energy error: orbits 1–10 {first:.2e}, orbits 91–100 {last:.2e}, {} steps", sim.stats().steps);
    assert!(first > 1e-6, "the method's error is visible: {first:e}");
    assert!(last < 1.2 * first, "no drift: {first:e} then {last:e}");
    // The momentum of time is kept to round-off (no kick changes it).
    assert!((sim.discrete_energy() - e0).abs() <= 1e-14 * e0.abs());
}

#[test]
fn solve_with_save_times_and_events_at_both_sizes() {
    let (b0, w0) = bodies_start();
    let scheme = splitting(Some(Composition::YOSHIDA6));
    let plan = || {
        Plan::until(12.0)
            .every(10)
            .save_at(vec![0.5, 2.25, 7.0])
            // The inner planet crosses the y axis (`x₁ = 0`), the run stops
            // where the outer one first crosses the x axis (`y₂ = 0`).
            .event(Event::new(|_, q, _| q[2]))
            .event(Event::new(|_, q, _| q[5]).action(Action::Stop))
    };
    // `dt ≈ σ/|V| ≈ 0.25`.
    let sigma = 0.003;
    let compiled = Problem::new(Bodies, 0.0, b0, w0).solve(&scheme, sigma, plan()).unwrap();
    let mut sim = Problem::new(BodiesDyn, 0.0, b0.to_vec(), w0.to_vec()).stepper(&scheme, sigma).unwrap();
    let sol = sim.solve(plan()).unwrap();
    assert!(matches!(sol.status, Status::Stopped { event: 1, .. }), "{:?}", sol.status);
    assert_eq!(sol.t.last(), Some(&sim.state().t));
    assert_eq!(sol.q.last(), Some(&sim.state().q[..]));
    // The outer planet's quarter orbit: `π/2 · 1.6^{3/2}`, to the planets' pull.
    let quarter = 0.5 * PI * 1.6f64.powf(1.5);
    let stop = *sol.t.last().unwrap();
    assert!((stop - quarter).abs() < 0.05, "{stop} against {quarter}");
    let records: Vec<f64> = sol.events.iter().filter(|e| e.event == 0).map(|e| e.t).collect();
    assert_eq!(records.len(), 1, "{records:?}");
    assert!((records[0] - 0.5 * PI).abs() < 0.05, "{records:?}");
    let saved: Vec<f64> = (0..sol.len()).filter(|&i| sol.step[i].is_none()).map(|i| sol.t[i]).collect();
    assert_eq!(saved, [0.5, 2.25]);
    let nodes: Vec<u64> = sol.step.iter().flatten().copied().collect();
    assert!(nodes[..nodes.len() - 1].iter().all(|k| k % 10 == 0), "{nodes:?}");
    // The rows of the compile-time solution, to round-off.
    assert_eq!(sol.step, compiled.step);
    let gap = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
    let rows = [(&sol.q, &compiled.q), (&sol.p, &compiled.p), (&sol.v, &compiled.v)]
        .iter()
        .map(|(a, b)| gap(a.as_flat(), b.as_flat()))
        .fold(gap(&sol.t, &compiled.t), f64::max);
    let events = gap(
        &sol.events.iter().map(|e| e.t).collect::<Vec<_>>(),
        &compiled.events.iter().map(|e| e.t).collect::<Vec<_>>(),
    );
    let energy = gap(&sol.energy, &compiled.energy);
    println!(
        "three bodies, Yoshida 6: {} rows, {} events, Δ {rows:.0e} (rows), {events:.0e} (events), {energy:.0e} (energy) to compile-time",
        sol.len(),
        sol.events.len()
    );
    assert!(rows < 1e-12 && events < 1e-12 && energy < 1e-12, "{rows:e} {events:e} {energy:e}");
}

#[test]
fn run_until_lands_exactly() {
    let (q0, v0) = kepler_start(0.9);
    let mut sim = Problem::new(KeplerDyn, 0.0, q0.to_vec(), v0.to_vec()).stepper(&splitting(None), 0.05).unwrap();
    for i in 1..=100 {
        let target = 10.0 * f64::from(i) / 100.0 * (1.0 - 1e-3 / PI);
        sim.run_until(target).unwrap();
        assert_eq!(sim.state().t.to_bits(), target.to_bits(), "target {i}");
    }
    // A target at the current time is a no-op.
    let before = sim.state().clone();
    sim.run_until(before.t).unwrap();
    assert_eq!(sim.state(), &before);
}

/// A separable system whose potential `V = √(1 − q²)` pushes the mass out
/// to where it stops being defined (`|q| > 1`).
#[derive(Clone)]
struct Edge;

#[lagrangian]
impl Edge {
    fn dimension(&self) -> usize {
        1
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        0.5 * v[0] * v[0] - (1.0 - q[0] * q[0]).sqrt()
    }
}

/// Not separable: the mass matrix depends on `q`.
#[derive(Clone, Debug)]
struct Pendulum2;

#[lagrangian]
impl Pendulum2 {
    fn dimension(&self) -> usize {
        2
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        v[0] * v[0] + 0.5 * v[1] * v[1] + v[0] * v[1] * (q[0] - q[1]).cos() + 2.0 * q[0].cos() + q[1].cos()
    }
}

/// A damped oscillator.
#[derive(Clone, Debug)]
struct Damped;

#[lagrangian]
impl Damped {
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

#[test]
fn bad_input_is_a_typed_error_and_leaves_the_stepper_as_it_was() {
    let scheme = splitting(None);
    // Not separable with a constant mass matrix: refused at start, naming it.
    let pendulum = Problem::new(Pendulum2, 0.0, vec![1.0, -0.5], vec![0.0, 0.3]);
    match pendulum.stepper(&scheme, 0.1) {
        Err(Error::NotSeparable { reason }) => assert!(reason.contains("constant mass matrix"), "{reason}"),
        other => panic!("{other:?}"),
    }
    // Forced, variable steps, sensitivities: refused by `supports`.
    let damped = Problem::new(Damped, 0.0, vec![1.0], vec![0.0]);
    match damped.stepper(&scheme, 0.1) {
        Err(Error::Unsupported { what }) => assert!(what.contains("forced system"), "{what}"),
        other => panic!("{other:?}"),
    }
    let (q0, v0) = kepler_start(0.5);
    let kepler = Problem::new(KeplerDyn, 0.0, q0.to_vec(), v0.to_vec());
    assert!(matches!(kepler.stepper(&scheme, Policy::energy_preserving(0.1)), Err(Error::Unsupported { .. })));
    assert!(matches!(kepler.supports(&scheme, 0.1, Capability::Sensitivities), Err(Error::Unsupported { .. })));
    // Data that is not finite, or at the singularity of `V`.
    for (q, v) in [
        (vec![f64::NAN, 0.0], vec![0.0, 1.0]),
        (vec![0.5, 0.0], vec![f64::INFINITY, 1.0]),
        (vec![0.0, 0.0], vec![0.0, 1.0]),
    ] {
        let problem = Problem::new(KeplerDyn, 0.0, q.clone(), v);
        assert!(matches!(problem.stepper(&scheme, 0.1), Err(Error::InvalidInitialData { .. })), "{q:?}");
    }
    // A step in `s` that is not positive.
    assert!(matches!(kepler.stepper(&scheme, -0.1), Err(Error::InvalidSetting { .. })));
    // A state that leaves the domain of `V`: the error carries the state the
    // step started from, and the stepper is bit for bit as it was.
    let mut sim = Problem::new(Edge, 0.0, vec![0.5], vec![0.9]).stepper(&scheme, 0.25).unwrap();
    let failure = loop {
        let before = sim.clone();
        match sim.step() {
            Ok(_) => continue,
            Err(e) => break (e, before),
        }
    };
    let (error, before) = failure;
    let state = match &error {
        Error::TimeFunctionArgument { state, .. } | Error::NonFinite { state, .. } | Error::OrbitLost { state, .. } => {
            state.clone()
        }
        other => panic!("not a typed step failure: {other:?}"),
    };
    println!("the edge of V: {error}");
    assert_eq!(&state, before.state());
    let bits =
        |s: &PhasePoint| (s.step, s.t.to_bits(), s.q.iter().chain(&s.p).map(|x| x.to_bits()).collect::<Vec<_>>());
    assert_eq!(bits(sim.state()), bits(before.state()));
    assert_eq!(sim.stats().steps, before.stats().steps);
    assert_eq!(sim.energy().unwrap().to_bits(), before.energy().unwrap().to_bits());
    // Again, the same error from the same state.
    assert_eq!(sim.step().unwrap_err().to_string(), error.to_string());
    // A target that is not finite or in the past.
    for target in [f64::NAN, -1.0] {
        match sim.run_until(target) {
            Err(Error::InvalidTarget { state, .. }) => assert_eq!(bits(&state), bits(before.state())),
            other => panic!("{other:?}"),
        }
    }
}
