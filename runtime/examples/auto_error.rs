//! The tolerance-driven solve on two of the report's problems written by
//! hand (the double pendulum from `(1, −0.5)` rad over `t = 10`, the
//! electromechanical sensor over `t = 2`), with the true error along the
//! whole run: every node against a Galerkin `s = 8` run at a sixteenth of
//! the solve's step. One line per tolerance: the method, the pilot's and
//! the final run's steps, the step, the estimate and the error asked for,
//! the error at the end and the largest along the run, and the growth the
//! pilot measured.
//!
//! ```text
//! cargo run --release -p lagrangian-runtime --example auto_error -- double-pendulum 1e-3 1e-4
//! cargo run --release -p lagrangian-runtime --example auto_error -- sensor 1e-3 1e-6
//! ```
#![allow(missing_docs)]

use lagrangian_runtime::auto::{Auto, Tolerance};
use lagrangian_runtime::{Galerkin, Integrator, Lagrangian, Plan, Scalar, Stepping};

/// `m = (1, 1.5)`, `l = (1, 0.7)`, `g = 9.81`.
#[derive(Clone)]
struct DoublePendulum;
impl Lagrangian<2> for DoublePendulum {
    const AUTONOMOUS: bool = true;
    const CYCLIC: [bool; 2] = [false, false];
    fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 2], v: [D; 2]) -> D {
        let (m1, m2, l1, l2, g) = (1.0, 1.5, 1.0, 0.7, 9.81);
        let kinetic = v[0] * v[0] * (0.5 * (m1 + m2) * l1 * l1)
            + v[1] * v[1] * (0.5 * m2 * l2 * l2)
            + v[0] * v[1] * (q[0] - q[1]).cos() * (m2 * l1 * l2);
        let potential = -(q[0].cos() * ((m1 + m2) * g * l1)) - q[1].cos() * (m2 * g * l2);
        kinetic - potential
    }
}

/// Armature `x` on a spring, charge through the inductance `L0/(1 + x/a)`,
/// a resistor `r = 10` and a battery `E = 12`.
#[derive(Clone)]
struct Sensor;
impl Lagrangian<2> for Sensor {
    const AUTONOMOUS: bool = true;
    const CYCLIC: [bool; 2] = [false, false];
    const HAS_FORCE: bool = true;
    const HAS_DISSIPATION: bool = true;
    fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 2], v: [D; 2]) -> D {
        let (m, k, g, l0, a) = (0.2, 80.0, 9.81, 0.5, 0.2);
        let x = q[0];
        let inductance = (x * (1.0 / a) + 1.0).recip() * l0;
        v[0] * v[0] * (0.5 * m) + inductance * v[1] * v[1] * 0.5 - x * x * (0.5 * k) + x * (m * g)
    }
    fn dissipation<D: Scalar>(&self, _q: [D; 2], v: [D; 2]) -> D {
        v[1] * v[1] * 5.0
    }
    fn force<D: Scalar>(&self, _t: D, _q: [D; 2], _v: [D; 2]) -> [D; 2] {
        [D::zero(), D::zero() + 12.0]
    }
}

fn report<S: Lagrangian<2> + Clone>(name: &str, system: S, q0: [f64; 2], v0: [f64; 2], t_end: f64, rtol: f64) {
    let solved =
        match Auto::new(system.clone(), 0.0, q0, v0).tolerance(Tolerance::relative(rtol)).solve(Plan::until(t_end)) {
            Ok(s) => s,
            Err(e) => {
                println!("{name} rtol {rtol:.2e}: {e}");
                return;
            }
        };
    let (e, s) = (&solved.estimate, &solved.solution);
    if let Some(err) = &s.error {
        println!("{name} rtol {rtol:.2e}: {}, the final run failed: {err}", e.method_name);
        return;
    }
    // The reference's nodes `16 k` are the solve's nodes `k`.
    let fine = 16;
    let reference = Integrator::new(system, Galerkin::<8, 8>::gauss(), e.step / fine as f64)
        .start(0.0, q0, v0)
        .ok()
        .and_then(|mut it| it.solve(Plan::until(t_end)).ok());
    let Some(reference) = reference else {
        println!("{name} rtol {rtol:.2e}: the reference run failed");
        return;
    };
    let n = s.t.len() - 1;
    let error = |k: usize| {
        let (a, b) = (&s.q[k], &reference.q[(k * fine).min(reference.q.len() - 1)]);
        (a[0] - b[0]).abs().max((a[1] - b[1]).abs())
    };
    let largest = (1..=n).map(error).fold(0.0f64, f64::max);
    println!(
        "{name} rtol {rtol:.2e}: {}, pilot {} + final {} steps, step {:.4e}, estimate {:.2e} of {:.2e} asked (scale {:.3}), \
         error at the end {:.2e}, largest {largest:.2e} (estimate / largest {:.2}), growth {:?}",
        e.method_name,
        e.pilot.steps,
        n,
        e.step,
        e.error,
        e.requested,
        e.scale,
        error(n),
        e.error / largest,
        e.growth
    );
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: auto_error double-pendulum|sensor RTOL...";
    let (Some(problem), rtols) = (args.first(), &args[1.min(args.len())..]) else {
        eprintln!("{usage}");
        std::process::exit(2);
    };
    for rtol in rtols {
        let Ok(rtol) = rtol.parse::<f64>() else {
            eprintln!("{usage}");
            std::process::exit(2);
        };
        match problem.as_str() {
            "double-pendulum" => report(problem, DoublePendulum, [1.0, -0.5], [0.0, 0.5], 10.0, rtol),
            "sensor" => report(problem, Sensor, [0.0, 0.0], [0.0, 0.0], 2.0, rtol),
            _ => {
                eprintln!("{usage}");
                std::process::exit(2);
            }
        }
    }
}
