//! Series RLC circuit driven by `E(t) = E0 cos(Ω t)`, the charge `q` on the
//! capacitor as coordinate: `L = ½ ℓ q̇² − q²/(2C)` (magnetic minus electric
//! energy, Fu, Dai & Tang eq. (1)–(2)), the resistor as `R = ½ r q̇²` (eq. (5)) and
//! the source as a time-dependent force.
//!
//! Prints the error in charge and current against the exact solution at
//! several step sizes (order 2) and the energy balance; plots `q(t)` and
//! `i(t)` with the exact ones, and their errors at two step sizes (a quarter
//! when h halves), into `target/example-output/rlc_circuit/` (or
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

    // Curves at h, errors at h and 2h: order 2 shows as a factor of 4 between them.
    let h = 0.005;
    // Rows (t, q, i).
    type Rows = Vec<(f64, f64, f64)>;
    let trajectory = |h: f64| -> Result<Rows, Box<dyn Error>> {
        let mut sim = Integrator::new(rlc, Midpoint, h).start(0.0, [0.0], [0.0])?;
        let mut out = vec![(0.0, 0.0, 0.0)];
        sim.run_until(t_end, |s| out.push((s.state().t, s.state().q[0], s.state().p[0] / rlc.l)))?;
        Ok(out)
    };
    let (fine, coarse) = (trajectory(h)?, trajectory(2.0 * h)?);
    let q: Vec<(f64, f64)> = fine.iter().map(|&(t, q, _)| (t, q)).collect();
    let i: Vec<(f64, f64)> = fine.iter().map(|&(t, _, i)| (t, i)).collect();
    let q_exact: Vec<(f64, f64)> = fine.iter().map(|&(t, ..)| (t, rlc.exact(t)[0])).collect();
    let i_exact: Vec<(f64, f64)> = fine.iter().map(|&(t, ..)| (t, rlc.exact(t)[1])).collect();
    let q_error = |run: &[(f64, f64, f64)]| -> Vec<(f64, f64)> {
        run.iter().map(|&(t, q, _)| (t, q - rlc.exact(t)[0])).collect()
    };
    let i_error = |run: &[(f64, f64, f64)]| -> Vec<(f64, f64)> {
        run.iter().map(|&(t, _, i)| (t, i - rlc.exact(t)[1])).collect()
    };
    let (q_error_2h, q_error_h, i_error_2h, i_error_h) =
        (q_error(&coarse), q_error(&fine), i_error(&coarse), i_error(&fine));
    let dir = plot::output_dir("rlc_circuit")?;
    Figure {
        title: "Driven series RLC circuit, midpoint rule, h = 0.005 (errors also at 0.01)",
        x_label: "t [s]",
        x_range: (0.0, t_end),
        equal_axes: false,
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
            Panel {
                y_label: "error in q [C]",
                series: vec![
                    Series { label: "h = 0.01", points: &q_error_2h, markers: false },
                    Series { label: "h = 0.005", points: &q_error_h, markers: false },
                ],
            },
            Panel {
                y_label: "error in i [A]",
                series: vec![
                    Series { label: "h = 0.01", points: &i_error_2h, markers: false },
                    Series { label: "h = 0.005", points: &i_error_h, markers: false },
                ],
            },
        ],
    }
    .save(&dir.join("rlc_circuit"), 1000)?;
    println!("  plots: {}", dir.join("rlc_circuit.png").display());
    Ok(())
}
