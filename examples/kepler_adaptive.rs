//! Adaptive steps that keep the structure: Kepler e = 0.9 and e = 0.99 over
//! 1000 orbits with a time-transformed Galerkin method (s = 4, order 8 in
//! the new time `s`, `dt/ds = r^{3/2}`; docs/time-transformation.md),
//! against fixed steps of the same method and the same number of steps.
//!
//! Prints, for each orbit and each integrator, the steps, the final position
//! error against Kepler's equation, the largest relative energy error and
//! the drift of the angular momentum; writes the orbits (equal axes) and the
//! energy error against time into `target/example-output/kepler_adaptive/`
//! (or `$LAGRANGIAN_OUT`).
//!
//! Run with `cargo run --release --example kepler_adaptive`.

#[path = "support/plot.rs"]
mod plot;

use std::error::Error;
use std::f64::consts::PI;
use std::path::Path;
use std::time::Instant;

use lagrangian::prelude::*;
use plot::{Figure, Panel, Series};
use plotters::prelude::*;

/// Planar Kepler, `μ = 1`, Cartesian.
#[derive(Clone, Copy, Debug)]
struct Kepler;

#[lagrangian]
impl Kepler {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) + 1.0 / (q[0] * q[0] + q[1] * q[1]).sqrt()
    }
}

const ORBITS: usize = 1000;

/// `E − e sin E = m`: Newton, kept inside the bracket `[m − e, m + e]` by bisection.
fn eccentric_anomaly(e: f64, m: f64) -> f64 {
    let (mut lo, mut hi) = (m - e, m + e);
    let mut x = m + e * m.sin();
    for _ in 0..100 {
        let f = x - e * x.sin() - m;
        if f > 0.0 {
            hi = x;
        } else {
            lo = x;
        }
        let mut next = x - f / (1.0 - e * x.cos());
        if !(next > lo && next < hi) {
            next = 0.5 * (lo + hi);
        }
        let done = (next - x).abs() <= f64::EPSILON * next.abs().max(1.0);
        x = next;
        if done {
            break;
        }
    }
    x
}

/// The exact position at `t` (semi-major axis 1, pericentre on +x at `t = 0`).
fn exact(e: f64, t: f64) -> [f64; 2] {
    let ea = eccentric_anomaly(e, t);
    [ea.cos() - e, (1.0 - e * e).sqrt() * ea.sin()]
}

/// What one run recorded.
struct Record {
    label: String,
    steps: u64,
    seconds: f64,
    /// Where the run stopped early, if it did.
    stopped: Option<String>,
    /// Final time reached and position error there.
    t: f64,
    position_error: f64,
    energy_max: f64,
    /// The largest `|ΔE/E0|` in each tenth of the run: flat when bounded.
    tenths: [f64; 10],
    momentum_drift: f64,
    /// `(t, log10 |ΔE/E0|)`, thinned for the plot.
    energy: Vec<(f64, f64)>,
    /// Positions, thinned.
    orbit: Vec<(f64, f64)>,
}

impl Record {
    fn new(label: String) -> Self {
        Record {
            label,
            steps: 0,
            seconds: 0.0,
            stopped: None,
            t: 0.0,
            position_error: f64::NAN,
            energy_max: 0.0,
            tenths: [0.0; 10],
            momentum_drift: 0.0,
            energy: Vec::new(),
            orbit: Vec::new(),
        }
    }

    /// Records the state after a step.
    fn observe(&mut self, e0: f64, j0: f64, s: &State<2>, energy: f64, keep: bool) {
        let de = ((energy - e0) / e0).abs();
        self.energy_max = self.energy_max.max(de);
        let k = ((s.t / (2.0 * PI * ORBITS as f64) * 10.0) as usize).min(9);
        self.tenths[k] = self.tenths[k].max(de);
        let j = s.q[0] * s.p[1] - s.q[1] * s.p[0];
        self.momentum_drift = self.momentum_drift.max(((j - j0) / j0).abs());
        if keep {
            // A floor keeps log10 finite where the error is exactly 0.
            self.energy.push((s.t, de.max(1e-17).log10()));
            self.orbit.push((s.q[0], s.q[1]));
        }
    }

