//! `solve(Plan)` on a run-time-sized system: a chain of eight oscillators
//! between fixed walls, started in its third normal mode, whose frequency
//! is `ω₃ = 2 sin(3π/18) = 1`, so that `q_i(t) = sin(πi/3) cos t`
//! (`i = 1 … 8`). Thinning, save times by dense output (the cubic Hermite of
//! the nodes) against that solution, a `Record` and a `Stop` event against
//! their analytic times, CSV and JSON bit for bit, and the rows of the same
//! chain at a compile-time size.

use lagrangian::prelude::*;
use lagrangian::{Action, DenseKind, Derivatives, Direction, Status};

/// The chain with its size known at compile time: `L = Σ ½v_i² − ½q_1² −
/// ½q_8² − Σ ½(q_{i+1} − q_i)²`.
#[derive(Clone)]
struct Chain;

#[lagrangian]
impl Chain {
    fn lagrangian(&self, q: [f64; 8], v: [f64; 8]) -> f64 {
        let mut kinetic = 0.0;
        for i in 0..8 {
            kinetic += 0.5 * v[i] * v[i];
        }
        let mut potential = 0.5 * (q[0] * q[0] + q[7] * q[7]);
        for i in 0..7 {
            let d = q[i + 1] - q[i];
            potential += 0.5 * d * d;
        }
        kinetic - potential
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
        let mut kinetic = 0.0;
        for i in 0..n {
            kinetic += 0.5 * v[i] * v[i];
        }
        let mut potential = 0.5 * (q[0] * q[0] + q[n - 1] * q[n - 1]);
        for i in 0..n - 1 {
            let d = q[i + 1] - q[i];
            potential += 0.5 * d * d;
        }
        kinetic - potential
    }
}

const H: f64 = 0.01;
const T_END: f64 = 8.0;
const SAVE: [f64; 4] = [0.3, 1.234, 2.5, 4.0];

/// The mode's shape `sin(πi/3)`, `i = 1 … 8`.
fn shape() -> [f64; 8] {
    core::array::from_fn(|i| (std::f64::consts::PI * (i + 1) as f64 / 3.0).sin())
}

/// Thinning, save times, a `Record` event at the zeros of `q_1` and a
/// `Stop` where `q_1 / sin(π/3) = cos t` rises through `1/2` (`t = 5π/3`).
fn plan() -> Plan<'static> {
    let amplitude = shape()[0];
    Plan::until(T_END)
        .every(20)
        .save_at(SAVE.to_vec())
        .event(Event::new(|_t, q, _v| q[0]))
        .event(Event::new(move |_t, q, _v| q[0] / amplitude - 0.5).direction(Direction::Rising).action(Action::Stop))
}

