//! Peak memory of a run-time-sized FPU-β chain: `N` masses (default
//! 100 000, or the first argument), 3 midpoint steps (banded Newton) and 10
//! explicit trapezoid steps through `DynIntegrator`, printing the energy
//! error and the process's peak resident memory (`VmHWM`, Linux) after each
//! stage.
//!
//! `cargo run --release --example chain_memory [N]`
use lagrangian::prelude::*;
use lagrangian::{Coupling, Pattern, Separability};

/// An FPU-β chain (β = 1) with fixed ends, unit masses and springs.
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
    // Mode N/10 with spring strains of 0.3.
    let k = n.div_ceil(10);
    let a = 0.3 * (n + 1) as f64 / (k as f64 * std::f64::consts::PI);
    let q0: Vec<f64> =
        (0..n).map(|i| a * ((i + 1) as f64 * k as f64 * std::f64::consts::PI / (n + 1) as f64).sin()).collect();
    let v0 = vec![0.0; n];
    println!("FPU-β chain, N = {n}; peak memory after the initial data: {}", peak_memory());
    let mut midpoint = DynIntegrator::new(Fpu(n), Midpoint, 0.05).start(0.0, &q0, &v0)?;
    let e0 = midpoint.energy()?;
    midpoint.run(3, |_| {})?;
    let e = midpoint.energy()?;
    println!(
        "3 midpoint steps: relative energy error {:.2e}, {} Newton iterations; peak memory {}",
        (e - e0).abs() / e0,
        midpoint.stats().newton_iterations,
        peak_memory()
    );
    drop(midpoint);
    let mut trapezoid = DynIntegrator::new(Fpu(n), Trapezoid, 0.05).start(0.0, &q0, &v0)?;
    trapezoid.run(10, |_| {})?;
    let e = trapezoid.energy()?;
    println!(
        "10 trapezoid steps (explicit): relative energy error {:.2e}; peak memory {}",
        (e - e0).abs() / e0,
        peak_memory()
    );
    Ok(())
}