    fn finish(&mut self, e: f64, s: &State<2>, steps: u64, seconds: f64) {
        let x = exact(e, s.t);
        self.t = s.t;
        self.position_error = (s.q[0] - x[0]).hypot(s.q[1] - x[1]);
        self.steps = steps;
        self.seconds = seconds;
    }

    fn print(&self) {
        print!(
            "  {:<44} {:>7} steps  {:>7.1} ms  position error {:.2e}  max |ΔE/E| {:.2e}  max |ΔJ/J| {:.1e}",
            self.label,
            self.steps,
            self.seconds * 1e3,
            self.position_error,
            self.energy_max,
            self.momentum_drift
        );
        match &self.stopped {
            Some(why) => println!("  stopped at t = {:.2}: {why}", self.t),
            None => println!(),
        }
        if self.stopped.is_none() && self.energy_max < 1e-2 {
            let t: Vec<String> = self.tenths.iter().map(|x| format!("{x:.1e}")).collect();
            println!("    max |ΔE/E| per 100 orbits: {}", t.join(" "));
        }
    }
}

/// The time-transformed run: Galerkin s = 4 in `s`, `g = r^{3/2}`, step `sigma`.
fn adaptive(e: f64, sigma: f64) -> Result<Record, Box<dyn Error>> {
    let t_end = 2.0 * PI * ORBITS as f64;
    let (q0, v0) = ([1.0 - e, 0.0], [0.0, ((1.0 + e) / (1.0 - e)).sqrt()]);
    let g = RadiusPower::new([0, 1], 1.5).ok_or("invalid monitor")?;
    let clock = Instant::now();
    let mut sim = TimeTransformed::new(Kepler, g).galerkin(Galerkin::<4, 4>::gauss(), sigma).start(0.0, q0, v0)?;
    let e0 = sim.energy()?;
    let s0 = sim.state();
    let j0 = s0.q[0] * s0.p[1] - s0.q[1] * s0.p[0];
    let mut rec = Record::new(format!("time-transformed Galerkin s = 4, σ = {sigma}"));
    rec.observe(e0, j0, &s0, e0, true);
    // Landing once at the end: a partial step shifts the modified energy.
    sim.run_until(t_end, |s| {
        let keep = s.stats().steps % 8 == 0;
        rec.observe(e0, j0, &s.state(), s.energy().unwrap_or(f64::NAN), keep);
    })?;
    let seconds = clock.elapsed().as_secs_f64();
    rec.finish(e, &sim.state(), sim.stats().steps, seconds);
    Ok(rec)
}

/// Fixed steps of the same method, `n` of them over the same span.
fn fixed(e: f64, n: u64) -> Result<Record, Box<dyn Error>> {
    let t_end = 2.0 * PI * ORBITS as f64;
    let (q0, v0) = ([1.0 - e, 0.0], [0.0, ((1.0 + e) / (1.0 - e)).sqrt()]);
    let clock = Instant::now();
    let mut sim = GalerkinIntegrator::new(Kepler, Galerkin::<4, 4>::gauss(), t_end / n as f64).start(0.0, q0, v0)?;
    let e0 = sim.energy()?;
    let s0 = *sim.state();
    let j0 = s0.q[0] * s0.p[1] - s0.q[1] * s0.p[0];
    let mut rec = Record::new(format!("fixed-step Galerkin s = 4, h = {:.4}", t_end / n as f64));
    rec.observe(e0, j0, &s0, e0, true);
    let result = sim.run(n as usize, |s| {
        let keep = s.stats().steps % 8 == 0;
        rec.observe(e0, j0, s.state(), s.energy().unwrap_or(f64::NAN), keep);
    });
    if let Err(err) = result {
        rec.stopped = Some(err.to_string());
    }
    let seconds = clock.elapsed().as_secs_f64();
    rec.finish(e, sim.state(), sim.stats().steps, seconds);
    Ok(rec)
}

