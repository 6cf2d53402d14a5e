//! Planar Kepler problem in polar coordinates, `L = ½(ṙ² + r² φ̇²) + μ/r`.
//! The angle is cyclic (the macro detects it), so the angular momentum
//! `p_φ` is conserved by the discrete flow to round-off.
//!
//! `cargo run --release --example kepler`

use lagrangian::prelude::*;

struct Kepler {
    mu: f64,
}

#[lagrangian]
impl Kepler {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let r = q[0];
        0.5 * (v[0] * v[0] + r * r * v[1] * v[1]) + self.mu / r
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let (mu, a, e): (f64, f64, f64) = (1.0, 1.0, 0.5);
    let r0 = a * (1.0 - e);
    let phi_dot = (mu * a * (1.0 - e * e)).sqrt() / (r0 * r0);
    let (h, n) = (0.01, 100_000);
    println!(
        "kepler, e = {e}, midpoint, h = {h}, {n} steps (~{:.0} orbits)",
        n as f64 * h / (2.0 * std::f64::consts::PI)
    );
    println!("  cyclic coordinates detected by the macro: {:?} (r, φ)", <Kepler as Lagrangian<2>>::CYCLIC);
    let mut sim = Integrator::new(Kepler { mu }, Midpoint, h).start(0.0, [r0, 0.0], [0.0, phi_dot])?;
    let e0 = sim.energy()?;
    let p0 = sim.state().p[1];
    let (mut worst_energy, mut worst_momentum) = (0.0f64, 0.0f64);
    sim.run(n, |s| {
        worst_energy = worst_energy.max(((s.energy().unwrap_or(f64::NAN) - e0) / e0).abs());
        worst_momentum = worst_momentum.max(((s.state().p[1] - p0) / p0).abs());
    })?;
    println!("  max |ΔE/E0|        = {worst_energy:.3e}  (bounded)");
    println!("  max |Δp_φ / p_φ|   = {worst_momentum:.3e}  (round-off: discrete Noether)");
    Ok(())
}
