//! `solve` on the pendulum with the midpoint rule (`h = 0.01`), for
//! instruction counts of its driver: `solve_profile KIND STEPS` with `KIND`
//! `rows` (every node a row, with velocity and energy), `thin` (every 100th
//! node, no velocities) or `save` (no nodes, a save time every 10 steps).
//! Per step: (instructions of `STEPS` steps − of none) / `STEPS` under
//! `valgrind --tool=callgrind`.
//!
//! The `dyn-` kinds take explicit trapezoid (Störmer–Verlet) steps of a
//! run-time-sized FPU-β chain of 1 000 masses (`h = 0.05`): `dyn-run`
//! without `solve`, `dyn-thin` through `solve` with a row every 100 steps,
//! and `dyn-event` the same with an event function that does not fire, for
//! which the driver refreshes a copy of the integrator before every step.
//! `const-run` and `const-event` take the same steps with the size known at
//! compile time, in reverse mode.
//!
//! ```text
//! cargo build --release -p lagrangian-runtime --example solve_profile
//! valgrind --tool=callgrind target/release/examples/solve_profile rows 20000
//! ```
use lagrangian_runtime::{
    Coupling, Derivatives, DynIntegrator, DynLagrangian, Event, Integrator, Lagrangian, Midpoint, Pattern, Plan,
    RunTimeStepping, Scalar, Separability, Stepping, Trapezoid,
};

/// `L = ½v² + g cos q`.
#[derive(Clone)]
struct Pendulum;
impl Lagrangian<1> for Pendulum {
    const AUTONOMOUS: bool = true;
    const CYCLIC: [bool; 1] = [false];
    fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 1], v: [D; 1]) -> D {
        v[0] * v[0] * 0.5 + q[0].cos() * 9.81
    }
}

/// The FPU-β chain with fixed ends, `L = ½|v|² − Σ (½r² + ¼β r⁴)` over the
/// bonds `r`, written by hand over slices (`β = 1`).
#[derive(Clone)]
struct Chain(usize);
impl DynLagrangian for Chain {
    const AUTONOMOUS: bool = true;
    const SEPARABILITY: Separability = Separability::ConstantMass;
    const COUPLING: Coupling =
        Coupling { q_q: Pattern::Banded { bandwidth: 1 }, q_v: Pattern::Diagonal, v_v: Pattern::Diagonal };
    fn dimension(&self) -> usize {
        self.0
    }
    fn lagrangian<D: Scalar>(&self, _t: D, q: &[D], v: &[D]) -> D {
        let bond = |r: D| r * r * 0.5 + r * r * r * r * 0.25;
        let n = q.len();
        let mut l = -bond(q[0]) - bond(-q[n - 1]);
        for i in 0..n {
            l += v[i] * v[i] * 0.5;
        }
        for i in 0..n - 1 {
            l -= bond(q[i + 1] - q[i]);
        }
        l
    }
}

/// [`Chain`] with its size known at compile time.
#[derive(Clone)]
struct ConstChain;
impl Lagrangian<1000> for ConstChain {
    const AUTONOMOUS: bool = true;
    const CYCLIC: [bool; 1000] = [false; 1000];
    const SEPARABILITY: Separability = Separability::ConstantMass;
    const COUPLING: Coupling =
        Coupling { q_q: Pattern::Banded { bandwidth: 1 }, q_v: Pattern::Diagonal, v_v: Pattern::Diagonal };
    fn lagrangian<D: Scalar>(&self, t: D, q: [D; 1000], v: [D; 1000]) -> D {
        Chain(1000).lagrangian(t, &q, &v)
    }
}

/// `STEPS` explicit steps of the run-time chain, through `solve` unless `kind`
/// is `dyn-run`.
fn chain(kind: &str, steps: usize) {
    let (n, h) = (1000, 0.05);
    let q0: Vec<f64> = (0..n).map(|i| 0.1 * (i as f64 * 0.01).sin()).collect();
    let mut sim = DynIntegrator::new(Chain(n), Trapezoid, h).start(0.0, &q0, &vec![0.0; n]).unwrap();
    let t_end = h * steps as f64 + 0.5 * h;
    let last = match kind {
        "dyn-run" => {
            sim.run(steps, |_| {}).unwrap();
            sim.state().q[0]
        }
        "dyn-thin" | "dyn-event" => {
            let mut plan = Plan::until(t_end).every(100).without_velocities();
            if kind == "dyn-event" {
                plan = plan.event(Event::new(|_t, q, _v| q[0] + 1e3));
            }
            let sol = sim.solve(plan).unwrap();
            sol.q.last().map_or(0.0, |q| q[0])
        }
        "const-run" | "const-event" => {
            let mut q = [0.0; 1000];
            q.copy_from_slice(&q0);
            let mut sim = Integrator::new(ConstChain, Trapezoid, h)
                .derivatives(Derivatives::Reverse)
                .start(0.0, q, [0.0; 1000])
                .unwrap();
            if kind == "const-run" {
                sim.run(steps, |_| {}).unwrap();
                sim.state().q[0]
            } else {
                let plan = Plan::until(t_end).every(100).without_velocities().event(Event::new(|_t, q, _v| q[0] + 1e3));
                let sol = sim.solve(plan).unwrap();
                sol.q.last().map_or(0.0, |q| q[0])
            }
        }
        _ => panic!("dyn-run | dyn-thin | dyn-event | const-run | const-event"),
    };
    println!("{last}");
}

/// Runs the plan `KIND` for `STEPS` steps and prints the rows and the last `q`.
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let plan_kind = args[1].as_str();
    let steps: usize = args[2].parse().unwrap();
    if plan_kind.starts_with("dyn-") || plan_kind.starts_with("const-") {
        chain(plan_kind, steps);
        return;
    }
    let h = 0.01;
    let mut sim = Integrator::new(Pendulum, Midpoint, h).start(0.0, [1.0], [0.0]).unwrap();
    let t_end = h * steps as f64 + 0.5 * h;
    let plan = match plan_kind {
        "rows" => Plan::until(t_end),
        "thin" => Plan::until(t_end).every(100).without_velocities(),
        "save" => Plan::until(t_end).every(0).save_at((0..steps / 10).map(|k| k as f64 * 10.0 * h + 0.003).collect()),
        _ => panic!("rows | thin | save | dyn-run | dyn-thin | dyn-event | const-run | const-event"),
    };
    let sol = sim.solve(plan).unwrap();
    println!("{} {}", sol.len(), sol.q.last().map_or(0.0, |q| q[0]));
}
