//! The Fermi–Pasta–Ulam–Tsingou β chain: masses joined by springs with a
//! quartic term, fixed ends,
//!
//! ```text
//! L = Σ ½ q̇ᵢ² − Σ_{i=0}^{N} [ ½ (q_{i+1} − qᵢ)² + β/4 (q_{i+1} − qᵢ)⁴ ],   q₀ = q_{N+1} = 0,
//! ```
//!
//! written with `for` loops over neighbours; `#[lagrangian]` proves it
//! separable with a constant mass and a Hessian of bandwidth 1, so
//! `Trapezoid` takes the explicit Störmer–Verlet path, and above
//! `Derivatives::FORWARD_MAX_N` coordinates every derivative comes from a
//! tape swept in reverse (`O(N)` per step).
//!
//! 1. N = 32, all the energy in the lowest normal mode: the energy flows into
//!    a few higher modes and comes back — the FPU recurrence — while the
//!    total energy stays within the method's `O(h²)` band. Plot:
//!    `modes_n32.png`.
//! 2. N = 10 000, a chain whose length is a run-time value (`q: &[f64]`,
//!    `fn dimension`: `#[lagrangian]` implements `DynLagrangian`, and the
//!    `Problem` stated by vectors keeps the state, the tape and the banded
//!    matrices on the heap, so it runs in an ordinary thread), mode 1000 excited with
//!    spring strains of about 1 (well into the quartic regime): the energy
//!    of modes 1000, 3000 and 5000 and the total energy error over 5 000
//!    explicit steps, and 20 steps of the implicit midpoint rule with banded
//!    Newton solves, with their cost per step. Plot: `modes_n10000.png`.
//!
//! Why the recurrence is shown on 32 masses: the lowest mode's period grows
//! like `N` (about 20 000 time units at N = 10 000), so a recurrence of the
//! long chain would take far longer than this example runs.
//!
//! Run with `cargo run --release --example fpu_chain`.

#[path = "support/plot.rs"]
mod plot;

use std::error::Error;
use std::f64::consts::PI;
use std::time::Instant;

use lagrangian::prelude::*;
use plot::{Figure, Panel, Series};

/// The FPU-β chain with fixed ends and unit masses and springs.
struct Fpu<const N: usize> {
    beta: f64,
}

#[lagrangian]
impl<const N: usize> Fpu<N> {
    fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
        let mut kinetic = 0.0;
        for i in 0..N {
            kinetic += 0.5 * v[i] * v[i];
        }
        let mut d = q[0];
        let mut potential = 0.5 * d * d + 0.25 * self.beta * d.powi(4);
        for i in 0..N - 1 {
            d = q[i + 1] - q[i];
            potential += 0.5 * d * d + 0.25 * self.beta * d.powi(4);
        }
        d = q[N - 1];
        potential += 0.5 * d * d + 0.25 * self.beta * d.powi(4);
        kinetic - potential
    }
}

/// The same chain with its length known at run time: `q.len()` masses.
#[derive(Clone)]
struct Chain {
    n: usize,
    beta: f64,
}

#[lagrangian]
impl Chain {
    fn dimension(&self) -> usize {
        self.n
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        let mut kinetic = 0.0;
        for i in 0..v.len() {
            kinetic += 0.5 * v[i] * v[i];
        }
        let mut d = q[0];
        let mut potential = 0.5 * d * d + 0.25 * self.beta * d.powi(4);
        for i in 0..q.len() - 1 {
            d = q[i + 1] - q[i];
            potential += 0.5 * d * d + 0.25 * self.beta * d.powi(4);
        }
        d = q[q.len() - 1];
        potential += 0.5 * d * d + 0.25 * self.beta * d.powi(4);
        kinetic - potential
    }
}

/// The harmonic energy of normal mode `k` (1-based):
/// `E_k = ½ (Ȧ_k² + ω_k² A_k²)` with `A_k = √(2/(N+1)) Σ qᵢ sin(ikπ/(N+1))`,
/// `ω_k = 2 sin(kπ / (2(N+1)))`; unit masses, so `q̇ = p`.
fn mode_energy(q: &[f64], p: &[f64], k: usize) -> f64 {
    let n = q.len();
    let scale = (2.0 / (n + 1) as f64).sqrt();
    let (mut a, mut da) = (0.0, 0.0);
    for i in 0..n {
        let s = ((i + 1) * k) as f64 * PI / (n + 1) as f64;
        a += q[i] * s.sin();
        da += p[i] * s.sin();
    }
    let omega = 2.0 * (k as f64 * PI / (2.0 * (n + 1) as f64)).sin();
    0.5 * scale * scale * (da * da + omega * omega * a * a)
}