fn scheme_cases() -> [(&'static str, Scheme); 3] {
    [
        ("midpoint", Scheme::MIDPOINT),
        ("trapezoid", Scheme::TRAPEZOID),
        ("yoshida 4", Scheme::composition(lagrangian::Composition::YOSHIDA4, OnePoint::Trapezoid)),
    ]
}

/// Every value of the table as bits.
fn bits(s: &Solution) -> Vec<u64> {
    let mut b: Vec<u64> = s.t.iter().chain(&s.energy).map(|x| x.to_bits()).collect();
    b.extend(s.step.iter().map(|k| k.map_or(u64::MAX, |k| k)));
    for rows in [&s.q, &s.p, &s.v] {
        b.extend(rows.as_flat().iter().map(|x| x.to_bits()));
    }
    b
}

#[test]
fn a_run_time_sized_chain_solves_as_a_compile_time_sized_one() {
    let pi = std::f64::consts::PI;
    let shape = shape();
    let dynamic = Problem::new(ChainDyn { n: 8 }, 0.0, shape.to_vec(), vec![0.0; 8]);
    let compiled = Problem::new(Chain, 0.0, shape, [0.0; 8]);
    for (name, scheme) in scheme_cases() {
        let mut sim = dynamic.stepper(&scheme, H).unwrap();
        let sol = sim.solve(plan()).unwrap().into_result().unwrap();
        assert_eq!(sol.width(), 8);

        // The stop at 5π/3, where the stepper is, on a node of its own.
        let t_stop = 5.0 * pi / 3.0;
        assert_eq!(sol.status, Status::Stopped { event: 1, t: *sol.t.last().unwrap() }, "{name}");
        assert!((sol.t.last().unwrap() - t_stop).abs() < 1e-4, "{name}: stop at {}", sol.t.last().unwrap());
        assert_eq!(sim.state().t, *sol.t.last().unwrap(), "{name}");
        assert_eq!(sol.q.last().unwrap(), &sim.state().q[..], "{name}: the last row is the stepper's node");

        // The records at π/2 and 3π/2, then the stop.
        let records: Vec<f64> = sol.events.iter().filter(|e| e.event == 0).map(|e| e.t).collect();
        assert_eq!(records.len(), 2, "{name}: {records:?}");
        for (t, exact) in records.iter().zip([pi / 2.0, 1.5 * pi]) {
            assert!((t - exact).abs() < 1e-4, "{name}: record at {t} against {exact}");
        }
        assert_eq!(sol.events.last().map(|e| e.event), Some(1));
        assert!(sol.events[0].q[0].abs() < 1e-12, "{name}: g = 0 on the dense output at the record");

        // Every 20th node, the save times interpolated, against q_i = sin(πi/3) cos t.
        let nodes: Vec<u64> = sol.step.iter().flatten().copied().collect();
        assert!(nodes[..nodes.len() - 1].iter().all(|k| k % 20 == 0), "{name}: {nodes:?}");
        let saved: Vec<usize> = (0..sol.len()).filter(|&i| sol.step[i].is_none()).collect();
        let times: Vec<f64> = saved.iter().map(|&i| sol.t[i]).collect();
        assert_eq!(times, SAVE, "{name}: the save times before the stop");
        let mut error = 0.0f64;
        for &i in &saved {
            let t = sol.t[i];
            for j in 0..8 {
                error = error.max((sol.q[i][j] - shape[j] * t.cos()).abs());
                error = error.max((sol.v[i][j] + shape[j] * t.sin()).abs());
                // ∂L/∂v = v for this chain.
                error = error.max((sol.p[i][j] - sol.v[i][j]).abs());
            }
        }
        assert!(error < 1e-4, "{name}: dense output error {error:e}");
        let energy = 0.5 * shape.iter().map(|x| x * x).sum::<f64>();
        assert!(sol.energy.iter().all(|e| (e - energy).abs() < 1e-4), "{name}: E_L is the mode's energy");

        // CSV and JSON bit for bit.
        let mut csv = Vec::new();
        sol.write_csv(&mut csv).unwrap();
        let back = Solution::read_csv(csv.as_slice()).unwrap();
        assert_eq!((back.width(), bits(&back)), (8, bits(&sol)), "{name}: csv");
        let mut json = Vec::new();
        sol.write_json(&mut json).unwrap();
        let back = Solution::read_json(json.as_slice()).unwrap();
        assert_eq!(bits(&back), bits(&sol), "{name}: json");
        assert_eq!(back.events, sol.events, "{name}: json events");

        // The same rows at a compile-time size, to round-off.
        let same = compiled.solve(&scheme, H, plan()).unwrap().into_result().unwrap();
        assert_eq!(same.step, sol.step, "{name}: the same nodes at both sizes");
        let largest = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        let gap = [(&same.q, &sol.q), (&same.p, &sol.p), (&same.v, &sol.v)]
            .iter()
            .map(|(a, b)| largest(a.as_flat(), b.as_flat()))
            .fold(largest(&same.t, &sol.t), f64::max);
        assert!(gap < 1e-12, "{name}: compile-time and run-time rows differ by {gap:e}");
        assert_eq!(same.events.len(), sol.events.len());
        println!("{name}: {} rows, dense output error {error:.1e}, rows within {gap:.1e} of compile-time", sol.len());
    }
}

/// What the run-time size does not have is refused before the run, and a
/// failed plan leaves the stepper where it was.
#[test]
fn quintic_dense_output_is_refused_at_a_run_time_size() {
    let problem = Problem::new(ChainDyn { n: 8 }, 0.0, shape().to_vec(), vec![0.0; 8]);
    let mut sim = problem.stepper(&Scheme::MIDPOINT, H).unwrap();
    let err = sim.solve(Plan::until(1.0).save_at(vec![0.5]).dense(DenseKind::Quintic)).unwrap_err();
    assert!(matches!(err, SolveError::InvalidPlan { .. }), "{err}");
    assert_eq!(sim.state().step, 0);
    let err = sim.solve(Plan::until(-1.0)).unwrap_err();
    assert!(matches!(err, SolveError::InvalidEnd { .. }), "{err}");
    // The cubic is the run-time size's own.
    let sol = sim.solve(Plan::until(1.0).every(0).save_at(vec![0.5]).dense(DenseKind::Cubic)).unwrap();
    assert_eq!((sol.len(), sol.t[0]), (1, 0.5));
}

/// A chain whose masses are coupled, `T = Σ ½v_i² + μ Σ v_i v_{i+1}`: a
/// constant, tridiagonal mass matrix, so the velocity of a node is a banded
/// solve with the factored `M`.
#[derive(Clone)]
struct CoupledMasses {
    n: usize,
}

/// The velocity coupling `μ` of [`CoupledMasses`] (`M` stays positive
/// definite for `|μ| < ½`).
const MU: f64 = 0.2;

#[lagrangian]
impl CoupledMasses {
    fn dimension(&self) -> usize {
        self.n
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        let n = q.len();
        let mut kinetic = 0.0;
        for i in 0..n {
            kinetic += 0.5 * v[i] * v[i];
        }
        for i in 0..n - 1 {
            kinetic += MU * v[i] * v[i + 1];
        }
        let mut potential = 0.0;
        for i in 0..n {
            potential += 0.5 * q[i] * q[i] + 0.25 * q[i] * q[i] * q[i] * q[i];
        }
        kinetic - potential
    }
}

/// The velocity of a node on a system with a constant mass matrix (the
/// explicit path's factored `M`, at unit masses and coupled ones): its
/// momentum `M v` is the node's `p` to round-off, and the chain's velocity
/// is what the same chain gives at a compile-time size.
#[test]
fn the_velocity_of_a_constant_mass_system_inverts_its_momentum() {
    let n = 12;
    let q0: Vec<f64> = (0..n).map(|i| 0.3 * (0.7 * i as f64).sin()).collect();
    let problem = Problem::new(CoupledMasses { n }, 0.0, q0.clone(), vec![0.1; n]);
    let mut sim = problem.stepper(&Scheme::TRAPEZOID, 0.05).unwrap();
    sim.run(40, |_| {}).unwrap();
    let v = sim.velocity().unwrap();
    let p = &sim.state().p;
    for i in 0..n {
        let left = if i > 0 { v[i - 1] } else { 0.0 };
        let right = if i + 1 < n { v[i + 1] } else { 0.0 };
        let momentum = v[i] + MU * (left + right);
        assert!(
            (momentum - p[i]).abs() <= 1e-15 * (1.0 + p[i].abs()),
            "coordinate {i}: M v = {momentum}, p = {}",
            p[i]
        );
    }

    // At both sizes, and at a compile-time size in both modes (reverse mode
    // keeps the factored mass matrix; forward mode inverts by Newton).
    let shape = shape();
    let mut dynamic =
        Problem::new(ChainDyn { n: 8 }, 0.0, shape.to_vec(), vec![0.0; 8]).stepper(&Scheme::TRAPEZOID, H).unwrap();
    dynamic.run(100, |_| {}).unwrap();
    let b = dynamic.velocity().unwrap();
    for derivatives in [Derivatives::Forward, Derivatives::Reverse] {
        let mut compiled =
            Integrator::new(Chain, Trapezoid, H).derivatives(derivatives).start(0.0, shape, [0.0; 8]).unwrap();
        compiled.run(100, |_| {}).unwrap();
        let a = compiled.velocity().unwrap();
        let gap = a.iter().zip(&b).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        assert!(gap <= 1e-15, "{derivatives:?}: velocities at both sizes differ by {gap:e}");
        let momentum = compiled.state().p;
        assert_eq!(a, momentum, "{derivatives:?}: unit masses, v = p");
    }
}

/// `clone_from` into an integrator that has taken other steps makes it the
/// source's twin: both then take bit-identical steps (the copy that `solve`
/// refreshes before every step when it may have to go back). The driver's
/// own `clone_from`, under both summations, so it is named directly.
#[test]
fn clone_from_makes_a_run_time_integrator_its_sources_twin() {
    use lagrangian_runtime::DynIntegrator;
    let n = 12;
    let q0: Vec<f64> = (0..n).map(|i| 0.3 * (0.7 * i as f64).sin()).collect();
    for plain in [false, true] {
        let summation = if plain { Summation::Plain } else { Summation::Compensated };
        let start = |h: f64| {
            DynIntegrator::new(CoupledMasses { n }, Trapezoid, h).summation(summation).start(0.0, &q0, &vec![0.1; n])
        };
        let mut source = start(0.05).unwrap();
        source.run(25, |_| {}).unwrap();
        let mut twin = start(0.01).unwrap();
        twin.run(7, |_| {}).unwrap();
        twin.clone_from(&source);
        source.run(30, |_| {}).unwrap();
        twin.run(30, |_| {}).unwrap();
        assert_eq!(source.state(), twin.state(), "plain sums: {plain}");
        assert_eq!(source.velocity().unwrap(), twin.velocity().unwrap());
        assert_eq!(source.discrete_energy().to_bits(), twin.discrete_energy().to_bits());
    }
}
