//! A fixed number of midpoint steps of a damped and driven FPU-β chain
//! sized at run time, for instruction counts of the forced reverse-mode
//! step at `N = 1e3, 1e4, 1e5` that do not depend on the load of the
//! machine: (instructions of `2s` steps − of `s`) / `s` under
//! `valgrind --tool=callgrind` is the steady step.
//!
//! ```text
//! cargo build --release -p lagrangian-bench --example damped_chain_steps
//! valgrind --tool=callgrind target/release/examples/damped_chain_steps damped 10000 4
//! ```
//!
//! `CASE N STEPS`, `h = 0.05`, run in a thread with the default 2 MiB
//! stack. Cases: `undamped` (the chain alone, the baseline), `damped` (the
//! macro's Rayleigh function `½γ Σ v_i² + ½κ Σ (v_{i+1} − v_i)²` over
//! slices), `driven` (the same and a force `Q_i = −μ v_i³`, `Q_0 += a cos
//! Ωt`, written by hand over the macro's chain: bandwidth 0 in `q`, 1 in
//! `v` with the dissipation), and `damped-balance`, `driven-balance`: the
//! same systems under energy-balance steps from `h` (the first step of
//! the given size among the `s`).
#![allow(missing_docs)]

use std::hint::black_box;

use lagrangian::prelude::*;
use lagrangian::{Coupling, ForceCoupling, Pattern, Scalar, Separability};
use lagrangian_bench::chain::{BETA, start_q};
use lagrangian_runtime::DynIntegrator;

const H: f64 = 0.05;

/// The FPU-β chain with dampers on the masses and between neighbours.
#[derive(Clone, Copy, Debug)]
pub struct DampedFpu {
    pub n: usize,
}

#[lagrangian]
impl DampedFpu {
    fn dimension(&self) -> usize {
        self.n
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        let n = q.len();
        let mut kinetic = 0.0;
        for i in 0..n {
            kinetic += 0.5 * v[i] * v[i];
        }
        let mut d = q[0];
        let mut potential = 0.5 * d * d + 0.25 * BETA * d.powi(4);
        for i in 0..n - 1 {
            d = q[i + 1] - q[i];
            potential += 0.5 * d * d + 0.25 * BETA * d.powi(4);
        }
        d = q[n - 1];
        potential += 0.5 * d * d + 0.25 * BETA * d.powi(4);
        kinetic - potential
    }

    fn dissipation(&self, _q: &[f64], v: &[f64]) -> f64 {
        let mut r = 0.0;
        for i in 0..v.len() {
            r += 0.05 * v[i] * v[i];
        }
        for i in 0..v.len() - 1 {
            let d = v[i + 1] - v[i];
            r += 0.01 * d * d;
        }
        r
    }
}

/// [`DampedFpu`] driven: its generated `L`, gradient code and dissipation,
/// and a force written by hand.
#[derive(Clone, Copy, Debug)]
pub struct DrivenFpu(pub DampedFpu);

impl DynLagrangian for DrivenFpu {
    const AUTONOMOUS: bool = <DampedFpu as DynLagrangian>::AUTONOMOUS;
    const SEPARABILITY: Separability = <DampedFpu as DynLagrangian>::SEPARABILITY;
    const COUPLING: Coupling = <DampedFpu as DynLagrangian>::COUPLING;
    const FORCE_COUPLING: ForceCoupling = ForceCoupling { q: Pattern::Diagonal, v: Pattern::Banded { bandwidth: 1 } };
    const HAS_DISSIPATION: bool = true;
    const HAS_FORCE: bool = true;
    const HAS_GRADIENT: bool = <DampedFpu as DynLagrangian>::HAS_GRADIENT;
    const HAS_GRADIENT_QV: bool = <DampedFpu as DynLagrangian>::HAS_GRADIENT_QV;

    fn dimension(&self) -> usize {
        self.0.n
    }

    fn lagrangian<D: Scalar>(&self, t: D, q: &[D], v: &[D]) -> D {
        DynLagrangian::lagrangian(&self.0, t, q, v)
    }

    fn gradient_q(&self, t: f64, q: &[f64], v: &[f64], out: &mut [f64]) {
        self.0.gradient_q(t, q, v, out);
    }

    fn value_gradient_q(&self, t: f64, q: &[f64], v: &[f64], out: &mut [f64]) -> f64 {
        self.0.value_gradient_q(t, q, v, out)
    }

    fn gradient_qv_scalar<D: Scalar>(&self, t: D, q: &[D], v: &[D], out_q: &mut [D], out_v: &mut [D]) {
        self.0.gradient_qv_scalar(t, q, v, out_q, out_v);
    }

    fn dissipation<D: Scalar>(&self, q: &[D], v: &[D]) -> D {
        DynLagrangian::dissipation(&self.0, q, v)
    }

    fn force<D: Scalar>(&self, t: D, _q: &[D], v: &[D], f: &mut [D]) {
        for (f, &v) in f.iter_mut().zip(v) {
            *f = -(v * v * v * 0.1);
        }
        f[0] += (t * 1.3).cos() * 0.3;
    }
}

/// `steps` midpoint steps of `system` from the bench chain's start, fixed
/// or energy-balance steps.
fn run<S: DynLagrangian>(system: S, n: usize, steps: usize, balance: bool) {
    let mut builder = DynIntegrator::new(system, Midpoint, H);
    if balance {
        builder = builder.energy_preserving(lagrangian::StepBounds::around(H));
    }
    let mut sim = builder.start(0.0, &start_q(n), &vec![0.0; n]).expect("start");
    sim.run(steps, |_| {}).expect("steps");
    black_box(sim.state().q[0]);
    eprintln!("{} Newton iterations in {} steps", sim.stats().newton_iterations, sim.stats().steps);
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let [_, case, n, steps] = &args[..] else {
        panic!("usage: damped_chain_steps undamped|damped|driven|damped-balance|driven-balance N STEPS");
    };
    let (case, n, steps) = (case.clone(), n.parse::<usize>().expect("N"), steps.parse::<usize>().expect("STEPS"));
    // The default 2 MiB stack of a spawned thread.
    std::thread::spawn(move || match case.as_str() {
        // The same chain through a Rayleigh function of zero.
        "undamped" => run(lagrangian_bench::chain::DynFpu(n), n, steps, false),
        "damped" => run(DampedFpu { n }, n, steps, false),
        "driven" => run(DrivenFpu(DampedFpu { n }), n, steps, false),
        "damped-balance" => run(DampedFpu { n }, n, steps, true),
        "driven-balance" => run(DrivenFpu(DampedFpu { n }), n, steps, true),
        _ => panic!("unknown case {case}"),
    })
    .join()
    .expect("the run");
}
