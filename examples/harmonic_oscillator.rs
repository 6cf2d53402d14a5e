//! Harmonic oscillator `L = ½ m q̇² − ½ k q²` with the midpoint rule, against
//! the exact solution. Prints the position, energy and momentum errors.
//!
//! `cargo run --release --example harmonic_oscillator`

use lagrangian::prelude::*;

struct Oscillator {
    m: f64,
    k: f64,
}

#[lagrangian]
impl Oscillator {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * self.m * v[0] * v[0] - 0.5 * self.k * q[0] * q[0]
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let (m, k): (f64, f64) = (2.0, 8.0);
    let w = (k / m).sqrt();
    let (q0, v0, h, periods) = (1.0, 0.0, 0.01, 1000.0);
    let t_end = periods * 2.0 * std::f64::consts::PI / w;
    let mut sim = Integrator::new(Oscillator { m, k }, Midpoint, h).start(0.0, [q0], [v0])?;
    let e0 = sim.energy()?;
    let mut worst_energy = 0.0f64;
    let mut worst_q = 0.0f64;
    sim.run_until(t_end, |s| {
        let t = s.state().t;
        let exact = q0 * (w * t).cos() + v0 / w * (w * t).sin();
        worst_q = worst_q.max((s.state().q[0] - exact).abs());
        worst_energy = worst_energy.max((s.energy().unwrap_or(f64::NAN) - e0).abs() / e0);
    })?;
    let exact_p = m * (-q0 * w * (w * t_end).sin() + v0 * (w * t_end).cos());
    println!("harmonic oscillator, midpoint, h = {h}, {periods} periods ({} steps)", sim.stats().steps);
    println!("  max |q - q_exact|              = {worst_q:.3e}  (phase error grows like h² t)");
    println!("  max |E - E0| / E0              = {worst_energy:.3e}  (bounded, no drift)");
    println!("  |p - p_exact| at the end       = {:.3e}", (sim.state().p[0] - exact_p).abs());
    println!(
        "  newton iterations per step     = {:.2}",
        sim.stats().newton_iterations as f64 / sim.stats().steps as f64
    );
    Ok(())
}
