//! Double pendulum (chaotic): energy error and symplecticity defect of the
//! midpoint rule along a trajectory.
//!
//! `cargo run --release --example double_pendulum`

use lagrangian::prelude::*;

struct DoublePendulum {
    m1: f64,
    m2: f64,
    l1: f64,
    l2: f64,
    g: f64,
}

#[lagrangian]
impl DoublePendulum {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let kinetic = 0.5 * (self.m1 + self.m2) * self.l1 * self.l1 * v[0] * v[0]
            + 0.5 * self.m2 * self.l2 * self.l2 * v[1] * v[1]
            + self.m2 * self.l1 * self.l2 * v[0] * v[1] * (q[0] - q[1]).cos();
        let potential = -(self.m1 + self.m2) * self.g * self.l1 * q[0].cos() - self.m2 * self.g * self.l2 * q[1].cos();
        kinetic - potential
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let system = DoublePendulum { m1: 1.0, m2: 1.0, l1: 1.0, l2: 1.0, g: 9.81 };
    let (h, n) = (0.005, 100_000);
    let mut sim = Integrator::new(system, Midpoint, h).start(0.0, [2.0, 1.0], [0.0, 0.0])?;
    let e0 = sim.energy()?;
    let (mut worst_energy, mut worst_defect) = (0.0f64, 0.0f64);
    sim.run(n, |s| {
        worst_energy = worst_energy.max(((s.energy().unwrap_or(f64::NAN) - e0) / e0).abs());
        if s.state().step % 1000 == 0
            && let Some(m) = s.last_tangent_map()
        {
            worst_defect = worst_defect.max(m.symplecticity_defect());
        }
    })?;
    println!("double pendulum from (2, 1) rad at rest, midpoint, h = {h}, {n} steps (t = {} s)", sim.state().t);
    println!("  max |ΔE/E0|                       = {worst_energy:.3e}");
    println!("  max symplecticity defect |MᵀJM−J| = {worst_defect:.3e}");
    println!(
        "  newton iterations per step        = {:.2}",
        sim.stats().newton_iterations as f64 / sim.stats().steps as f64
    );
    Ok(())
}
