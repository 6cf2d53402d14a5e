//! Figures for the examples: stacked panels of line series sharing one x
//! axis, written as PNG and SVG with plotters.
//!
//! The font is bundled (DejaVu Sans, licence beside it) and drawn through
//! ab_glyph, so the examples need no system font library. Include this file
//! from an example with `#[path = "support/plot.rs"] mod plot;`. Write
//! subscripts and Greek letters as Unicode (`τₖ`, `E₀`, `ẋ`): the text is
//! drawn as given, with no markup.
#![allow(dead_code, unreachable_pub)]

use std::error::Error;
use std::path::{Path, PathBuf};
use std::sync::Once;

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

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
    /// Draw x and y to the same scale (orbits, phase portraits): the height
    /// of each panel then follows from its y range and the width.
    pub equal_axes: bool,
}

const COLORS: [RGBColor; 4] = [RGBColor(31, 119, 180), RGBColor(214, 39, 40), RGBColor(44, 160, 44), BLACK];

// Layout in pixels. The right margin leaves room for half of the last x tick
// label, which is centred on the plot's edge.
const TITLE_HEIGHT: u32 = 44;
const MARGIN: u32 = 12;
const MARGIN_RIGHT: u32 = 36;
const Y_LABEL_AREA: u32 = 90;
const X_LABEL_AREA_LAST: u32 = 50;
const X_LABEL_AREA: u32 = 30;
const PANEL_HEIGHT: u32 = 300;
const TICK_FONT: u32 = 15;
const LEGEND_FONT: u32 = 14;
// Tick labels requested per axis; `tick_decimals` assumes this count.
const LABELS: usize = 10;

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

/// Where a panel's legend goes.
#[derive(Clone, Copy)]
enum Corner {
    UpperLeft,
    UpperRight,
    LowerLeft,
    LowerRight,
}

impl Corner {
    fn position(self) -> SeriesLabelPosition {
        match self {
            Corner::UpperLeft => SeriesLabelPosition::UpperLeft,
            Corner::UpperRight => SeriesLabelPosition::UpperRight,
            Corner::LowerLeft => SeriesLabelPosition::LowerLeft,
            Corner::LowerRight => SeriesLabelPosition::LowerRight,
        }
    }
}

/// A panel laid out: its y range, pixel height and legend corner.
struct Layout {
    y_range: (f64, f64),
    height: u32,
    legend: Corner,
}

impl Figure<'_> {
    /// Writes `<stem>.png` and `<stem>.svg`, `width` pixels wide; each panel
    /// is 300 pixels high, or as high as equal axes need.
    pub fn save(&self, stem: &Path, width: u32) -> Result<(), Box<dyn Error>> {
        register_font();
        let layouts = self.layout(width)?;
        let height = TITLE_HEIGHT + layouts.iter().map(|l| l.height).sum::<u32>();
        let png = stem.with_extension("png");
        let svg = stem.with_extension("svg");
        self.draw(BitMapBackend::new(&png, (width, height)).into_drawing_area(), &layouts)?;
        self.draw(SVGBackend::new(&svg, (width, height)).into_drawing_area(), &layouts)?;
        Ok(())
    }

    fn layout(&self, width: u32) -> Result<Vec<Layout>, Box<dyn Error>> {
        let (x0, x1) = self.x_range;
        let plot_width = f64::from(width.saturating_sub(MARGIN + MARGIN_RIGHT + Y_LABEL_AREA).max(1));
        let mut out = Vec::with_capacity(self.panels.len());
        for (k, panel) in self.panels.iter().enumerate() {
            let x_area = if k + 1 == self.panels.len() { X_LABEL_AREA_LAST } else { X_LABEL_AREA };
            let frame = 2 * MARGIN + x_area;
            let (mut lo, mut hi) = y_range(panel, self.x_range);
            let fixed_plot_height = f64::from(PANEL_HEIGHT - frame);
            // Pixels per unit of y: fixed by the width for equal axes.
            let scale_y = |lo: f64, hi: f64| {
                if self.equal_axes { plot_width / (x1 - x0) } else { fixed_plot_height / (hi - lo) }
            };
            let legend = legend_size(panel)?;
            let mut corner = Corner::UpperRight;
            if let Some((w, h)) = legend {
                let (sx, sy) = (plot_width / (x1 - x0), scale_y(lo, hi));
                let count = |c: Corner, lo: f64, hi: f64| -> usize {
                    let (bx, by) = (w / sx, h / sy);
                    let (xa, xb) = match c {
                        Corner::UpperLeft | Corner::LowerLeft => (x0, x0 + bx),
                        Corner::UpperRight | Corner::LowerRight => (x1 - bx, x1),
                    };
                    let (ya, yb) = match c {
                        Corner::UpperLeft | Corner::UpperRight => (hi - by, hi),
                        Corner::LowerLeft | Corner::LowerRight => (lo, lo + by),
                    };
                    panel
                        .series
                        .iter()
                        .flat_map(|s| s.points.iter())
                        .filter(|p| p.0 >= xa && p.0 <= xb && p.1 >= ya && p.1 <= yb)
                        .count()
                };
                let corners = [Corner::UpperRight, Corner::UpperLeft, Corner::LowerRight, Corner::LowerLeft];
                let (best, hits) =
                    corners.iter().map(|&c| (c, count(c, lo, hi))).min_by_key(|p| p.1).unwrap_or((corner, 0));
                corner = best;
                if hits > 0 {
                    // Every corner has data under it: make room above the data.
                    corner = Corner::UpperRight;
                    let extra = if self.equal_axes {
                        h / sy
                    } else {
                        // Grow the range so that the band h pixels high is free.
                        (hi - lo) * h / (fixed_plot_height - h).max(1.0)
                    };
                    hi += extra;
                }
            }
            if self.equal_axes {
                // A centred pad keeps the data off the frame.
                let pad = 0.02 * (hi - lo);
                lo -= pad;
                hi += pad;
            }
            let height =
                if self.equal_axes { frame + (scale_y(lo, hi) * (hi - lo)).round() as u32 } else { PANEL_HEIGHT };
            out.push(Layout { y_range: (lo, hi), height, legend: corner });
        }
        Ok(out)
    }

    fn draw<B: DrawingBackend>(&self, root: DrawingArea<B, Shift>, layouts: &[Layout]) -> Result<(), Box<dyn Error>>
    where
        B::ErrorType: 'static,
    {
        root.fill(&WHITE)?;
        let (title, mut rest) = root.split_vertically(TITLE_HEIGHT);
        let (w, _) = title.dim_in_pixel();
        let style = TextStyle::from(("sans-serif", 22).into_font()).pos(Pos::new(HPos::Center, VPos::Center));
        title.draw_text(self.title, &style, (w as i32 / 2, TITLE_HEIGHT as i32 / 2))?;
        for (k, (panel, layout)) in self.panels.iter().zip(layouts).enumerate() {
            let (area, below) = rest.split_vertically(layout.height);
            rest = below;
            let last = k + 1 == self.panels.len();
            let (y_min, y_max) = layout.y_range;
            let mut chart = ChartBuilder::on(&area)
                .margin(MARGIN)
                .margin_right(MARGIN_RIGHT)
                .x_label_area_size(if last { X_LABEL_AREA_LAST } else { X_LABEL_AREA })
                .y_label_area_size(Y_LABEL_AREA)
                .build_cartesian_2d(self.x_range.0..self.x_range.1, y_min..y_max)?;
            let x_decimals = tick_decimals(self.x_range);
            // Very small or large values are labelled in units of a power of ten.
            let y_exp = exponent(layout.y_range);
            let unit = 10f64.powi(y_exp);
            let y_decimals = tick_decimals((y_min / unit, y_max / unit));
            let y_desc = if y_exp == 0 {
                panel.y_label.to_string()
            } else {
                format!("{} (×10{})", panel.y_label, superscript(y_exp))
            };
            let x_tick = move |x: &f64| tick_label(*x, x_decimals);
            let y_tick = move |y: &f64| tick_label(*y / unit, y_decimals);
            let mut mesh = chart.configure_mesh();
            mesh.y_desc(y_desc)
                .x_labels(LABELS)
                .y_labels(LABELS)
                .x_label_formatter(&x_tick)
                .y_label_formatter(&y_tick)
                .label_style(("sans-serif", TICK_FONT))
                .axis_desc_style(("sans-serif", TICK_FONT + 1))
                .light_line_style(WHITE.mix(0.0));
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
                    .position(layout.legend.position())
                    .background_style(WHITE.mix(0.85))
                    .border_style(BLACK)
                    .label_font(("sans-serif", LEGEND_FONT))
                    .draw()?;
            }
        }
        root.present()?;
        Ok(())
    }
}

