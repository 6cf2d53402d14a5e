//! Peak memory of a run-time-sized FPU-β chain: `N` masses (default
//! 100 000, or the first argument), 3 midpoint steps (banded Newton) and 10
//! explicit trapezoid steps through `Problem`/`Stepper`, printing the energy
//! error, the time per step and the process's peak resident memory
//! (`VmHWM`, Linux) after each stage.
//!
//! The chain is written through `#[lagrangian]` over slices, so the macro
//! writes its gradient code and Newton steps take their derivatives from it
//! on dual numbers; with `tape` as the second argument the same chain is
//! written by hand (no gradient code), and every derivative comes from the
//! tape.
//!
//! `cargo run --release --example chain_memory [N] [tape]`
use std::time::Instant;

use lagrangian::prelude::*;
use lagrangian::{Coupling, Pattern, Separability};

/// The FPU-β chain (β = 1) through the macro.
#[derive(Clone)]
struct Generated(usize);

#[lagrangian]
impl Generated {
    fn dimension(&self) -> usize {
        self.0
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        let n = q.len();
        let mut kinetic = 0.0;
        for i in 0..n {
            kinetic += 0.5 * v[i] * v[i];
        }
        let mut d = q[0];
        let mut potential = 0.5 * d * d + 0.25 * d.powi(4);
        for i in 0..n - 1 {
            d = q[i + 1] - q[i];
            potential += 0.5 * d * d + 0.25 * d.powi(4);
        }
        d = q[n - 1];
        potential += 0.5 * d * d + 0.25 * d.powi(4);
        kinetic - potential
    }
}

/// An FPU-β chain (β = 1) with fixed ends, unit masses and springs, by hand.
#[derive(Clone)]
struct Fpu(usize);

impl DynLagrangian for Fpu {
    const AUTONOMOUS: bool = true;
    const SEPARABILITY: Separability = Separability::ConstantMass;
    const COUPLING: Coupling =
        Coupling { q_q: Pattern::Banded { bandwidth: 1 }, q_v: Pattern::Diagonal, v_v: Pattern::Diagonal };

    fn dimension(&self) -> usize {
        self.0
    }

    fn lagrangian<D: Scalar>(&self, _t: D, q: &[D], v: &[D]) -> D {
        let n = q.len();
        let spring = |d: D| d * d * 0.5 + d.powi(4) * 0.25;
        let mut kinetic = D::zero();
        for x in v {
            kinetic += *x * *x * 0.5;
        }
        let mut potential = spring(q[0]) + spring(q[n - 1]);
        for i in 0..n - 1 {
            potential += spring(q[i + 1] - q[i]);
        }
        kinetic - potential
    }
}

/// `VmHWM` from `/proc/self/status`, if readable.
fn peak_memory() -> String {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| s.lines().find(|l| l.starts_with("VmHWM:")).map(|l| l["VmHWM:".len()..].trim().to_string()))
        .unwrap_or_else(|| "unavailable".into())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let n: usize = match std::env::args().nth(1) {
        Some(arg) => arg.parse()?,
        None => 100_000,
    };
    match std::env::args().nth(2).as_deref() {
        None | Some("generated") => run(n, Generated),
        Some("tape") => run(n, Fpu),
        Some(other) => Err(format!("unknown system `{other}`: `generated` or `tape`").into()),
    }
}

/// The stages on the chain `system(n)`.
fn run<S: DynLagrangian + Clone>(n: usize, system: fn(usize) -> S) -> Result<(), Box<dyn std::error::Error>> {
    let which = if S::HAS_GRADIENT_QV { "generated gradient code" } else { "tape" };
    // Mode N/10 with spring strains of 0.3.
    let k = n.div_ceil(10);
    let a = 0.3 * (n + 1) as f64 / (k as f64 * std::f64::consts::PI);
    let q0: Vec<f64> =
        (0..n).map(|i| a * ((i + 1) as f64 * k as f64 * std::f64::consts::PI / (n + 1) as f64).sin()).collect();
    let v0 = vec![0.0; n];
    println!("FPU-β chain, N = {n} ({which}); peak memory after the initial data: {}", peak_memory());
    let mut midpoint = Problem::new(system(n), 0.0, q0.clone(), v0.clone()).stepper(&Scheme::MIDPOINT, 0.05)?;
    println!("after `start` (Legendre map): peak memory {}", peak_memory());
    let e0 = midpoint.energy()?;
    let clock = Instant::now();
    midpoint.run(3, |_| {})?;
    let per_step = clock.elapsed().as_secs_f64() / 3.0;
    let e = midpoint.energy()?;
    println!(
        "3 midpoint steps: relative energy error {:.2e}, {} Newton iterations, {:.1} ms per step; peak memory {}",
        (e - e0).abs() / e0,
        midpoint.stats().newton_iterations,
        per_step * 1e3,
        peak_memory()
    );
    drop(midpoint);
    let mut trapezoid = Problem::new(system(n), 0.0, q0, v0).stepper(&Scheme::TRAPEZOID, 0.05)?;
    trapezoid.run(10, |_| {})?;
    let e = trapezoid.energy()?;
    println!(
        "10 trapezoid steps (explicit): relative energy error {:.2e}; peak memory {}",
        (e - e0).abs() / e0,
        peak_memory()
    );
    Ok(())
}
