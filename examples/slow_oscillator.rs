//! The slowly varying oscillator `L = ½ q̇² − ½ ω(εt)² q²`, with
//! `ω(s) = 1 + ½ sin s` and `ε = 0.01`, integrated with fixed and with
//! energy-preserving variable midpoint steps (a time-dependent Lagrangian:
//! the energy is not conserved but balanced, `dE/dt = −∂L/∂t`, de León & Martín de Diego).
//!
//! Prints the energy of both runs against an RK4 reference and the
//! adiabatic invariant `E/ω`, and plots `q`, `E` and the variable steps into
//! `target/example-output/slow_oscillator/` (or `$LAGRANGIAN_OUT`).
//!
//! Run with `cargo run --release --example slow_oscillator`.

#[path = "support/plot.rs"]
mod plot;

use std::error::Error;

use lagrangian::StepBounds;
use lagrangian::prelude::*;
use plot::{Figure, Panel, Series};

/// `L = ½ q̇² − ½ ω(εt)² q²`.
#[derive(Clone, Copy, Debug)]
struct SlowOscillator {
    eps: f64,
}

#[lagrangian]
impl SlowOscillator {
    fn lagrangian(&self, t: f64, q: [f64; 1], v: [f64; 1]) -> f64 {
        let w = 1.0 + 0.5 * (self.eps * t).sin();
        0.5 * v[0] * v[0] - 0.5 * w * w * q[0] * q[0]
    }
}

impl SlowOscillator {
    fn omega(&self, t: f64) -> f64 {
        1.0 + 0.5 * (self.eps * t).sin()
    }

    /// `(q, v)` at every multiple of `h` up to `t_end`, by RK4 with `sub` substeps per `h`.
    fn reference(&self, (q0, v0): (f64, f64), h: f64, n: usize, sub: usize) -> Vec<(f64, f64, f64)> {
        let f = |t: f64, q: f64| -self.omega(t).powi(2) * q;
        let (mut q, mut v) = (q0, v0);
        let dt = h / sub as f64;
        let mut out = vec![(0.0, q, v)];
        for k in 0..n {
            for j in 0..sub {
                let t = k as f64 * h + j as f64 * dt;
                let (k1q, k1v) = (v, f(t, q));
                let (k2q, k2v) = (v + 0.5 * dt * k1v, f(t + 0.5 * dt, q + 0.5 * dt * k1q));
                let (k3q, k3v) = (v + 0.5 * dt * k2v, f(t + 0.5 * dt, q + 0.5 * dt * k2q));
                let (k4q, k4v) = (v + dt * k3v, f(t + dt, q + dt * k3q));
                q += dt / 6.0 * (k1q + 2.0 * k2q + 2.0 * k3q + k4q);
                v += dt / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
            }
            out.push(((k + 1) as f64 * h, q, v));
        }
        out
    }

    fn energy_of(&self, t: f64, q: f64, v: f64) -> f64 {
        0.5 * v * v + 0.5 * self.omega(t).powi(2) * q * q
    }
}

fn main() -> Result<(), Box<dyn Error>> {
    let system = SlowOscillator { eps: 0.01 };
    let (t_end, h) = (1000.0, 0.05);
    let n = (t_end / h) as usize;
    let reference = system.reference((1.0, 0.0), h, n, 10);

    // Fixed steps.
    let mut fixed = Integrator::new(system, Midpoint, h).start(0.0, [1.0], [0.0])?;
    let mut fixed_energy = Vec::with_capacity(n);
    let mut worst_fixed = 0.0f64;
    fixed.run(n, |s| {
        let k = s.state().step as usize;
        let (t, q, v) = reference[k];
        let e_ref = system.energy_of(t, q, v);
        worst_fixed = worst_fixed.max((s.discrete_energy() - e_ref).abs() / e_ref);
        fixed_energy.push((t, s.discrete_energy()));
    })?;

    // Variable steps.
    let mut variable =
        Integrator::new(system, Midpoint, h).energy_preserving(StepBounds::around(h)).start(0.0, [1.0], [0.0])?;
    let (mut q_var, mut e_var, mut tau) = (Vec::new(), Vec::new(), Vec::new());
    let mut t_prev = 0.0;
    variable.run_until(t_end, |s| {
        let t = s.state().t;
        q_var.push((t, s.state().q[0]));
        e_var.push((t, s.discrete_energy()));
        tau.push((t_prev, t - t_prev));
        t_prev = t;
    })?;
    let (t, q, v) = reference[n];
    let e_ref = system.energy_of(t, q, v);
    let invariant_0 = system.energy_of(0.0, 1.0, 0.0) / system.omega(0.0);

    println!(
        "t = {t_end}: reference q = {q:.6}, E = {e_ref:.6}, E/ω = {:.6} (E/ω at 0: {invariant_0:.6})",
        e_ref / system.omega(t)
    );
    println!("fixed h = {h}: {n} steps, q = {:.6}, largest |E_k − E(t_k)|/E = {worst_fixed:.2e}", fixed.state().q[0]);
    println!(
        "variable (h0 = {h}): {} steps, q = {:.6}, E = {:.6} ({:.2e} relative), τ in [{:.4}, {:.4}]",
        variable.stats().steps,
        variable.state().q[0],
        variable.discrete_energy(),
        (variable.discrete_energy() - e_ref).abs() / e_ref,
        tau.iter().skip(1).map(|p| p.1).fold(f64::INFINITY, f64::min),
        tau.iter().skip(1).map(|p| p.1).fold(0.0, f64::max),
    );

    let dir = plot::output_dir("slow_oscillator")?;
    let exact_energy: Vec<(f64, f64)> = reference.iter().map(|&(t, q, v)| (t, system.energy_of(t, q, v))).collect();
    Figure {
        title: "Slowly varying oscillator, ε = 0.01",
        x_label: "t",
        x_range: (0.0, t_end),
        panels: vec![
            Panel { y_label: "q", series: vec![Series { label: "variable steps", points: &q_var, markers: false }] },
            Panel {
                y_label: "energy",
                series: vec![
                    Series { label: "RK4 reference", points: &exact_energy, markers: false },
                    Series { label: "fixed steps E_k", points: &fixed_energy, markers: false },
                    Series { label: "variable steps E_k", points: &e_var, markers: false },
                ],
            },
            Panel { y_label: "τ_k (variable)", series: vec![Series { label: "", points: &tau[1..], markers: false }] },
        ],
    }
    .save(&dir.join("slow_oscillator"), 1000)?;
    println!("wrote {}", dir.display());
    Ok(())
}