/// Pixel size of a panel's legend box as plotters draws it (30 pixels of line
/// sample, margins of 10, 5 from the frame), a few pixels generous; `None`
/// without labels.
fn legend_size(panel: &Panel<'_>) -> Result<Option<(f64, f64)>, Box<dyn Error>> {
    let font = ("sans-serif", LEGEND_FONT).into_font();
    let mut lines = 0u32;
    let mut width = 0u32;
    for s in panel.series.iter().filter(|s| !s.label.is_empty()) {
        lines += 1;
        width = width.max(font.box_size(s.label).map_err(|e| e.to_string())?.0);
    }
    if lines == 0 {
        return Ok(None);
    }
    let height = 1.25 * f64::from(LEGEND_FONT) * f64::from(lines) + 20.0 + 5.0 + 6.0;
    Ok(Some((f64::from(width) + 30.0 + 20.0 + 5.0 + 6.0, height)))
}

/// Decimals that show every tick of `range` exactly: one more than the tick
/// spacing needs, trailing zeros being trimmed by `tick_label`.
fn tick_decimals((lo, hi): (f64, f64)) -> usize {
    let step = (hi - lo).abs() / LABELS as f64;
    if !(step.is_finite() && step > 0.0) {
        return 1;
    }
    (1.0 - step.log10().floor()).clamp(0.0, 12.0) as usize
}

/// The power of ten to label an axis in: 0 unless the values are below 10⁻³
/// or from 10⁵ on.
fn exponent((lo, hi): (f64, f64)) -> i32 {
    let top = lo.abs().max(hi.abs());
    if !(top.is_finite() && top > 0.0) || (1e-3..1e5).contains(&top) {
        return 0;
    }
    top.log10().floor() as i32
}

/// `n` in superscript digits, with a superscript minus.
fn superscript(n: i32) -> String {
    const DIGITS: [char; 10] = ['⁰', '¹', '²', '³', '⁴', '⁵', '⁶', '⁷', '⁸', '⁹'];
    let digits = n
        .unsigned_abs()
        .to_string()
        .chars()
        .map(|c| c.to_digit(10).map_or('?', |d| DIGITS[d as usize]))
        .collect::<String>();
    if n < 0 { format!("⁻{digits}") } else { digits }
}

/// A tick label: `decimals` places, trailing zeros trimmed, never "-0".
pub fn tick_label(x: f64, decimals: usize) -> String {
    let mut text = format!("{x:.decimals$}");
    if text.contains('.') {
        text = text.trim_end_matches('0').trim_end_matches('.').to_string();
    }
    if text == "-0" {
        text = "0".to_string();
    }
    // A true minus sign, as in the axis descriptions.
    text.replace('-', "−")
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