/// Normal mode `k` of `n` masses with amplitude `a`, at rest.
fn mode(n: usize, k: usize, a: f64) -> Vec<f64> {
    (0..n).map(|i| a * ((i + 1) as f64 * k as f64 * PI / (n + 1) as f64).sin()).collect()
}

struct Run {
    /// `(t, E_k)` for each plotted mode.
    modes: Vec<Vec<(f64, f64)>>,
    /// `(t, |E − E₀| / E₀)`.
    energy_error: Vec<(f64, f64)>,
    seconds: f64,
    steps: usize,
}

fn run<const N: usize>(
    beta: f64,
    (excited, amplitude): (usize, f64),
    h: f64,
    steps: usize,
    every: usize,
    modes: &[usize],
) -> Result<Run, Box<dyn Error>> {
    let q0: [f64; N] = mode(N, excited, amplitude).try_into().map_err(|_| "N masses")?;
    let mut sim = Integrator::new(Fpu::<N> { beta }, Trapezoid, h).start(0.0, q0, [0.0; N])?;
    let e0 = sim.energy()?;
    let mut out = Run { modes: vec![Vec::new(); modes.len()], energy_error: Vec::new(), seconds: 0.0, steps };
    let record = |sim: &Integrator<Fpu<N>, Trapezoid, N>, out: &mut Run| -> Result<(), Box<dyn Error>> {
        let s = sim.state();
        for (series, &k) in out.modes.iter_mut().zip(modes) {
            series.push((s.t, mode_energy(&s.q, &s.p, k)));
        }
        out.energy_error.push((s.t, (sim.energy()? - e0).abs() / e0));
        Ok(())
    };
    record(&sim, &mut out)?;
    for _ in 0..steps / every {
        let start = Instant::now();
        sim.run(every, |_| {})?;
        out.seconds += start.elapsed().as_secs_f64();
        record(&sim, &mut out)?;
    }
    assert_eq!(sim.stats().newton_iterations, 0, "the explicit path takes no Newton iteration");
    Ok(out)
}

fn plot_modes(
    dir: &std::path::Path,
    stem: &str,
    title: &str,
    run: &Run,
    modes: &[usize],
    e0: f64,
) -> Result<(), Box<dyn Error>> {
    let labels: Vec<String> = modes.iter().map(|k| format!("mode {k}")).collect();
    let scaled: Vec<Vec<(f64, f64)>> =
        run.modes.iter().map(|s| s.iter().map(|&(t, e)| (t, e / e0)).collect()).collect();
    let error: Vec<(f64, f64)> = run.energy_error.iter().map(|&(t, e)| (t, e.max(1e-17).log10())).collect();
    let t_end = run.energy_error.last().map_or(1.0, |p| p.0);
    Figure {
        title,
        x_label: "t",
        x_range: (0.0, t_end),
        panels: vec![
            Panel {
                y_label: "E_k / E",
                series: scaled
                    .iter()
                    .zip(&labels)
                    .map(|(points, label)| Series { label, points, markers: false })
                    .collect(),
            },
            Panel {
                y_label: "log10 |ΔE/E₀|",
                series: vec![Series { label: "total energy", points: &error, markers: false }],
            },
        ],
        equal_axes: false,
    }
    .save(&dir.join(stem), 1000)
}

