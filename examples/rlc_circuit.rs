//! Series RLC circuit driven by `E(t) = E0 cos(Ω t)`, the charge `q` on the
//! capacitor as coordinate: `L = ½ ℓ q̇² − q²/(2C)` (magnetic minus electric
//! energy, Fu, Dai & Tang eq. (1)–(2)), the resistor as `R = ½ r q̇²` (eq. (5)) and
//! the source as a time-dependent force.
//!
//! Prints the error in charge and current against the exact solution at
//! several step sizes (order 2) and the energy balance; plots `q(t)` and
//! `i(t)` with the exact ones into `target/example-output/rlc_circuit/` (or
//! `$LAGRANGIAN_OUT`).
//!
//! Run with `cargo run --release --example rlc_circuit`.

#[path = "support/plot.rs"]
mod plot;

use std::error::Error;

use lagrangian::prelude::*;
use plot::{Figure, Panel, Series};

#[derive(Clone, Copy, Debug)]
struct Rlc {
    l: f64,
    r: f64,
    c: f64,
    e0: f64,
    omega: f64,
}

#[lagrangian]
impl Rlc {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * self.l * v[0] * v[0] - 0.5 * q[0] * q[0] / self.c
    }

    fn dissipation(&self, _q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * self.r * v[0] * v[0]
    }

    fn force(&self, t: f64, _q: [f64; 1], _v: [f64; 1]) -> [f64; 1] {
        [self.e0 * (self.omega * t).cos()]
    }
}

impl Rlc {
    /// Exact `(q, i)` from `q = i = 0`: steady state `Re(E0 e^{iΩt}/Z)` plus the transient.
    fn exact(&self, t: f64) -> [f64; 2] {
        let alpha = self.r / (2.0 * self.l);
        let wd = (1.0 / (self.l * self.c) - alpha * alpha).sqrt();
        let (zr, zi) = (1.0 / self.c - self.l * self.omega * self.omega, self.r * self.omega);
        let norm = zr * zr + zi * zi;
        let (a, b) = (self.e0 * zr / norm, -self.e0 * zi / norm);
        let (c1, c2) = (-a, (b * self.omega - alpha * a) / wd);
        let (sw, cw) = (self.omega * t).sin_cos();
        let (sd, cd) = (wd * t).sin_cos();
        let decay = (-alpha * t).exp();
        let q = a * cw - b * sw + decay * (c1 * cd + c2 * sd);
        let i = -self.omega * (a * sw + b * cw) + decay * ((-alpha * c1 + wd * c2) * cd + (-alpha * c2 - wd * c1) * sd);
        [q, i]
    }
}

fn main() -> Result<(), Box<dyn Error>> {
    let rlc = Rlc { l: 0.5, r: 1.5, c: 0.02, e0: 10.0, omega: 7.0 };
    let t_end = 4.0;
    println!(
        "series RLC, ℓ = {} H, r = {} Ω, C = {} F, E = {} cos({} t) V, from rest, midpoint, to t = {t_end}",
        rlc.l, rlc.r, rlc.c, rlc.e0, rlc.omega
    );
    let exact = rlc.exact(t_end);
    let mut previous: Option<f64> = None;
    for h in [0.04, 0.02, 0.01, 0.005] {
        let mut sim = Integrator::new(rlc, Midpoint, h).start(0.0, [0.0], [0.0])?;
        let (mut worst, mut scale) = (0.0f64, 0.0f64);
        sim.run_until(t_end, |s| {
            if let Some(b) = s.energy_balance() {
                worst = worst.max(b.residual().abs());
                scale = scale.max(b.energy_after.abs());
            }
        })?;
        let s = sim.state();
        let err = (s.q[0] - exact[0]).abs().max((s.p[0] / rlc.l - exact[1]).abs()) / exact[0].abs().max(exact[1].abs());
        let order = previous.map_or(String::new(), |p| format!(", observed order {:.2}", (p / err).log2()));
        println!(
            "  h = {h:<6} error in (q, i) {err:.3e}{order}; max |E_k+1 − E_k − W_k| = {:.1e} of max E",
            worst / scale
        );
        previous = Some(err);
    }

    let h = 0.005;
    let mut sim = Integrator::new(rlc, Midpoint, h).start(0.0, [0.0], [0.0])?;
    let (mut q, mut i, mut q_exact, mut i_exact) =
        (vec![(0.0, 0.0)], vec![(0.0, 0.0)], vec![(0.0, 0.0)], vec![(0.0, 0.0)]);
    sim.run_until(t_end, |s| {
        let t = s.state().t;
        let e = rlc.exact(t);
        q.push((t, s.state().q[0]));
        i.push((t, s.state().p[0] / rlc.l));
        q_exact.push((t, e[0]));
        i_exact.push((t, e[1]));
    })?;
    let dir = plot::output_dir("rlc_circuit")?;
    Figure {
        title: "Driven series RLC circuit, midpoint rule, h = 0.005",
        x_label: "t [s]",
        x_range: (0.0, t_end),
        panels: vec![
            Panel {
                y_label: "charge q [C]",
                series: vec![
                    Series { label: "discrete", points: &q, markers: false },
                    Series { label: "exact", points: &q_exact, markers: false },
                ],
            },
            Panel {
                y_label: "current i = p/ℓ [A]",
                series: vec![
                    Series { label: "discrete", points: &i, markers: false },
                    Series { label: "exact", points: &i_exact, markers: false },
                ],
            },
        ],
    }
    .save(&dir.join("rlc_circuit"), 1000)?;
    println!("  plots: {}", dir.join("rlc_circuit.png").display());
    Ok(())
}