/// The orbits with equal scales on both axes (the helper's figures share
/// only a time axis).
fn orbit_plot(path: &Path, title: &str, runs: &[&Record]) -> Result<(), Box<dyn Error>> {
    let font = include_bytes!("support/DejaVuSans.ttf");
    // Registering twice is harmless; a failure only means the font was there.
    let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, font);
    let points = runs.iter().flat_map(|r| r.orbit.iter()).filter(|p| p.0.abs() < 3.0 && p.1.abs() < 3.0);
    let (x0, x1, y0, y1) = points
        .fold((0.0f64, 0.0f64, 0.0f64, 0.0f64), |(a, b, c, d), p| (a.min(p.0), b.max(p.0), c.min(p.1), d.max(p.1)));
    let pad = 0.05 * (x1 - x0).max(y1 - y0);
    let (x0, x1, y0, y1) = (x0 - pad, x1 + pad, y0 - pad, y1 + pad);
    // Plot area of 900 px across; its height follows the data's aspect ratio.
    let width = 900.0;
    let height = (width * (y1 - y0) / (x1 - x0)).max(120.0);
    let size = ((width + 100.0) as u32, (height + 110.0) as u32);
    let range = (x0, x1, y0, y1);
    draw_orbits(BitMapBackend::new(&path.with_extension("png"), size).into_drawing_area(), title, runs, range)?;
    draw_orbits(SVGBackend::new(&path.with_extension("svg"), size).into_drawing_area(), title, runs, range)?;
    Ok(())
}

fn draw_orbits<B: DrawingBackend>(
    root: DrawingArea<B, plotters::coord::Shift>,
    title: &str,
    runs: &[&Record],
    (x0, x1, y0, y1): (f64, f64, f64, f64),
) -> Result<(), Box<dyn Error>>
where
    B::ErrorType: 'static,
{
    const COLORS: [RGBColor; 2] = [RGBColor(31, 119, 180), RGBColor(214, 39, 40)];
    root.fill(&WHITE)?;
    let root = root.titled(title, ("sans-serif", 20))?;
    let mut chart = ChartBuilder::on(&root)
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(x0..x1, y0..y1)?;
    chart.configure_mesh().x_desc("x").y_desc("y").label_style(("sans-serif", 14)).draw()?;
    for (run, color) in runs.iter().zip(COLORS) {
        let inside = run.orbit.iter().copied().filter(|p| p.0 >= x0 && p.0 <= x1 && p.1 >= y0 && p.1 <= y1);
        chart
            .draw_series(inside.map(|p| Circle::new(p, 1, color.filled())))?
            .label(run.label.as_str())
            .legend(move |(x, y)| Circle::new((x + 10, y), 3, color.filled()));
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .label_font(("sans-serif", 14))
        .draw()?;
    root.present()?;
    Ok(())
}

fn main() -> Result<(), Box<dyn Error>> {
    let dir = plot::output_dir("kepler_adaptive")?;
    println!("Kepler over {ORBITS} orbits (T = {:.1}); position error against Kepler's equation", 2000.0 * PI);
    for (e, sigma) in [(0.9, 0.3), (0.99, 0.25)] {
        println!("e = {e}:");
        let tt = adaptive(e, sigma)?;
        tt.print();
        let fx = fixed(e, tt.steps)?;
        fx.print();
        let tag = format!("e{}", e.to_string().replace('.', "_"));
        orbit_plot(
            &dir.join(format!("orbit_{tag}")),
            &format!("Kepler e = {e}, {ORBITS} orbits, every 8th step (equal axes)"),
            &[&tt, &fx],
        )?;
        Figure {
            title: &format!("Kepler e = {e}: relative energy error, {} steps each", tt.steps),
            x_label: "t",
            x_range: (0.0, 2.0 * PI * ORBITS as f64),
            panels: vec![Panel {
                y_label: "log10 |ΔE/E0|",
                series: vec![
                    Series { label: &tt.label, points: &tt.energy, markers: false },
                    Series { label: &fx.label, points: &fx.energy, markers: false },
                ],
            }],
            equal_axes: false,
        }
        .save(&dir.join(format!("energy_{tag}")), 1000)?;
    }
    println!("plots: {}", dir.display());
    Ok(())
}
