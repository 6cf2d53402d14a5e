//! Damped oscillator `m q̈ + c q̇ + k q = 0` as a Lagrangian with a Rayleigh
//! dissipation function, `L = ½ m q̇² − ½ k q²`, `R = ½ c q̇²`, integrated by
//! the discrete Lagrange–d'Alembert principle (midpoint and trapezoid).
//!
//! Prints the error against the exact solution at several step sizes (order
//! 2) and the discrete energy balance `E_{k+1} − E_k − W_k` (round-off for the
//! midpoint rule, `O(h³)` for the trapezoid); plots `q(t)`, its error against
//! the exact solution at two step sizes (a quarter when h halves), the discrete
//! energy `E_k` and the energy the damper has taken out, into
//! `target/example-output/damped_oscillator/` (or `$LAGRANGIAN_OUT`).
//!
//! Run with `cargo run --release --example damped_oscillator`.

#[path = "support/plot.rs"]
mod plot;

use std::error::Error;

use lagrangian::prelude::*;
use plot::{Figure, Panel, Series};

#[derive(Clone, Copy, Debug)]
struct Damped {
    m: f64,
    k: f64,
    c: f64,
}

#[lagrangian]
impl Damped {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * self.m * v[0] * v[0] - 0.5 * self.k * q[0] * q[0]
    }

    fn dissipation(&self, _q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * self.c * v[0] * v[0]
    }
}

impl Damped {
    /// Exact `q(t)` from `(q0, 0)`, underdamped.
    fn exact(&self, q0: f64, t: f64) -> f64 {
        let alpha = self.c / (2.0 * self.m);
        let wd = (self.k / self.m - alpha * alpha).sqrt();
        q0 * (-alpha * t).exp() * ((wd * t).cos() + alpha / wd * (wd * t).sin())
    }
}

/// Error at `t_end` and the worst energy-balance residual of one run.
fn run<M: DiscreteLagrangian>(sys: Damped, method: M, h: f64, t_end: f64) -> Result<(f64, f64), Box<dyn Error>> {
    let mut sim = Integrator::new(sys, method, h).start(0.0, [1.0], [0.0])?;
    let mut worst = 0.0f64;
    sim.run_until(t_end, |s| {
        if let Some(b) = s.energy_balance() {
            worst = worst.max(b.residual().abs());
        }
    })?;
    Ok(((sim.state().q[0] - sys.exact(1.0, t_end)).abs(), worst))
}

fn main() -> Result<(), Box<dyn Error>> {
    let sys = Damped { m: 1.0, k: 4.0, c: 0.5 };
    let t_end = 8.0;
    println!("damped oscillator m = {}, k = {}, c = {}, q0 = 1, E0 = 2, to t = {t_end}", sys.m, sys.k, sys.c);
    println!("  {:>8} {:>22} {:>22}", "h", "midpoint: error, balance", "trapezoid: error, balance");
    let mut previous: Option<(f64, f64)> = None;
    for h in [0.04, 0.02, 0.01, 0.005] {
        let (em, bm) = run(sys, Midpoint, h, t_end)?;
        let (et, bt) = run(sys, Trapezoid, h, t_end)?;
        let orders = previous.map_or(String::new(), |(pm, pt)| {
            format!("   observed orders {:.2}, {:.2}", (pm / em).log2(), (pt / et).log2())
        });
        println!("  {h:>8} {em:>11.3e} {bm:>10.1e} {et:>11.3e} {bt:>10.1e}{orders}");
        previous = Some((em, et));
    }

    // One run in detail: E_k, the energy removed Σ −W_k, and their sum.
    let h = 0.01;
    let mut sim = Integrator::new(sys, Midpoint, h).start(0.0, [1.0], [0.0])?;
    let (mut q, mut exact, mut energy, mut budget) = (vec![(0.0, 1.0)], vec![(0.0, 1.0)], vec![], vec![]);
    let mut removed = 0.0;
    sim.run_until(t_end, |s| {
        let t = s.state().t;
        q.push((t, s.state().q[0]));
        exact.push((t, sys.exact(1.0, t)));
        if let Some(b) = s.energy_balance() {
            removed -= b.work;
            energy.push((t, b.energy_after));
            budget.push((t, b.energy_after + removed));
        }
    })?;
    // The error at h and 2h: order 2 shows as a factor of 4 between the curves.
    let error = |h: f64| -> Result<Vec<(f64, f64)>, Box<dyn Error>> {
        let mut sim = Integrator::new(sys, Midpoint, h).start(0.0, [1.0], [0.0])?;
        let mut out = vec![(0.0, 0.0)];
        sim.run_until(t_end, |s| out.push((s.state().t, s.state().q[0] - sys.exact(1.0, s.state().t))))?;
        Ok(out)
    };
    let (error_2h, error_h) = (error(2.0 * h)?, error(h)?);
    let drift = budget.iter().map(|p| (p.1 - budget[0].1).abs()).fold(0.0, f64::max);
    println!("  h = {h}: E_k + (energy removed by the damper) stays at {:.15} to {drift:.1e}", budget[0].1);
    let dir = plot::output_dir("damped_oscillator")?;
    Figure {
        title: "Damped oscillator, midpoint rule with dissipation, h = 0.01 (error also at 0.02)",
        x_label: "t",
        x_range: (0.0, t_end),
        equal_axes: false,
        panels: vec![
            Panel {
                y_label: "q",
                series: vec![
                    Series { label: "discrete", points: &q, markers: false },
                    Series { label: "exact", points: &exact, markers: false },
                ],
            },
            Panel {
                y_label: "error qₖ − q(tₖ)",
                series: vec![
                    Series { label: "h = 0.02", points: &error_2h, markers: false },
                    Series { label: "h = 0.01", points: &error_h, markers: false },
                ],
            },
            Panel {
                y_label: "energy",
                series: vec![
                    Series { label: "discrete energy Eₖ", points: &energy, markers: false },
                    Series { label: "Eₖ + energy dissipated", points: &budget, markers: false },
                ],
            },
        ],
    }
    .save(&dir.join("damped_oscillator"), 1000)?;
    println!("  plots: {}", dir.join("damped_oscillator.png").display());
    Ok(())
}
