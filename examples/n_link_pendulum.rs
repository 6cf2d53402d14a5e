//! A planar pendulum of N = 64 equal links, released from rest along a
//! shallow arc: the chain falls and whips. Unit masses at the joints, unit
//! link lengths, `g = 1`, angles from the downward vertical:
//!
//! ```text
//! ẋᵢ = Σ_{j≤i} cos qⱼ q̇ⱼ,   ẏᵢ = Σ_{j≤i} sin qⱼ q̇ⱼ,   yᵢ = −Σ_{j≤i} cos qⱼ,
//! L = Σᵢ ½ (ẋᵢ² + ẏᵢ²) − Σᵢ yᵢ.
//! ```
//!
//! Written with running sums, `L` costs `O(N)` operations, but every angle
//! couples with every other through the mass matrix `M(q)`: `#[lagrangian]`
//! cannot prove a band, so the midpoint rule's Newton systems are dense. Above
//! `Derivatives::FORWARD_MAX_N` coordinates the derivatives come from a tape
//! swept in reverse (`N` directions for the dense Jacobian), solved by dense
//! LU on the heap.
//!
//! Prints the energy error and the cost per step; writes the path of the
//! chain's free end (equal axes) to `target/example-output/n_link_pendulum/`
//! (or `$LAGRANGIAN_OUT`).
//!
//! Run with `cargo run --release --example n_link_pendulum`.

#[path = "support/plot.rs"]
mod plot;

use std::error::Error;
use std::time::Instant;

use lagrangian::prelude::*;
use plot::{Figure, Panel, Series};

/// `N` equal links with unit masses at the joints.
struct NLinkPendulum<const N: usize>;

#[lagrangian]
impl<const N: usize> NLinkPendulum<N> {
    fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
        let (mut vx, mut vy, mut y) = (0.0, 0.0, 0.0);
        let mut l = 0.0;
        for i in 0..N {
            vx += q[i].cos() * v[i];
            vy += q[i].sin() * v[i];
            y -= q[i].cos();
            l += 0.5 * (vx * vx + vy * vy) - y;
        }
        l
    }
}

/// The free end's position.
fn tip<const N: usize>(q: &[f64; N]) -> (f64, f64) {
    q.iter().fold((0.0, 0.0), |(x, y), a| (x + a.sin(), y - a.cos()))
}

fn main() -> Result<(), Box<dyn Error>> {
    const N: usize = 64;
    let (h, t_end) = (2e-3, 20.0);
    // A shallow arc: the links from 60° at the top to 100° at the end.
    let q0: [f64; N] = core::array::from_fn(|i| (60.0 + 40.0 * i as f64 / (N - 1) as f64).to_radians());
    let mut sim = Integrator::new(NLinkPendulum::<N>, Midpoint, h).start(0.0, q0, [0.0; N])?;
    let e0 = sim.energy()?;
    let mut path = vec![tip(&q0)];
    let mut worst: f64 = 0.0;
    let start = Instant::now();
    let steps = (t_end / h).round() as usize;
    for k in 1..=steps {
        sim.step()?;
        if k % 10 == 0 {
            path.push(tip(&sim.state().q));
        }
        if k % 500 == 0 {
            worst = worst.max((sim.energy()? - e0).abs() / e0.abs());
        }
    }
    let seconds = start.elapsed().as_secs_f64();
    let stats = sim.stats();
    println!(
        "{N}-link pendulum, midpoint, h = {h}, {steps} steps to t = {t_end}: {:.2} ms/step, {:.2} Newton iterations per step",
        seconds / steps as f64 * 1e3,
        stats.newton_iterations as f64 / steps as f64
    );
    println!("largest relative energy error (every 500 steps): {worst:.2e}");
    let dir = plot::output_dir("n_link_pendulum")?;
    let x_range = path.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| (a.min(p.0), b.max(p.0)));
    Figure {
        title: &format!("{N}-link pendulum: path of the free end, t ≤ {t_end} (equal axes)"),
        x_label: "x",
        x_range,
        panels: vec![Panel { y_label: "y", series: vec![Series { label: "", points: &path, markers: false }] }],
        equal_axes: true,
    }
    .save(&dir.join("tip"), 900)?;
    println!("plot: {}", dir.display());
    Ok(())
}
