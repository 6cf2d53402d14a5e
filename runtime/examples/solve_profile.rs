//! `solve` on the pendulum with the midpoint rule (`h = 0.01`), for
//! instruction counts of its driver: `solve_profile KIND STEPS` with `KIND`
//! `rows` (every node a row, with velocity and energy), `thin` (every 100th
//! node, no velocities) or `save` (no nodes, a save time every 10 steps).
//! Per step: (instructions of `STEPS` steps − of none) / `STEPS` under
//! `valgrind --tool=callgrind`.
//!
//! ```text
//! cargo build --release -p lagrangian-runtime --example solve_profile
//! valgrind --tool=callgrind target/release/examples/solve_profile rows 20000
//! ```
use lagrangian_runtime::{Integrator, Lagrangian, Midpoint, Plan, Scalar, Stepping};

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

/// Runs the plan `KIND` for `STEPS` steps and prints the rows and the last `q`.
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let plan_kind = args[1].as_str();
    let steps: usize = args[2].parse().unwrap();
    let h = 0.01;
    let mut sim = Integrator::new(Pendulum, Midpoint, h).start(0.0, [1.0], [0.0]).unwrap();
    let t_end = h * steps as f64 + 0.5 * h;
    let plan = match plan_kind {
        "rows" => Plan::until(t_end),
        "thin" => Plan::until(t_end).every(100).without_velocities(),
        "save" => Plan::until(t_end).every(0).save_at((0..steps / 10).map(|k| k as f64 * 10.0 * h + 0.003).collect()),
        _ => panic!("rows | thin | save"),
    };
    let sol = sim.solve(plan).unwrap();
    println!("{} {}", sol.len(), sol.q.last().map_or(0.0, |q| q[0]));
}
