//! Kepler problem in Cartesian coordinates, `L = ½|v|² + μ/r`: no coordinate
//! is cyclic, but `L` is invariant under rotations in the (x, y) plane, so the
//! discrete momentum map of `Symmetry::rotation(0, 1)`, `J = x p_y − y p_x`,
//! is conserved (docs/theory.md §7). With a drag `R = ½ c|v|²` and a tangential
//! thrust, `J` changes by exactly the forcing impulse of each step.
//!
//! Prints both checks and plots the orbits and `J(t)` into
//! `target/example-output/kepler_cartesian/` (or `$LAGRANGIAN_OUT`).
//!
//! Run with `cargo run --release --example kepler_cartesian`.

#[path = "support/plot.rs"]
mod plot;

use std::error::Error;

use lagrangian::Symmetry;
use lagrangian::prelude::*;
use plot::{Figure, Panel, Series};

/// Kepler with drag `c` and tangential thrust `s` (both may be zero).
#[derive(Clone, Copy, Debug)]
struct Kepler {
    mu: f64,
    c: f64,
    s: f64,
}

#[lagrangian]
impl Kepler {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let r = (q[0] * q[0] + q[1] * q[1]).sqrt();
        0.5 * (v[0] * v[0] + v[1] * v[1]) + self.mu / r
    }

    fn dissipation(&self, _q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * self.c * (v[0] * v[0] + v[1] * v[1])
    }

    fn force(&self, q: [f64; 2], _v: [f64; 2]) -> [f64; 2] {
        let r = (q[0] * q[0] + q[1] * q[1]).sqrt();
        [-self.s * q[1] / r, self.s * q[0] / r]
    }
}

struct Run {
    orbit: Vec<(f64, f64)>,
    momentum: Vec<(f64, f64)>,
    /// max |J_k − J_0| / |J_0|.
    drift: f64,
    /// max over steps of |J_{k+1} − J_k − impulse_k| / |J|.
    balance: f64,
}

fn run(kepler: Kepler, h: f64, n: usize) -> Result<Run, Box<dyn Error>> {
    let (e, r0) = (0.5, 0.5);
    let mut sim = Integrator::new(kepler, Midpoint, h).start(0.0, [r0, 0.0], [0.0, ((1.0 + e) / r0).sqrt()])?;
    let rotation = Symmetry::rotation(0, 1).ok_or("bad plane")?;
    let j0 = sim.momentum_map(&rotation);
    let mut out = Run { orbit: vec![(r0, 0.0)], momentum: vec![(0.0, j0)], drift: 0.0, balance: 0.0 };
    let mut j = j0;
    sim.run(n, |s| {
        let next = s.momentum_map(&rotation);
        let impulse = s.forcing_impulse(&rotation).unwrap_or(f64::NAN);
        out.balance = out.balance.max((next - j - impulse).abs() / next.abs().max(j.abs()));
        out.drift = out.drift.max((next - j0).abs() / j0.abs());
        j = next;
        let st = s.state();
        if st.step % 10 == 0 {
            out.orbit.push((st.q[0], st.q[1]));
            out.momentum.push((st.t, next));
        }
    })?;
    Ok(out)
}

fn main() -> Result<(), Box<dyn Error>> {
    let (h, n) = (0.01, 100_000);
    println!("Cartesian Kepler, e = 0.5, midpoint, h = {h}, {n} steps");
    println!(
        "  cyclic coordinates: {:?} (none: the symmetry is declared as a rotation)",
        <Kepler as Lagrangian<2>>::CYCLIC
    );
    let free = run(Kepler { mu: 1.0, c: 0.0, s: 0.0 }, h, n)?;
    println!("  no forces: max |J_k − J_0| / |J_0| = {:.2e}  (round-off)", free.drift);
    let forced = run(Kepler { mu: 1.0, c: 0.004, s: 0.001 }, h, 20_000)?;
    println!(
        "  drag c = 0.004, thrust 0.001, 20000 steps: J changes by {:.1}% in all; per step |J_k+1 − J_k − impulse| / |J| ≤ {:.2e}",
        100.0 * forced.drift,
        forced.balance
    );
    let dir = plot::output_dir("kepler_cartesian")?;
    let free_orbit = &free.orbit[..free.orbit.len().min(1000)];
    Figure {
        title: "Cartesian Kepler: free orbit and orbit with drag and thrust",
        x_label: "x",
        x_range: (-1.6, 0.6),
        equal_axes: true,
        panels: vec![Panel {
            y_label: "y",
            series: vec![
                Series { label: "no forces", points: free_orbit, markers: false },
                Series { label: "drag + thrust", points: &forced.orbit, markers: false },
            ],
        }],
    }
    .save(&dir.join("orbits"), 800)?;
    Figure {
        // With unit mass p = v, so J = x p_y − y p_x is written without subscripts.
        title: "Angular momentum J = x ẏ − y ẋ",
        x_label: "t",
        x_range: (0.0, 200.0),
        equal_axes: false,
        panels: vec![Panel {
            y_label: "J",
            series: vec![
                Series { label: "no forces", points: &free.momentum, markers: false },
                Series { label: "drag + thrust", points: &forced.momentum, markers: false },
            ],
        }],
    }
    .save(&dir.join("momentum"), 1000)?;
    println!("  plots: {}", dir.display());
    Ok(())
}
