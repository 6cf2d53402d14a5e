//! A chain of 10 000 planar links in Cartesian coordinates (N = 20 000
//! coordinates, M = 10 000 constraints) under `DynConstrained`, whose
//! saddle-point systems are banded: stepped in a spawned thread with the
//! default 2 MiB stack, the constraints and their hidden form at
//! round-off at every node. The cost per step against the number of links
//! is `cargo bench -p lagrangian-bench --bench constrained` (group
//! "hanging chain").

use lagrangian::prelude::*;

#[path = "../common/links.rs"]
mod links;

use links::{Links, folded, max_abs};

#[test]
fn a_chain_of_ten_thousand_links_runs_in_a_default_thread_with_its_constraints_at_round_off() {
    let run = std::thread::Builder::new()
        .stack_size(2 << 20)
        .spawn(|| {
            let n = 10_000;
            let q0 = folded(n, 0.01);
            let mut sim = DynConstrained::start(Links(n), Midpoint, 1e-3, 0.0, &q0, &vec![0.0; 2 * n]).expect("start");
            let e0 = sim.energy();
            let (mut g_worst, mut gv_worst) = (0.0f64, 0.0f64);
            sim.run(50, |s| {
                g_worst = s.constraint_values().iter().fold(g_worst, |m, x| m.max(x.abs()));
                let speed = max_abs(s.velocity());
                gv_worst = s.constraint_velocities().iter().fold(gv_worst, |m, x| m.max(x.abs() / speed));
            })
            .expect("steps");
            let moved = sim.state().q.iter().zip(&q0).fold(0.0f64, |m, (a, b)| m.max((a - b).abs()));
            let energy_error = (sim.energy() - e0).abs() / e0.abs();
            (g_worst, gv_worst, max_abs(&sim.state().q), moved, energy_error, sim.saddle_point_bandwidth())
        })
        .unwrap()
        .join()
        .expect("the run in a 2 MiB thread");
    let (g, gv, q_max, moved, energy_error, bandwidth) = run;
    println!(
        "10 000 links, 50 steps of 1e-3: max |g| {g:.2e} (positions up to {q_max:.0}), max |G v|/|v| {gv:.2e}, joints moved up to {moved:.2e}, relative energy error {energy_error:.2e}, saddle-point bandwidth {bandwidth}"
    );
    // The chain moves (the test checks a motion, not a chain at rest).
    assert!(moved > 1e-6, "largest displacement {moved:e}");
    // `g = |Δx|² − 1` from coordinates of size up to 100: the round-off of
    // the coordinates alone is `ε·|q|`, 2.2e-14 here.
    assert!(g <= 8.0 * f64::EPSILON * q_max, "max |g| = {g:e}");
    assert!(gv <= 1e-13, "max |G v| / |v| = {gv:e}");
    assert!(bandwidth <= 3, "saddle-point bandwidth {bandwidth}");
    assert!(energy_error < 1e-6, "relative energy error {energy_error:e}");
}
