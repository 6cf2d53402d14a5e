//! Figures for the examples: stacked panels of line series sharing one time
//! axis, written as PNG and SVG with plotters.
//!
//! The font is bundled (DejaVu Sans, licence beside it) and drawn through
//! ab_glyph, so the examples need no system font library. Include this file
//! from an example with `#[path = "support/plot.rs"] mod plot;`.
#![allow(dead_code, unreachable_pub)]

use std::error::Error;
use std::path::{Path, PathBuf};
use std::sync::Once;

use plotters::coord::Shift;
use plotters::prelude::*;

/// One curve of a panel.
pub struct Series<'a> {
    /// Legend text; empty for no legend entry.
    pub label: &'a str,
    /// `(x, y)` points, drawn as a polyline.
    pub points: &'a [(f64, f64)],
    /// Draw a dot at every point as well as the line (for sparse step data).
    pub markers: bool,
}

/// One plot area: a y axis and its series.
pub struct Panel<'a> {
    /// Label of the y axis.
    pub y_label: &'a str,
    /// The curves.
    pub series: Vec<Series<'a>>,
}

/// A figure of panels stacked vertically over a shared x range.
pub struct Figure<'a> {
    /// Title above the first panel.
    pub title: &'a str,
    /// Label of the x axis (under the last panel).
    pub x_label: &'a str,
    /// The x range shown.
    pub x_range: (f64, f64),
    /// The panels, top to bottom.
    pub panels: Vec<Panel<'a>>,
}

const COLORS: [RGBColor; 4] = [RGBColor(31, 119, 180), RGBColor(214, 39, 40), RGBColor(44, 160, 44), BLACK];

fn register_font() {
    static FONT: Once = Once::new();
    FONT.call_once(|| {
        plotters::style::register_font("sans-serif", FontStyle::Normal, include_bytes!("DejaVuSans.ttf"))
            .unwrap_or_else(|_| panic!("the bundled font is a valid TrueType file"));
    });
}

/// The directory the examples write to: `$LAGRANGIAN_OUT`, or
/// `target/example-output/<name>`; created if missing.
pub fn output_dir(name: &str) -> std::io::Result<PathBuf> {
    let base = std::env::var_os("LAGRANGIAN_OUT").map_or_else(|| PathBuf::from("target/example-output"), PathBuf::from);
    let dir = base.join(name);
    std::fs::create_dir_all(&dir)?;
    Ok(dir)
}

impl Figure<'_> {
    /// Writes `<stem>.png` and `<stem>.svg`, `width × 320·panels` pixels.
    pub fn save(&self, stem: &Path, width: u32) -> Result<(), Box<dyn Error>> {
        register_font();
        let height = 60 + 300 * self.panels.len() as u32;
        let png = stem.with_extension("png");
        let svg = stem.with_extension("svg");
        self.draw(BitMapBackend::new(&png, (width, height)).into_drawing_area())?;
        self.draw(SVGBackend::new(&svg, (width, height)).into_drawing_area())?;
        Ok(())
    }

    fn draw<B: DrawingBackend>(&self, root: DrawingArea<B, Shift>) -> Result<(), Box<dyn Error>>
    where
        B::ErrorType: 'static,
    {
        root.fill(&WHITE)?;
        let root = root.titled(self.title, ("sans-serif", 22))?;
        let areas = root.split_evenly((self.panels.len(), 1));
        for (k, (panel, area)) in self.panels.iter().zip(&areas).enumerate() {
            let (y_min, y_max) = y_range(panel, self.x_range);
            let last = k + 1 == self.panels.len();
            let mut chart = ChartBuilder::on(area)
                .margin(12)
                .x_label_area_size(if last { 45 } else { 25 })
                .y_label_area_size(80)
                .build_cartesian_2d(self.x_range.0..self.x_range.1, y_min..y_max)?;
            let mut mesh = chart.configure_mesh();
            mesh.y_desc(panel.y_label).label_style(("sans-serif", 15)).light_line_style(WHITE.mix(0.0));
            if last {
                mesh.x_desc(self.x_label);
            }
            mesh.draw()?;
            let mut legend = false;
            for (i, s) in panel.series.iter().enumerate() {
                let color = COLORS[i % COLORS.len()];
                let visible = s.points.iter().copied().filter(|(x, _)| *x >= self.x_range.0 && *x <= self.x_range.1);
                let drawn = chart.draw_series(LineSeries::new(visible.clone(), color.stroke_width(1)))?;
                if !s.label.is_empty() {
                    legend = true;
                    drawn.label(s.label).legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], color));
                }
                if s.markers {
                    chart.draw_series(visible.map(|p| Circle::new(p, 2, color.filled())))?;
                }
            }
            if legend {
                chart
                    .configure_series_labels()
                    .background_style(WHITE.mix(0.8))
                    .border_style(BLACK)
                    .label_font(("sans-serif", 14))
                    .draw()?;
            }
        }
        root.present()?;
        Ok(())
    }
}

/// The y range of a panel's data inside the x range, padded by 5%.
fn y_range(panel: &Panel<'_>, (x0, x1): (f64, f64)) -> (f64, f64) {
    let (lo, hi) = panel
        .series
        .iter()
        .flat_map(|s| s.points.iter().filter(|p| p.0 >= x0 && p.0 <= x1).map(|p| p.1))
        .filter(|y| y.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), y| (lo.min(y), hi.max(y)));
    if !lo.is_finite() {
        return (-1.0, 1.0);
    }
    let pad = 0.05 * (hi - lo).max(1e-12 * hi.abs().max(1.0));
    (lo - pad, hi + pad)
}
