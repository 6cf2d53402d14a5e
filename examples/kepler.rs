//! Planar Kepler problem in polar coordinates, `L = ½(ṙ² + r² φ̇²) + μ/r`.
//! The angle is cyclic (the macro detects it), so the angular momentum
//! `p_φ` is conserved by the discrete flow to round-off.
//!
//! Plots the first and the last revolution in the plane, to the same scale in
//! x and y, into `target/example-output/kepler/` (or `$LAGRANGIAN_OUT`): the
//! orbit keeps its shape and slowly turns (the midpoint rule's precession).
//!
//! `cargo run --release --example kepler`

#[path = "support/plot.rs"]
mod plot;

use lagrangian::prelude::*;
use plot::{Figure, Panel, Series};

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
    // One revolution of the exact orbit, 2π √(a³/μ), in steps.
    let revolution = (std::f64::consts::TAU * (a * a * a / mu).sqrt() / h).ceil() as usize;
    let plane = |q: [f64; 2]| (q[0] * q[1].cos(), q[0] * q[1].sin());
    let (mut first, mut last) = (vec![plane([r0, 0.0])], Vec::new());
    sim.run(n, |s| {
        worst_energy = worst_energy.max(((s.energy().unwrap_or(f64::NAN) - e0) / e0).abs());
        worst_momentum = worst_momentum.max(((s.state().p[1] - p0) / p0).abs());
        let k = s.state().step as usize;
        if k <= revolution {
            first.push(plane(s.state().q));
        } else if k + revolution >= n {
            last.push(plane(s.state().q));
        }
    })?;
    println!("  max |ΔE/E0|        = {worst_energy:.3e}  (bounded)");
    println!("  max |Δp_φ / p_φ|   = {worst_momentum:.3e}  (round-off: discrete Noether)");
    let dir = plot::output_dir("kepler")?;
    let orbits = n as f64 * h / (std::f64::consts::TAU * (a * a * a / mu).sqrt());
    let title = format!("Kepler orbit, e = {e}, midpoint rule, h = {h}: first and last of {orbits:.0} revolutions");
    Figure {
        title: &title,
        x_label: "x = r cos φ",
        x_range: (-a * (1.0 + e) - 0.15, a * (1.0 - e) + 0.15),
        equal_axes: true,
        panels: vec![Panel {
            y_label: "y = r sin φ",
            series: vec![
                Series { label: "first revolution", points: &first, markers: false },
                Series { label: "last revolution", points: &last, markers: false },
            ],
        }],
    }
    .save(&dir.join("orbit"), 800)?;
    println!("  plot: {}", dir.join("orbit.png").display());
    Ok(())
}
