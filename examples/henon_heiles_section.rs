//! The Poincaré section of the Hénon–Heiles system at energy 1/8: the
//! crossings of the plane x = 0 with ẋ > 0, plotted as (y, ẏ).
//!
//! Events locate every crossing on the quintic dense output of a Galerkin
//! s = 3 run (order 6); twelve orbits run as an ensemble (in parallel with
//! the `rayon` feature). Regular orbits draw closed curves, chaotic ones fill
//! areas. Writes `henon_heiles_section.{png,svg}` and `.csv` (the crossings)
//! to `target/example-output/henon_heiles_section/`.
//!
//! `cargo run --release --example henon_heiles_section --features rayon`

#[path = "support/plot.rs"]
mod plot;

use lagrangian::ensemble;
use lagrangian::prelude::*;
use lagrangian::{DenseKind, Direction, Event, EventRecord, Plan};
use plotters::prelude::*;

/// `L = ½|v|² − ½(x² + y²) − x²y + y³/3`.
#[derive(Clone)]
pub struct HenonHeiles;

#[lagrangian]
impl HenonHeiles {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let (x, y) = (q[0], q[1]);
        0.5 * (v[0] * v[0] + v[1] * v[1]) - 0.5 * (x * x + y * y) - x * x * y + y * y * y / 3.0
    }
}

const ENERGY: f64 = 0.125;
const T_END: f64 = 2000.0;

/// Starts on the section: x = 0, given (y, ẏ), ẋ > 0 from the energy.
fn start(y: f64, vy: f64) -> Option<([f64; 2], [f64; 2])> {
    let vx2 = 2.0 * ENERGY - vy * vy - y * y + 2.0 * y * y * y / 3.0;
    (vx2 > 0.0).then(|| ([0.0, y], [vx2.sqrt(), vy]))
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let inputs: Vec<(f64, f64)> = (0..12).map(|i| (-0.25 + 0.06 * i as f64, 0.0)).collect();
    let clock = std::time::Instant::now();
    let runs = ensemble::run(&inputs, |_, &(y, vy)| -> Result<Vec<EventRecord>, String> {
        let (q, v) = start(y, vy).ok_or("outside the energy surface")?;
        let mut sim = GalerkinIntegrator::new(HenonHeiles, Galerkin::<3, 3>::gauss(), 0.1)
            .start(0.0, q, v)
            .map_err(|e| e.to_string())?;
        let plan = Plan::until(T_END)
            .every(0)
            .dense(DenseKind::Quintic)
            .energy_tolerance(1e-9)
            .event(Event::new(|_, q, _| q[0]).direction(Direction::Rising));
        let sol = sim.solve(plan).map_err(|e| e.to_string())?.into_result().map_err(|e| e.to_string())?;
        if let Some(warning) = sol.energy_warning() {
            eprintln!("y0 = {y}: {warning}");
        }
        Ok(sol.events)
    });
    println!("{} orbits to t = {T_END} in {:.2} s", inputs.len(), clock.elapsed().as_secs_f64());
    for (i, e) in runs.failures() {
        println!("orbit {i} failed: {e}");
    }

    // Every crossing lies on the plane and on the energy surface.
    let (mut worst_x, mut worst_e, mut count) = (0.0f64, 0.0f64, 0);
    let dir = plot::output_dir("henon_heiles_section")?;
    let mut csv = String::from("orbit,t,y,vy\n");
    for (i, events) in runs.successes() {
        for e in events {
            worst_x = worst_x.max(e.q[0].abs());
            let (q, v): ([f64; 2], [f64; 2]) = (e.q.as_slice().try_into()?, e.v.as_slice().try_into()?);
            worst_e = worst_e.max((HenonHeiles.energy(e.t, q, v) - ENERGY).abs());
            csv.push_str(&format!("{i},{},{},{}\n", e.t, e.q[1], e.v[1]));
            count += 1;
        }
    }
    println!("{count} crossings; |x| ≤ {worst_x:.1e} there, energy error ≤ {worst_e:.1e}");
    std::fs::write(dir.join("henon_heiles_section.csv"), csv)?;

    plotters::style::register_font("sans-serif", FontStyle::Normal, include_bytes!("support/DejaVuSans.ttf"))
        .map_err(|_| "the bundled font is not a valid TrueType file")?;
    let png = dir.join("henon_heiles_section.png");
    let svg = dir.join("henon_heiles_section.svg");
    draw(BitMapBackend::new(&png, (900, 900)).into_drawing_area(), &runs)?;
    draw(SVGBackend::new(&svg, (900, 900)).into_drawing_area(), &runs)?;
    println!("wrote {} and {}", png.display(), svg.display());
    Ok(())
}

/// A tick label with at most one decimal, never "-0".
fn tick(x: &f64) -> String {
    plot::tick_label(*x, 1)
}

fn draw<B: DrawingBackend>(
    root: DrawingArea<B, plotters::coord::Shift>,
    runs: &ensemble::Ensemble<Vec<EventRecord>, String>,
) -> Result<(), Box<dyn std::error::Error>>
where
    B::ErrorType: 'static,
{
    root.fill(&WHITE)?;
    // Equal scales on both axes: the section is drawn undistorted.
    let mut chart = ChartBuilder::on(&root)
        .caption("Hénon–Heiles, E = 1/8: section x = 0, ẋ > 0", ("sans-serif", 22))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(60)
        .build_cartesian_2d(-0.45f64..0.65f64, -0.55f64..0.55f64)?;
    chart
        .configure_mesh()
        .x_desc("y")
        .y_desc("ẏ")
        .label_style(("sans-serif", 16))
        .x_label_formatter(&tick)
        .y_label_formatter(&tick)
        .draw()?;
    for (i, events) in runs.successes() {
        let color = Palette99::pick(i).to_rgba();
        chart.draw_series(events.iter().map(|e| Circle::new((e.q[1], e.v[1]), 1, color.filled())))?;
    }
    root.present()?;
    Ok(())
}
