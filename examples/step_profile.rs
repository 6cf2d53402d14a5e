//! A fixed number of steps of one benchmark case, for instruction counts that
//! do not depend on the load of the machine:
//!
//! ```text
//! cargo build --release --example step_profile
//! valgrind --tool=callgrind target/release/examples/step_profile "double pendulum" midpoint 20000
//! ```
//!
//! Cases: `pendulum` or `double pendulum`; methods: `midpoint`, `trapezoid`,
//! `variable` (energy-preserving midpoint, from the start of the bench's
//! variable-step group), `damped` (double pendulum with joint friction, a
//! forced step), `energy` (a midpoint step and `Integrator::energy` after it), `hand` (the hand-written midpoint of the bench) or
//! `derivatives` (one `step_derivatives` evaluation per "step", nothing else); `verlet` (the bench's hand-written Störmer–Verlet, pendulum only).
//! It prints the wall-clock ns per step; `/usr/bin/time -f %U` gives CPU time,
//! which is steadier on a shared machine.
#![allow(missing_docs)]

#[path = "../tests/common/mod.rs"]
mod common;
#[path = "../bench/src/handwritten.rs"]
mod handwritten;

use common::{DOUBLE_PENDULUM as DP, DoublePendulum, PENDULUM as P, Pendulum};
use handwritten::*;
use lagrangian::derivatives::step_derivatives;
use lagrangian::{Integrator, Midpoint, Segment, StepBounds, Trapezoid};
use std::hint::black_box;

const H: f64 = 0.01;

/// The double pendulum of the tests with joint friction: a forced (Lagrange–d'Alembert) step.
struct DampedDoublePendulum {
    p: DoublePendulum,
    c: f64,
}

#[lagrangian::lagrangian]
impl DampedDoublePendulum {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let (m1, m2, l1, l2, g) = (self.p.m1, self.p.m2, self.p.l1, self.p.l2, self.p.g);
        let kinetic = 0.5 * (m1 + m2) * l1 * l1 * v[0] * v[0]
            + 0.5 * m2 * l2 * l2 * v[1] * v[1]
            + m2 * l1 * l2 * v[0] * v[1] * (q[0] - q[1]).cos();
        kinetic + (m1 + m2) * g * l1 * q[0].cos() + m2 * g * l2 * q[1].cos()
    }

    fn dissipation(&self, _q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * self.c * (v[0] * v[0] + (v[1] - v[0]) * (v[1] - v[0]))
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let (case, method, n) = (args[1].as_str(), args[2].as_str(), args[3].parse::<usize>().unwrap());
    let start = std::time::Instant::now();
    let q = match (case, method) {
        ("pendulum", "hand") => {
            let mut s = PendulumMidpoint::new(PendulumParams { a: P.m * P.l * P.l, d: P.m * P.g * P.l }, H, 1.0, 0.0);
            (0..n).for_each(|_| s.step().unwrap());
            vec![s.q]
        }
        ("pendulum", "verlet") => {
            let params = PendulumParams { a: P.m * P.l * P.l, d: P.m * P.g * P.l };
            let mut s = PendulumVerlet { s: params, h: H, q: 1.0, p: 0.0 };
            (0..n).for_each(|_| s.step());
            vec![s.q]
        }
        ("pendulum", "midpoint") => run(Integrator::new(Pendulum { ..P }, Midpoint, H).start(0.0, [1.0], [0.0]), n),
        ("pendulum", "trapezoid") => run(Integrator::new(Pendulum { ..P }, Trapezoid, H).start(0.0, [1.0], [0.0]), n),
        ("pendulum", "variable") => run(
            Integrator::new(Pendulum { ..P }, Midpoint, H).energy_preserving(StepBounds::around(H)).start(
                0.0,
                [1.0],
                [0.0],
            ),
            n,
        ),
        ("double pendulum", "hand") => {
            let p = DoubleParams {
                a: (DP.m1 + DP.m2) * DP.l1 * DP.l1,
                b: DP.m2 * DP.l2 * DP.l2,
                c: DP.m2 * DP.l1 * DP.l2,
                d: (DP.m1 + DP.m2) * DP.g * DP.l1,
                e: DP.m2 * DP.g * DP.l2,
            };
            let mut s = DoubleStepper::new(p, DoubleMethod::Midpoint, H, [1.0, -0.5], [0.0, 0.5]);
            (0..n).for_each(|_| s.step().unwrap());
            s.q.to_vec()
        }
        ("double pendulum", "midpoint") => {
            run(Integrator::new(DoublePendulum { ..DP }, Midpoint, H).start(0.0, [1.0, -0.5], [0.0, 0.5]), n)
        }
        ("double pendulum", "trapezoid") => {
            run(Integrator::new(DoublePendulum { ..DP }, Trapezoid, H).start(0.0, [1.0, -0.5], [0.0, 0.5]), n)
        }
        ("double pendulum", "variable") => run(
            Integrator::new(DoublePendulum { ..DP }, Midpoint, H).energy_preserving(StepBounds::around(H)).start(
                0.0,
                [0.5, 0.3],
                [0.0, 0.0],
            ),
            n,
        ),
        (_, "derivatives") => {
            // The derivative evaluation alone: one `step_derivatives` (residual
            // part, momentum, Jacobian) per "step", at nearby segments (every input
            // varies, so that nothing is hoisted out of the loop).
            let mut acc = 0.0;
            for k in 0..n {
                let x = black_box(1e-9 * k as f64);
                acc += if case == "pendulum" {
                    let seg = Segment { t0: 0.0, h: H, q0: [1.0 + x], dq: [0.001 + x] };
                    step_derivatives(&Pendulum { ..P }, &Midpoint, &seg).d2_q0_q1[0]
                } else {
                    let seg = Segment { t0: 0.0, h: H, q0: [1.0 + x, -0.5 - x], dq: [0.001 + x, 0.002 - x] };
                    step_derivatives(&DoublePendulum { ..DP }, &Midpoint, &seg).d2_q0_q1[(0, 1)]
                };
            }
            vec![acc]
        }
        ("double pendulum", "energy") => {
            // A step and the energy readout `E_L(q_k, v(p_k))` (inverse Legendre transform) after each.
            let mut sim =
                Integrator::new(DoublePendulum { ..DP }, Midpoint, H).start(0.0, [1.0, -0.5], [0.0, 0.5]).unwrap();
            let mut e = 0.0;
            for _ in 0..n {
                sim.step().unwrap();
                e += sim.energy().unwrap();
            }
            vec![e]
        }
        ("double pendulum", "damped") => run(
            Integrator::new(DampedDoublePendulum { p: DoublePendulum { ..DP }, c: 0.05 }, Midpoint, H).start(
                0.0,
                [1.0, -0.5],
                [0.0, 0.5],
            ),
            n,
        ),
        _ => panic!("unknown case {case:?} {method:?}"),
    };
    let ns = start.elapsed().as_nanos() as f64 / n.max(1) as f64;
    println!("{ns:.1} ns/step, q = {:?}", black_box(q));
}

fn run<S: lagrangian::Lagrangian<N>, M: lagrangian::DiscreteLagrangian, const N: usize>(
    sim: Result<lagrangian::Integrator<S, M, N>, lagrangian::Error<N>>,
    n: usize,
) -> Vec<f64> {
    let mut sim = sim.unwrap();
    for _ in 0..n {
        black_box(sim.step().unwrap());
    }
    let s = sim.stats();
    eprintln!("newton iterations per step: {:.3}", s.newton_iterations as f64 / s.steps as f64);
    sim.state().q.to_vec()
}