fn main() -> Result<(), Box<dyn Error>> {
    let dir = plot::output_dir("fpu_chain")?;
    let beta = 1.0;

    // 1. The recurrence, N = 32, all the energy in mode 1.
    let (amplitude, h) = (1.5, 0.1);
    let modes = [1, 3, 5];
    let small = run::<32>(beta, (1, amplitude), h, 200_000, 100, &modes)?;
    let e0 = mode_energy(&mode(32, 1, amplitude), &[0.0; 32], 1);
    let first = &small.modes[0];
    // The recurrence: the lowest point of mode 1's energy, and its largest
    // return after that.
    let low = (0..first.len()).min_by(|&a, &b| first[a].1.total_cmp(&first[b].1)).unwrap_or(0);
    let (t_low, least) = first[low];
    let (t_back, back) = first[low..].iter().copied().fold((t_low, least), |m, p| if p.1 > m.1 { p } else { m });
    let worst = small.energy_error.iter().fold(0.0f64, |m, p| m.max(p.1));
    println!(
        "N = 32, β = {beta}, mode 1 amplitude {amplitude}, h = {h}, {} explicit steps ({:.0} ns/step):",
        small.steps,
        small.seconds / small.steps as f64 * 1e9
    );
    println!(
        "  mode 1 falls to {:.1}% of the energy at t = {t_low:.0} and returns to {:.1}% at t = {t_back:.0}",
        100.0 * least / e0,
        100.0 * back / e0
    );
    println!("  largest relative energy error {worst:.2e}");
    let title = "FPU-β, N = 32: energy of normal modes 1, 3, 5 (the recurrence)";
    plot_modes(&dir, "modes_n32", title, &small, &modes, e0)?;

    // 2. Ten thousand masses, a run-time length, mode 1000 excited with strains of about 1.
    let n = 10_000;
    let excited = 1_000;
    let amplitude = 1.0 * n as f64 / (excited as f64 * PI);
    let modes = [excited, 3 * excited, 5 * excited];
    let chain = Chain { n, beta };
    let q0 = mode(n, excited, amplitude);
    let (steps, every) = (5_000, 50);
    let mut sim = Problem::new(chain, 0.0, q0.clone(), vec![0.0; n]).stepper(&Scheme::TRAPEZOID, h)?;
    let e_total = sim.energy()?;
    let mut big = Run { modes: vec![Vec::new(); modes.len()], energy_error: Vec::new(), seconds: 0.0, steps };
    let record = |sim: &Stepper<Chain, Dyn>, out: &mut Run| -> Result<(), Box<dyn Error>> {
        let s = sim.state();
        for (series, &k) in out.modes.iter_mut().zip(&modes) {
            series.push((s.t, mode_energy(&s.q, &s.p, k)));
        }
        out.energy_error.push((s.t, (sim.energy()? - e_total).abs() / e_total));
        Ok(())
    };
    record(&sim, &mut big)?;
    for _ in 0..steps / every {
        let start = Instant::now();
        sim.run(every, |_| {})?;
        big.seconds += start.elapsed().as_secs_f64();
        record(&sim, &mut big)?;
    }
    assert_eq!(sim.stats().newton_iterations, 0, "the explicit path takes no Newton iteration");
    // The implicit midpoint rule with banded Newton solves, for its cost.
    let mut implicit = Problem::new(Chain { n, beta }, 0.0, q0.clone(), vec![0.0; n]).stepper(&Scheme::MIDPOINT, h)?;
    let start = Instant::now();
    implicit.run(20, |_| {})?;
    let midpoint_step = start.elapsed().as_secs_f64() / 20.0;
    let iterations = implicit.stats().newton_iterations as f64 / 20.0;
    let e0 = mode_energy(&q0, &vec![0.0; n], excited);
    let worst = big.energy_error.iter().fold(0.0f64, |m, p| m.max(p.1));
    let kept = big.modes[0].last().map_or(f64::NAN, |p| p.1) / e0;
    println!(
        "N = {n} (run-time length), mode {excited} amplitude {amplitude:.2}: {} explicit steps, {:.2} ms/step; mode {excited} keeps {:.1}% of the energy at t = {:.0}; largest relative energy error {worst:.2e}",
        big.steps,
        big.seconds / big.steps as f64 * 1e3,
        100.0 * kept,
        big.steps as f64 * h
    );
    println!(
        "  midpoint (banded Newton): {:.1} ms/step, {iterations:.2} Newton iterations per step",
        midpoint_step * 1e3
    );
    let title = format!("FPU-β, N = {n}: energy of normal modes {excited}, {}, {}", 3 * excited, 5 * excited);
    plot_modes(&dir, &format!("modes_n{n}"), &title, &big, &modes, e0)?;
    println!("plots: {}", dir.display());
    Ok(())
}
