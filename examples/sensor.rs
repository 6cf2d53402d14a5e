//! Fu, Dai & Tang §4 (Fu, Dai & Tang): the electromechanical sensor. An armature
//! of mass `m` on a spring `k` under gravity moves inside a winding whose
//! self-inductance `L1(x)` depends on the armature position `x`; the winding
//! is in series with a resistor `R` and a battery `E`. Coordinates: `x` and
//! the charge `q` that has flowed,
//!
//! ```text
//! L = ½ m ẋ² + ½ L1(x) q̇² − ½ k x² + m g x,   dissipation ½ R q̇²,   force (0, E)
//! ```
//!
//! integrated with the midpoint rule and the discrete Lagrange–d'Alembert
//! principle, once with `L1` constant and once with `L1(x) = L0/(1 + x/a)`.
//! Prints the discrete first integral `I_k = p_{q,k} + R q_k − E t_k` (the
//! charge part of the paper's (27)–(28); `q` is cyclic), the energy balance
//! `E_{k+1} − E_k − W_k`, and plots `x(t)` and the current `q̇(t)` into
//! `target/example-output/sensor/` (or `$LAGRANGIAN_OUT`).
//!
//! Run with `cargo run --release --example sensor`.

#[path = "support/plot.rs"]
mod plot;

use std::error::Error;

use lagrangian::Symmetry;
use lagrangian::prelude::*;
use plot::{Figure, Panel, Series};

/// The sensor; `a = ∞` gives the constant inductance `L1 = L0`.
#[derive(Clone, Copy, Debug)]
struct Sensor {
    m: f64,
    k: f64,
    g: f64,
    l0: f64,
    a: f64,
    r: f64,
    e: f64,
}

#[lagrangian]
impl Sensor {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let x = q[0];
        let l1 = self.l0 / (1.0 + x / self.a);
        0.5 * self.m * v[0] * v[0] + 0.5 * l1 * v[1] * v[1] - 0.5 * self.k * x * x + self.m * self.g * x
    }

    fn dissipation(&self, _q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * self.r * v[1] * v[1]
    }

    fn force(&self, _q: [f64; 2], _v: [f64; 2]) -> [f64; 2] {
        [0.0, self.e]
    }
}

/// One run: `(t, x)`, `(t, current)`, and the worst first-integral and
/// energy-balance errors.
struct Run {
    x: Vec<(f64, f64)>,
    current: Vec<(f64, f64)>,
    first_integral: f64,
    balance: f64,
    energy_scale: f64,
}

fn run(sensor: Sensor, h: f64, t_end: f64) -> Result<Run, Box<dyn Error>> {
    let mut sim = Integrator::new(sensor, Midpoint, h).start(0.0, [0.0, 0.0], [0.0, 0.0])?;
    let charge = Symmetry::translation(1).ok_or("no coordinate 1")?;
    let mut out =
        Run { x: vec![(0.0, 0.0)], current: vec![(0.0, 0.0)], first_integral: 0.0, balance: 0.0, energy_scale: 0.0 };
    // I_k = J_k + R q_k − E t_k with the charge summed from the increments,
    // free of the rounding of q_k itself (see tests/verification/forces.rs).
    let (mut flowed, mut compensation) = (0.0f64, 0.0f64);
    let i0 = sim.momentum_map(&charge);
    let mut failure = None;
    sim.run_until(t_end, |s| {
        let st = s.state();
        let dq = s.last_step().map_or(0.0, |seg| seg.dq[1]);
        let sum = flowed + dq;
        compensation += if flowed.abs() >= dq.abs() { (flowed - sum) + dq } else { (dq - sum) + flowed };
        flowed = sum;
        let q = flowed + compensation;
        let integral = s.momentum_map(&charge) + sensor.r * q - sensor.e * st.t;
        let scale = st.p[1].abs().max(sensor.r * q.abs()).max(sensor.e * st.t);
        out.first_integral = out.first_integral.max((integral - i0).abs() / scale);
        if let Some(b) = s.energy_balance() {
            out.balance = out.balance.max(b.residual().abs());
            out.energy_scale = out.energy_scale.max(b.energy_after.abs());
        }
        match s.velocity() {
            Ok(v) => {
                out.x.push((st.t, st.q[0]));
                out.current.push((st.t, v[1]));
            }
            Err(e) => failure = Some(e),
        }
    })?;
    if let Some(e) = failure {
        return Err(e.into());
    }
    Ok(out)
}

fn main() -> Result<(), Box<dyn Error>> {
    let constant = Sensor { m: 0.2, k: 80.0, g: 9.81, l0: 0.5, a: f64::INFINITY, r: 10.0, e: 12.0 };
    let variable = Sensor { a: 0.2, ..constant };
    let (h, t_end) = (1e-3, 2.0);
    println!(
        "electromechanical sensor (Fu, Dai & Tang §4), midpoint, h = {h}, t ≤ {t_end}: m = {}, k = {}, L0 = {}, R = {}, E = {}",
        constant.m, constant.k, constant.l0, constant.r, constant.e
    );
    println!("  cyclic coordinates (x, q): {:?}", <Sensor as Lagrangian<2>>::CYCLIC);
    let fixed = run(constant, h, t_end)?;
    let moving = run(variable, h, t_end)?;
    for (name, r) in [("L1 constant", &fixed), ("L1 = L0/(1 + x/a), a = 0.2", &moving)] {
        println!("  {name}:");
        println!("    first integral p_q + R q − E t: max |I_k − I_0| / scale = {:.2e}  (round-off)", r.first_integral);
        println!(
            "    energy balance: max |E_k+1 − E_k − W_k| = {:.2e}, {:.2e} of max |E|  ({})",
            r.balance,
            r.balance / r.energy_scale,
            if name.starts_with("L1 constant") {
                "round-off: L is quadratic"
            } else {
                "O(h³) per step: L is not quadratic"
            }
        );
        let (t, i) = *r.current.last().ok_or("empty run")?;
        println!(
            "    at t = {t}: x = {:.5} m, current = {i:.5} A (E/R = {})",
            r.x.last().ok_or("empty run")?.1,
            constant.e / constant.r
        );
    }
    let dir = plot::output_dir("sensor")?;
    Figure {
        title: "Electromechanical sensor (Fu, Dai & Tang §4), midpoint rule, h = 0.001",
        x_label: "t [s]",
        x_range: (0.0, t_end),
        equal_axes: false,
        panels: vec![
            Panel {
                y_label: "armature x [m]",
                series: vec![
                    Series { label: "L₁ constant", points: &fixed.x, markers: false },
                    Series { label: "L₁ = L₀/(1 + x/a)", points: &moving.x, markers: false },
                ],
            },
            Panel {
                y_label: "current dq/dt [A]",
                series: vec![
                    Series { label: "L₁ constant", points: &fixed.current, markers: false },
                    Series { label: "L₁ = L₀/(1 + x/a)", points: &moving.current, markers: false },
                ],
            },
        ],
    }
    .save(&dir.join("sensor"), 1000)?;
    println!("  plots: {}", dir.join("sensor.png").display());
    Ok(())
}
