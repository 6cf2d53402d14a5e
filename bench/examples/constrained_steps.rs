//! A fixed number of constrained steps of one case, for instruction counts
//! that do not depend on the load of the machine (`bench/constrained-instructions.sh`
//! runs every case under `valgrind --tool=callgrind` and prints
//! (instructions of `n` steps − of none) / `n`):
//!
//! ```text
//! cargo build --release -p lagrangian-bench --example constrained_steps
//! valgrind --tool=callgrind target/release/examples/constrained_steps double-galerkin4 2000
//! ```
//!
//! Cases, each from the initial data of the report's problems, `h = 0.01`
//! unless a third argument gives it:
//! `pendulum-midpoint` (a unit pendulum on the unit circle, one constraint,
//! RATTLE midpoint) and `pendulum-angle-midpoint` (the same pendulum in its
//! angle, unconstrained midpoint); on the report's double pendulum
//! (`double-pendulum-cartesian`, two constraints) `double-midpoint`
//! (RATTLE midpoint), `double-galerkin2`, `double-galerkin3`,
//! `double-galerkin4` (`Constrained::galerkin` of `Galerkin::<s, s>::gauss()`),
//! `double-yoshida4`, `double-yoshida6`, `double-kahan-li8` (constrained
//! compositions of RATTLE trapezoid steps),
//! and the angle equations unconstrained: `double-angle-midpoint`,
//! `double-angle-galerkin4`. It prints the Newton iterations per step on
//! standard error.
#![allow(missing_docs)]

use lagrangian::Composition;
use lagrangian::prelude::*;
use lagrangian_bench::cartesian::{AnglePendulum, CartesianPendulum, system};
use lagrangian_bench::constrained::CartesianDoublePendulum;
use lagrangian_bench::problems::{DoublePendulum, Model};

/// `steps` steps of size `h` from `(q0, v0)`; prints the Newton iterations per step.
fn run<S: Lagrangian<N>, M: F64Readouts, const N: usize>(
    system: S,
    method: M,
    h: f64,
    (q0, v0): ([f64; N], [f64; N]),
    steps: usize,
) {
    let mut sim = Integrator::new(system, method, h).start(0.0, q0, v0).expect("start");
    sim.run(steps, |s| {
        std::hint::black_box(&s.state().q);
    })
    .expect("steps");
    let stats = sim.stats();
    eprintln!("Newton iterations per step: {:.2}", stats.newton_iterations as f64 / stats.steps.max(1) as f64);
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let usage = "usage: constrained_steps CASE STEPS [H]";
    let case = args.get(1).expect(usage).as_str();
    let steps: usize = args.get(2).and_then(|s| s.parse().ok()).expect(usage);
    let h: f64 = args.get(3).map_or(0.01, |s| s.parse().expect(usage));
    let theta = 1.0f64;
    let pendulum = ([theta.sin(), -theta.cos()], [0.0; 2]);
    let double = CartesianDoublePendulum { scale: 1.0 }.initial_state();
    let angles = DoublePendulum { scale: 1.0 };
    match case {
        "pendulum-midpoint" => run(CartesianPendulum, Constrained::<_, 1>::new(Midpoint), h, pendulum, steps),
        "pendulum-angle-midpoint" => run(AnglePendulum, Midpoint, h, ([theta], [0.0]), steps),
        "double-midpoint" => run(system(), Constrained::<_, 2>::new(Midpoint), h, double, steps),
        "double-galerkin2" => run(system(), Constrained::<_, 2>::galerkin(Galerkin::<2, 2>::gauss()), h, double, steps),
        "double-galerkin3" => run(system(), Constrained::<_, 2>::galerkin(Galerkin::<3, 3>::gauss()), h, double, steps),
        "double-galerkin4" => run(system(), Constrained::<_, 2>::galerkin(Galerkin::<4, 4>::gauss()), h, double, steps),
        "double-yoshida4" => run(system(), Constrained::<_, 2>::composition(Composition::YOSHIDA4), h, double, steps),
        "double-yoshida6" => run(system(), Constrained::<_, 2>::composition(Composition::YOSHIDA6), h, double, steps),
        "double-kahan-li8" => run(system(), Constrained::<_, 2>::composition(Composition::KAHAN_LI8), h, double, steps),
        "double-angle-midpoint" => run(angles.system(), Midpoint, h, angles.initial(), steps),
        "double-angle-galerkin4" => run(angles.system(), Galerkin::<4, 4>::gauss(), h, angles.initial(), steps),
        other => panic!("unknown case {other}; {usage}"),
    }
}
