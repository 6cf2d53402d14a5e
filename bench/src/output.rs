//! Writes a [`Report`] to a directory: `report.json`, `report.md`,
//! `report.html`, and per problem a work–precision plot and, when the
//! energy is conserved, an energy plot (SVG and PNG). Everything is written to a temporary sibling directory
//! first and renamed into place at the end, so a failed run never leaves a
//! half-written report that looks complete.

use std::fmt::Write as _;
use std::fs;
use std::path::{Path, PathBuf};
use std::sync::Once;

use plotters::prelude::*;

use crate::methods::{Family, Setting};
use crate::report::*;

/// Writes the report to `out` (replacing an earlier report there).
pub fn write(report: &Report, out: &Path) -> Result<(), String> {
    let parent = match out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    fs::create_dir_all(&parent).map_err(|e| format!("cannot create the output directory {}: {e}", parent.display()))?;
    let name = out.file_name().map_or_else(|| "report".into(), |n| n.to_string_lossy().into_owned());
    let tmp = parent.join(format!(".{name}.partial-{}", std::process::id()));
    let _ = fs::remove_dir_all(&tmp);
    fs::create_dir(&tmp).map_err(|e| format!("cannot write to {}: {e}", parent.display()))?;
    let result = write_into(report, &tmp).and_then(|()| {
        let old = parent.join(format!(".{name}.old-{}", std::process::id()));
        if out.exists() {
            fs::rename(out, &old).map_err(|e| format!("cannot replace {}: {e}", out.display()))?;
        }
        fs::rename(&tmp, out).map_err(|e| format!("cannot move the report into {}: {e}", out.display()))?;
        let _ = fs::remove_dir_all(&old);
        Ok(())
    });
    if result.is_err() {
        let _ = fs::remove_dir_all(&tmp);
    }
    result
}

fn io(path: &Path) -> impl FnOnce(std::io::Error) -> String + '_ {
    move |e| format!("cannot write {}: {e}", path.display())
}

fn write_into(report: &Report, dir: &Path) -> Result<(), String> {
    let json = serde_json::to_string_pretty(report).map_err(|e| format!("cannot serialise the report: {e}"))?;
    let path = dir.join("report.json");
    fs::write(&path, json).map_err(io(&path))?;
    for p in &report.problems {
        work_precision_plot(p, &dir.join(format!("{}-work-precision", p.id)))?;
        // No long energy runs for problems whose energy is not conserved.
        if !p.energy.is_empty() {
            energy_plot(p, &dir.join(format!("{}-energy", p.id)))?;
        }
    }
    let blocks = document(report);
    let path = dir.join("report.md");
    fs::write(&path, markdown(&blocks)).map_err(io(&path))?;
    let path = dir.join("report.html");
    fs::write(&path, html(&blocks)).map_err(io(&path))?;
    Ok(())
}

// ------------------------------------------------------------------ plots

const COLORS: [RGBColor; 10] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];

fn register_font() {
    static FONT: Once = Once::new();
    FONT.call_once(|| {
        // The font the examples bundle (DejaVu Sans, licence beside it).
        plotters::style::register_font(
            "sans-serif",
            FontStyle::Normal,
            include_bytes!("../../examples/support/DejaVuSans.ttf"),
        )
        .unwrap_or_else(|_| panic!("the bundled font is a valid TrueType file"));
    });
}

/// Label, points, and whether to mark each point.
type Line = (String, Vec<(f64, f64)>, bool);

/// A log–log (or lin–log) line chart with a legend.
struct Chart<'a> {
    title: &'a str,
    x_label: &'a str,
    y_label: &'a str,
    log_x: bool,
    series: Vec<Line>,
}

fn range(values: impl Iterator<Item = f64>, log: bool) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|v| v.is_finite() && (!log || *v > 0.0))
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
    if !lo.is_finite() {
        return if log { (1e-16, 1.0) } else { (0.0, 1.0) };
    }
    if log {
        (lo / 2.0, hi * 2.0)
    } else if hi > lo {
        (lo, hi)
    } else {
        (lo - 1.0, hi + 1.0)
    }
}

fn draw<DB: DrawingBackend>(root: DrawingArea<DB, plotters::coord::Shift>, chart: &Chart<'_>) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    let err = |e: DrawingAreaErrorKind<DB::ErrorType>| format!("plot {}: {e}", chart.title);
    root.fill(&WHITE).map_err(err)?;
    let xs = range(chart.series.iter().flat_map(|s| s.1.iter().map(|p| p.0)), chart.log_x);
    let ys = range(chart.series.iter().flat_map(|s| s.1.iter().map(|p| p.1)), true);
    let mut builder = ChartBuilder::on(&root);
    builder.caption(chart.title, ("sans-serif", 20)).margin(12).x_label_area_size(40).y_label_area_size(70);
    macro_rules! body {
        ($c:expr) => {{
            let mut c = $c;
            c.configure_mesh()
                .x_desc(chart.x_label)
                .y_desc(chart.y_label)
                .y_label_formatter(&|v| format!("{v:.0e}"))
                .draw()
                .map_err(err)?;
            for (i, (label, points, markers)) in chart.series.iter().enumerate() {
                let color = COLORS[i % COLORS.len()];
                let dashed = i >= COLORS.len();
                let style =
                    ShapeStyle { color: color.to_rgba(), filled: false, stroke_width: if dashed { 1 } else { 2 } };
                let pts: Vec<(f64, f64)> = points
                    .iter()
                    .copied()
                    .filter(|p| p.0.is_finite() && p.1 > 0.0 && (!chart.log_x || p.0 > 0.0))
                    .collect();
                c.draw_series(LineSeries::new(pts.clone(), style))
                    .map_err(err)?
                    .label(label.as_str())
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], style));
                if *markers {
                    c.draw_series(pts.iter().map(|&p| Circle::new(p, 2, color.filled()))).map_err(err)?;
                }
            }
            c.configure_series_labels()
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .position(SeriesLabelPosition::UpperRight)
                .label_font(("sans-serif", 12))
                .draw()
                .map_err(err)?;
        }};
    }
    if chart.log_x {
        body!(builder.build_cartesian_2d((xs.0..xs.1).log_scale(), (ys.0..ys.1).log_scale()).map_err(err)?);
    } else {
        body!(builder.build_cartesian_2d(xs.0..xs.1, (ys.0..ys.1).log_scale()).map_err(err)?);
    }
    root.present().map_err(err)?;
    Ok(())
}

fn save(chart: &Chart<'_>, base: &Path) -> Result<(), String> {
    register_font();
    let size = (900, 600);
    // Appended, not `with_extension`: ids such as `kepler-0.5` contain a dot.
    let svg = PathBuf::from(format!("{}.svg", base.display()));
    draw(SVGBackend::new(&svg, size).into_drawing_area(), chart)?;
    let png = PathBuf::from(format!("{}.png", base.display()));
    draw(BitMapBackend::new(&png, size).into_drawing_area(), chart)?;
    Ok(())
}

fn work_precision_plot(p: &ProblemReport, base: &Path) -> Result<(), String> {
    let series = p
        .sweeps
        .iter()
        .map(|s| {
            let pts = s.points.iter().filter_map(|pt| Some((pt.seconds, pt.error?))).collect();
            (s.method.clone(), pts, true)
        })
        .collect();
    let title = format!("{}: final error against time", p.title);
    save(
        &Chart {
            title: &title, x_label: "time of one run (s)", y_label: "max |q(T) − q_ref(T)|", log_x: true, series
        },
        base,
    )
}

fn energy_plot(p: &ProblemReport, base: &Path) -> Result<(), String> {
    let series = p
        .energy
        .iter()
        .map(|e| (e.method.clone(), e.samples.iter().map(|&(t, d)| (t, d.abs().max(1e-17))).collect(), false))
        .collect();
    let title = format!("{}: energy error over a long run", p.title);
    save(&Chart { title: &title, x_label: "t", y_label: "|E − E0| / |E0|", log_x: false, series }, base)
}

// --------------------------------------------------------------- document

/// A piece of the Markdown/HTML report.
enum Block {
    Heading(u8, String),
    Para(String),
    Image(String, String),
    Table(Vec<String>, Vec<Vec<String>>),
}

fn e(x: f64) -> String {
    format!("{x:.1e}")
}

fn setting(s: &Setting) -> String {
    match s {
        Setting::Steps(n) => format!("{n} steps"),
        Setting::Tolerance(t) => format!("tol {t:.1e}"),
        Setting::Sigma(s) => format!("σ = {s:.4}"),
    }
}

fn ms(s: f64) -> String {
    if s < 0.1 { format!("{:.3} ms", s * 1e3) } else { format!("{:.1} ms", s * 1e3) }
}

fn family(f: Family) -> &'static str {
    match f {
        Family::Project => "project",
        Family::Peer => "peer crate",
        Family::HandWritten => "hand-written",
    }
}

fn best(b: &Option<Best>) -> String {
    b.as_ref().map_or_else(|| "—".into(), |b| format!("{} ({}, {})", b.method, ms(b.seconds), setting(&b.setting)))
}

/// The headline table: per problem and target, the fastest project method and the fastest other method.
pub fn headline(report: &Report, targets: &[f64]) -> String {
    let mut s = String::from(
        "| problem | target | best project method | best peer crate | best hand-written |\n| --- | --- | --- | --- | --- |\n",
    );
    for p in &report.problems {
        for r in p.recommendations.iter().filter(|r| targets.contains(&r.target)) {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} |",
                p.id,
                e(r.target),
                best(&r.best_project),
                best(&r.best_peer),
                best(&r.best_hand_written)
            );
        }
    }
    s
}

fn ratio(x: Option<f64>) -> String {
    x.map_or_else(|| "—".into(), |x| format!("{x:.2}×"))
}

/// Project compositions against their hand-written twins (the same map on a
/// separable constant-mass problem), at equal error: every problem and target.
pub fn twins_table(report: &Report) -> String {
    let mut s = String::from(
        "| problem | target | generated | hand-written | generated / hand-written time | per step |\n| --- | --- | --- | --- | --- | --- |\n",
    );
    let run = |seconds: Option<f64>, steps: Option<u64>| match (seconds, steps) {
        (Some(t), Some(n)) => format!("{} ({n} steps)", ms(t)),
        _ => "not reached".into(),
    };
    for p in &report.problems {
        for t in &p.twins {
            let _ = writeln!(
                s,
                "| {} | {} | {} {} | {} {} | {} | {} |",
                p.id,
                e(t.target),
                t.generated,
                run(t.generated_seconds, t.generated_steps),
                t.hand_written,
                run(t.hand_written_seconds, t.hand_written_steps),
                ratio(t.ratio),
                ratio(t.per_step_ratio)
            );
        }
    }
    s
}

/// The methods of the time-transformed comparison: the time-transformed
/// ones, the best fixed-step Galerkin rules and the DOP853 peers.
const TIME_TRANSFORMED_ROWS: [&str; 7] = [
    "tt-galerkin-4",
    "tt-galerkin-6",
    "tt-auto-galerkin-6",
    "galerkin-6",
    "galerkin-8",
    "ode_solvers-dop853",
    "diffeq-dop853",
];

/// Time-transformed against fixed steps and DOP853 on the eccentric Kepler
/// orbits: every target, the calibrated setting and its cost.
pub fn time_transformed_table(report: &Report) -> String {
    let mut s = String::from(
        "| problem | target | method | setting | worst error of 3 | time | Newton it./step |\n| --- | --- | --- | --- | --- | --- | --- |\n",
    );
    for p in report.problems.iter().filter(|p| p.id.starts_with("kepler-")) {
        for &target in &report.targets {
            for name in TIME_TRANSFORMED_ROWS {
                let Some(c) = p.calibrated.iter().find(|c| c.method == name && c.target == target) else { continue };
                let _ = writeln!(
                    s,
                    "| {} | {} | {} | {} | {} | {} | {} |",
                    p.id,
                    e(target),
                    name,
                    c.setting.as_ref().map_or("not reached".into(), setting),
                    c.worst_of_three.map_or("—".into(), e),
                    c.seconds.map_or("—".into(), ms),
                    c.newton_per_step.map_or("—".into(), |x| format!("{x:.2}"))
                );
            }
        }
    }
    s
}

/// The tolerance-driven solve against the fastest other project method at
/// one problem and target, both calibrated to it.
#[derive(Clone, Debug, PartialEq)]
pub struct AutoRatio {
    /// The problem.
    pub problem: String,
    /// The target error.
    pub target: f64,
    /// Seconds of the calibrated auto run; `None` where it missed the target.
    pub auto: Option<f64>,
    /// The fastest other project method and its seconds.
    pub fastest: Option<(String, f64)>,
    /// Steps of the calibrated auto run (pilot included) and of the fastest method's.
    pub steps: (Option<u64>, Option<u64>),
    /// What auto chose at its calibrated setting.
    pub choice: Option<crate::calibrate::AutoChoice>,
}

impl AutoRatio {
    /// Auto's time over the fastest method's.
    pub fn ratio(&self) -> Option<f64> {
        Some(self.auto? / self.fastest.as_ref()?.1)
    }
}

/// [`AutoRatio`] for every problem and target of `report` that ran `auto`.
pub fn auto_ratios(report: &Report) -> Vec<AutoRatio> {
    let mut out = Vec::new();
    for p in &report.problems {
        for &target in &report.targets {
            let Some(auto) = p.calibrated.iter().find(|c| c.method == "auto" && c.target == target) else { continue };
            let fastest = p
                .calibrated
                .iter()
                .filter(|c| c.target == target && c.family == Family::Project && c.method != "auto")
                .filter(|c| c.setting.is_some())
                .filter_map(|c| Some((c.method.clone(), c.seconds?)))
                .min_by(|a, b| a.1.total_cmp(&b.1));
            let point = |method: &str, setting: Option<&Setting>| {
                let sweep = p.sweeps.iter().find(|w| w.method == method)?;
                sweep.points.iter().find(|pt| Some(&pt.setting) == setting)
            };
            let auto_point = point("auto", auto.setting.as_ref());
            let fastest_steps = fastest.as_ref().and_then(|(m, _)| {
                let c = p.calibrated.iter().find(|c| &c.method == m && c.target == target)?;
                point(m, c.setting.as_ref()).map(|pt| pt.steps)
            });
            out.push(AutoRatio {
                problem: p.id.clone(),
                target,
                auto: auto.setting.as_ref().and(auto.seconds),
                fastest,
                steps: (auto_point.map(|pt| pt.steps), fastest_steps),
                choice: auto_point.and_then(|pt| pt.auto.clone()),
            });
        }
    }
    out
}

/// The tolerance-driven solve (pilot included) against the fastest project
/// method at each target, with the ratio of their times; then the cases
/// above 1.5× with the reason the report's numbers show.
pub fn auto_table(report: &Report) -> String {
    let mut s = String::from(
        "| problem | target | auto | auto ran | steps (pilot) | fastest project method | its steps | auto / fastest |\n\
         | --- | --- | --- | --- | --- | --- | --- | --- |\n",
    );
    let ratios = auto_ratios(report);
    let count = |n: Option<u64>| n.map_or("—".into(), |n| n.to_string());
    for r in &ratios {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {} | {} | {} | {} |",
            r.problem,
            e(r.target),
            r.auto.map_or("not reached".into(), ms),
            r.choice.as_ref().map_or("—".into(), |c| c.method.clone()),
            match (r.steps.0, &r.choice) {
                (Some(n), Some(c)) => format!("{n} ({})", c.pilot_steps),
                (n, _) => count(n),
            },
            r.fastest.as_ref().map_or("—".into(), |(n, t)| format!("{n} ({})", ms(*t))),
            count(r.steps.1),
            ratio(r.ratio())
        );
    }
    let above: Vec<String> = ratios
        .iter()
        .filter(|r| r.ratio().is_some_and(|x| x > 1.5))
        .map(|r| format!("{} at {}: {:.1}×, {}", r.problem, e(r.target), r.ratio().unwrap_or(f64::NAN), auto_reason(r)))
        .collect();
    let measured = ratios.iter().filter(|r| r.ratio().is_some()).count();
    let within2 = ratios.iter().filter(|r| r.ratio().is_some_and(|x| x <= 2.0)).count();
    let _ = writeln!(s, "\nAt most 2× the fastest in {within2} of {measured} cases.");
    if above.is_empty() {
        s.push_str("\nNo case above 1.5×.\n");
    } else {
        let _ = writeln!(s, "\nAbove 1.5× ({} of {}):\n", above.len(), ratios.len());
        for a in above {
            let _ = writeln!(s, "- {a}");
        }
    }
    s
}

/// Why auto takes longer than the fastest method at `r`, from the steps
/// the report recorded: another method, the pilot's share, a final step
/// finer than the calibrated one, or the fixed cost of the choice.
fn auto_reason(r: &AutoRatio) -> String {
    let (Some(choice), (Some(steps), Some(fastest_steps)), Some((fastest, _))) = (&r.choice, r.steps, &r.fastest)
    else {
        return "no steps recorded".into();
    };
    let final_steps = steps.saturating_sub(choice.pilot_steps);
    let same = match choice.method.as_str() {
        m if m.starts_with("Kahan–Li 8 composition") => fastest == "composition-kahan-li8",
        m if m.starts_with("explicit time-transformed") => fastest.starts_with("tt-split-logh"),
        m if m.starts_with("Galerkin s = ") => fastest == &format!("galerkin-{}", &m["Galerkin s = ".len()..]),
        _ => false,
    };
    let mut why = Vec::new();
    if !same {
        why.push(format!("ran {} where {fastest} is faster", choice.method));
    }
    if choice.pilot_steps as f64 >= 0.5 * final_steps as f64 {
        why.push(format!("pilot {} steps against {final_steps} of the final run", choice.pilot_steps));
    }
    if same && final_steps as f64 > 1.3 * fastest_steps as f64 {
        why.push(format!(
            "final run {:.1}× the calibrated steps (the step the estimate allows is finer)",
            final_steps as f64 / fastest_steps as f64
        ));
    }
    if why.is_empty() {
        why.push(format!("the fixed cost of the choice and pilot ({} wall clock)", ms(choice.pilot_seconds)));
    }
    why.join("; ")
}

/// Iterations and evaluations per step of every method's calibrated run on
/// problem `p`, one row per method, two columns per target (`—` where a
/// method has no such count or missed the target).
pub fn per_step_table(targets: &[f64], p: &ProblemReport) -> String {
    let mut s = String::from("| method |");
    for &t in targets {
        let _ = write!(s, " iterations/step ≤ {} | evaluations/step ≤ {} |", e(t), e(t));
    }
    s.push_str("\n| --- |");
    for _ in targets {
        s.push_str(" --- | --- |");
    }
    s.push('\n');
    for sweep in &p.sweeps {
        let _ = write!(s, "| {} |", sweep.method);
        for &t in targets {
            let c = p.calibrated.iter().find(|c| c.method == sweep.method && c.target == t);
            let iterations = c.and_then(|c| c.newton_per_step).map_or("—".into(), |n| format!("{n:.2}"));
            let steps = c.and_then(|c| {
                sweep.points.iter().find(|pt| Some(&pt.setting) == c.setting.as_ref()).map(|pt| pt.steps)
            });
            let evaluations = match (c.and_then(|c| c.evaluations), steps) {
                (Some(k), Some(n)) if n > 0 => format!("{:.1}", k as f64 / n as f64),
                _ => "—".into(),
            };
            let _ = write!(s, " {iterations} | {evaluations} |");
        }
        s.push('\n');
    }
    s
}

/// Every method's calibrated run on problem `p`, per target, fastest first;
/// the methods that did not reach a target in one line after.
pub fn calibrated_table(report: &Report, p: &ProblemReport) -> String {
    let mut s = String::from(
        "| target | method | setting | steps | worst error of 3 | time | Newton or fixed-point it./step | evaluations/step |\n| --- | --- | --- | --- | --- | --- | --- | --- |\n",
    );
    let steps_of = |c: &Calibrated| {
        let sweep = p.sweeps.iter().find(|w| w.method == c.method)?;
        sweep.points.iter().find(|pt| Some(&pt.setting) == c.setting.as_ref()).map(|pt| pt.steps)
    };
    for &target in &report.targets {
        let mut met: Vec<&Calibrated> =
            p.calibrated.iter().filter(|c| c.target == target && c.setting.is_some() && c.seconds.is_some()).collect();
        met.sort_by(|a, b| a.seconds.unwrap_or(f64::INFINITY).total_cmp(&b.seconds.unwrap_or(f64::INFINITY)));
        for c in met {
            let steps = steps_of(c);
            // Right-hand sides (peers, compositions) or derivatives of L at quadrature points (Galerkin).
            let per_step = match (c.evaluations, steps) {
                (Some(k), Some(n)) if n > 0 => format!("{:.1}", k as f64 / n as f64),
                _ => "—".into(),
            };
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {} | {} | {} |",
                e(target),
                c.method,
                c.setting.as_ref().map_or("—".into(), setting),
                steps.map_or("—".into(), |n| n.to_string()),
                c.worst_of_three.map_or("—".into(), e),
                c.seconds.map_or("—".into(), ms),
                c.newton_per_step.map_or("—".into(), |x| format!("{x:.2}")),
                per_step
            );
        }
        let missed: Vec<&str> = p
            .calibrated
            .iter()
            .filter(|c| c.target == target && (c.setting.is_none() || c.seconds.is_none()))
            .map(|c| c.method.as_str())
            .collect();
        if !missed.is_empty() {
            // Eight cells, as the header: target, the methods, six empty.
            let _ = writeln!(s, "| {} | not reached: {} | | | | | | |", e(target), missed.join(", "));
        }
    }
    s
}

/// The constraint and energy drift of each calibrated run of a problem with
/// constraints, per target in the order of `targets`, methods in report order.
pub fn drift_table(targets: &[f64], p: &ProblemReport) -> String {
    let mut s = String::from(
        "| target | method | setting | max \\|E − E0\\|/\\|E0\\| | max rod length error / length | max \\|d(rod length)/dt\\| (m/s) | outcome |\n\
         | --- | --- | --- | --- | --- | --- | --- |\n",
    );
    for &target in targets {
        for c in p.constraints.iter().filter(|c| c.target == target) {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {} | {} |",
                e(target),
                c.method,
                setting(&c.setting),
                c.energy_max_abs.map_or("—".into(), e),
                c.position_max.map_or("—".into(), e),
                c.velocity_max.map_or("—".into(), e),
                c.failure.as_deref().map_or("ok".into(), short)
            );
        }
    }
    s
}

/// The step-cost table: ns per step at `h` = 0.01, per system, with the
/// generated / hand-written ratio of the midpoint rule.
pub fn step_cost_table(report: &Report) -> String {
    let methods = [
        "generated midpoint",
        "generated energy-preserving midpoint",
        "generated trapezoid",
        "hand-written midpoint",
        "hand-written verlet",
    ];
    // (label, numerator, denominator)
    let ratios = [
        ("generated / hand midpoint", "generated midpoint", "hand-written midpoint"),
        ("generated trapezoid / hand verlet", "generated trapezoid", "hand-written verlet"),
        ("energy-preserving / fixed midpoint", "generated energy-preserving midpoint", "generated midpoint"),
    ];
    let mut s = String::from("| ns/step |");
    for m in methods {
        let _ = write!(s, " {m} |");
    }
    for (label, _, _) in ratios {
        let _ = write!(s, " {label} |");
    }
    s.push_str("\n|");
    s.push_str(&" --- |".repeat(methods.len() + ratios.len() + 1));
    s.push('\n');
    let mut systems: Vec<&str> = Vec::new();
    for c in report.step_costs.iter().filter(|c| methods.contains(&c.method.as_str())) {
        if !systems.contains(&c.system.as_str()) {
            systems.push(&c.system);
        }
    }
    for system in systems {
        let find = |m: &str| report.step_costs.iter().find(|c| c.system == system && c.method == m);
        let _ = write!(s, "| {system} |");
        for m in methods {
            let cell = find(m).map_or_else(
                || "—".into(),
                |c| match c.newton_per_step {
                    Some(n) if n > 0.0 => format!("{:.1} ({n:.2} Newton it.)", c.ns_per_step),
                    _ => format!("{:.1}", c.ns_per_step),
                },
            );
            let _ = write!(s, " {cell} |");
        }
        for (_, a, b) in ratios {
            let r = find(a).zip(find(b)).map(|(a, b)| a.ns_per_step / b.ns_per_step);
            let _ = write!(s, " {} |", ratio(r));
        }
        s.push('\n');
    }
    s
}

/// The Galerkin step-cost table: ns and Newton iterations per step against `s`.
pub fn galerkin_cost_table(report: &Report) -> String {
    let rows: Vec<&StepCost> = report.step_costs.iter().filter(|c| c.method.starts_with("galerkin-")).collect();
    let mut s = String::from("| s |");
    for c in &rows {
        let _ = write!(s, " {} |", c.method.trim_start_matches("galerkin-"));
    }
    s.push_str("\n|");
    s.push_str(&" --- |".repeat(rows.len() + 1));
    s.push_str("\n| ns/step |");
    for c in &rows {
        let _ = write!(s, " {:.0} |", c.ns_per_step);
    }
    s.push_str("\n| Newton iterations/step |");
    for c in &rows {
        let _ = write!(s, " {} |", c.newton_per_step.map_or("—".into(), |n| format!("{n:.2}")));
    }
    s.push('\n');
    s
}

/// ` (command)` when the report records the command that ran it, for the
/// text that says where a table came from.
pub fn stated_command(report: &Report) -> String {
    if report.command.is_empty() { String::new() } else { format!(" (`{}`)", report.command) }
}

/// How busy the machine was, for the text under a table.
pub fn load(report: &Report) -> String {
    match (report.machine.load_start, report.machine.load_end) {
        (Some(a), Some(b)) => format!("load average {a:.1} at the start, {b:.1} at the end"),
        _ => "load average not recorded".into(),
    }
}

fn document(r: &Report) -> Vec<Block> {
    use Block::*;
    let mut d = vec![
        Heading(1, "lagrangian: work–precision and stress report".into()),
        Para(format!(
            "Suite `{}`{}, lagrangian-bench {}, {} cores ({}/{}). Error = `max_i |q_i(T) − q_i^ref(T)|` at the horizon T. \
             Each method is calibrated per target with the rule: the coarsest step count (largest tolerance) for which \
             it and the next two finer settings meet the target. Times are CPU seconds of the thread that ran the integrator \
             (minimum of the repeats for the calibrated settings), on a machine shared with other work. \
             Every number is in `report.json` (schema in `bench/src/report.rs`).",
            r.suite,
            stated_command(r),
            r.crate_version,
            r.machine.cores,
            r.machine.os,
            r.machine.arch
        )),
        Heading(2, "Headline".into()),
    ];
    let (header, rows) = table_of(&headline(r, &r.targets));
    d.push(Table(header, rows));
    d.push(Heading(2, "Generated against hand-written compositions".into()));
    d.push(Para(
        "The project's `Composition::{YOSHIDA6, KAHAN_LI8}` and its trapezoid rule against the hand-written \
         Yoshida 6, Kahan–Li 8 and Störmer–Verlet of this crate, which compute the same maps on separable \
         constant-mass problems (the runtime's explicit path); each calibrated to the same target, so the time ratio \
         is the cost ratio at equal error; both timed again in alternation (minimum of at least 5 runs each), so \
         load hits both alike. Runs under ~0.05 ms are timer noise."
            .into(),
    ));
    let (header, rows) = table_of(&twins_table(r));
    if rows.is_empty() {
        d.push(Para("No problem with both a project composition and its hand-written twin in this run.".into()));
    } else {
        d.push(Table(header, rows));
    }
    d.push(Heading(2, "Cost of one step".into()));
    let (header, rows) = table_of(&step_cost_table(r));
    if rows.is_empty() {
        d.push(Para("Not measured in this run.".into()));
    } else {
        d.push(Para(format!(
            "ns per step at h = 0.01, best of the timed runs; {}; the hand-written steps have analytic \
             derivatives (`bench/src/handwritten.rs`).",
            load(r)
        )));
        d.push(Table(header, rows));
        d.push(Para("Galerkin s = 1…8 on the pendulum from 1 rad at h = 0.1:".into()));
        let (header, rows) = table_of(&galerkin_cost_table(r));
        d.push(Table(header, rows));
    }
    for p in &r.problems {
        d.push(Heading(2, p.title.clone()));
        d.push(Para(format!(
            "T = {}, {} degrees of freedom. Reference: {} ({}; difference {:.1e}, accepted ≤ {:.1e}).",
            p.horizon, p.dim, p.reference.kind, p.reference.check, p.reference.agreement, p.reference.accepted
        )));
        d.push(Image(format!("{}-work-precision.svg", p.id), format!("{} work–precision", p.id)));
        let mut header = vec!["method".to_string(), "who".into(), "order".into()];
        header.extend(r.targets.iter().map(|t| format!("≤ {}", e(*t))));
        let rows = p
            .sweeps
            .iter()
            .map(|s| {
                let mut row = vec![s.method.clone(), family(s.family).into(), s.order.to_string()];
                row.extend(r.targets.iter().map(|&t| {
                    p.calibrated.iter().find(|c| c.method == s.method && c.target == t).map_or("—".into(), |c| match (
                        c.seconds, &c.setting, c.error,
                    ) {
                        (Some(sec), Some(set), Some(err)) => format!("{} ({}, err {})", ms(sec), setting(set), e(err)),
                        _ => "not reached".into(),
                    })
                }));
                row
            })
            .collect();
        d.push(Para("Time to reach each target (setting, error of that run); \"not reached\": the sweep stopped (failure or time budget) first.".into()));
        d.push(Table(header, rows));
        let rows = p
            .recommendations
            .iter()
            .map(|rec| vec![e(rec.target), best(&rec.best), best(&rec.best_project), best(&rec.best_peer)])
            .collect();
        d.push(Para("Recommended method per accuracy:".into()));
        d.push(Table(
            vec!["target".into(), "fastest".into(), "fastest project method".into(), "fastest peer crate".into()],
            rows,
        ));
        d.push(Para(
            "Work per step of each calibrated run: Newton or fixed-point iterations (project methods), and \
             evaluations — derivatives of L at one quadrature point (gradients, Hessians in v and whole \
             Hessians alike) for Galerkin rules, right-hand sides for the peers, forces for the compositions \
             (— where the method does not count them)."
                .into(),
        ));
        let (header, rows) = table_of(&per_step_table(&r.targets, p));
        d.push(Table(header, rows));
        if !p.constraints.is_empty() {
            d.push(Para(format!(
                "Constraints and energy along each calibrated run (the run again at its setting, {} samples evenly \
                 spread over T; adaptive methods at the first accepted step at or after each): the rods' length errors \
                 relative to their lengths, the rates of change of their lengths, the energy error.",
                p.constraints[0].samples
            )));
            let (header, rows) = table_of(&drift_table(&r.targets, p));
            d.push(Table(header, rows));
        }
        if p.energy.is_empty() {
            let why = if r.calibration_only {
                "No long energy runs: a calibration-only report."
            } else {
                "Energy is not conserved by this problem (time-dependent or forced): no long energy runs."
            };
            d.push(Para(why.into()));
            continue;
        }
        d.push(Image(format!("{}-energy.svg", p.id), format!("{} energy error", p.id)));
        // The angular momentum column only for problems that conserve it.
        let momentum = p.energy.iter().any(|s| s.momentum_max_abs.is_some());
        let rows = p
            .energy
            .iter()
            .map(|s| {
                let mut row = vec![
                    s.method.clone(),
                    setting(&s.setting),
                    format!("{}", s.t_end),
                    s.max_abs.map_or("—".into(), e),
                ];
                if momentum {
                    row.push(s.momentum_max_abs.map_or("—".into(), e));
                }
                row.push(s.failure.clone().unwrap_or_else(|| "ok".into()));
                row
            })
            .collect();
        d.push(Para(
            "Long runs with the settings calibrated at the loosest target (same h or tolerance, longer T):".into(),
        ));
        let mut header = vec!["method".into(), "setting".into(), "T".into(), "max |E − E0|/|E0|".into()];
        if momentum {
            header.push("max |L − L0|/|L0| (angular momentum)".into());
        }
        header.push("outcome".into());
        d.push(Table(header, rows));
    }
    d.push(Heading(2, "Stress".into()));
    d.push(Heading(3, "Largest step each fixed-step method survives".into()));
    let mut criteria: Vec<&str> = Vec::new();
    for l in &r.stress.largest_step {
        if !criteria.contains(&l.criterion.as_str()) {
            criteria.push(&l.criterion);
        }
    }
    for c in criteria {
        d.push(Para(format!("Criterion: {c}.")));
    }
    let rows = r
        .stress
        .largest_step
        .iter()
        .map(|l| {
            vec![
                l.problem.clone(),
                l.method.clone(),
                l.h.map_or("none".into(), |h| format!("{h:.4}")),
                l.h_over_period.map_or("—".into(), |x| format!("{x:.3}")),
            ]
        })
        .collect();
    d.push(Table(vec!["problem".into(), "method".into(), "largest h".into(), "h / period".into()], rows));
    d.push(Heading(3, "Hard orbits: Kepler e = 0.9 and 0.99".into()));
    let rows = r
        .stress
        .hard_orbits
        .iter()
        .map(|h| {
            vec![
                h.problem.clone(),
                h.method.clone(),
                setting(&h.setting),
                h.error.map_or("—".into(), e),
                h.energy_error.map_or("—".into(), e),
                short(&h.outcome),
            ]
        })
        .collect();
    d.push(Table(
        vec![
            "problem".into(),
            "method".into(),
            "setting".into(),
            "error".into(),
            "max energy error".into(),
            "outcome".into(),
        ],
        rows,
    ));
    d.push(Heading(3, "Many steps".into()));
    d.push(Para(
        "Each fixed-step method takes its step calibrated at the loosest target many times over (DOP853 keeps its \
         tolerance and runs over the trapezoid rule's span); the invariants are sampled 1000 times."
            .into(),
    ));
    let rows = r
        .stress
        .long_runs
        .iter()
        .map(|l| {
            vec![
                l.problem.clone(),
                l.method.clone(),
                setting(&l.setting),
                l.steps.to_string(),
                format!("{:.0}", l.t_end),
                format!("{:.2} s", l.seconds),
                l.energy_max_abs.map_or("—".into(), e),
                l.momentum_max_abs.map_or("—".into(), e),
                short(&l.outcome),
            ]
        })
        .collect();
    d.push(Table(
        vec![
            "problem".into(),
            "method".into(),
            "setting".into(),
            "steps".into(),
            "T".into(),
            "time".into(),
            "max |E − E0|/|E0|".into(),
            "max |L − L0|/|L0|".into(),
            "outcome".into(),
        ],
        rows,
    ));
    d.push(Heading(3, "Bad input".into()));
    let rows = r.stress.bad_input.iter().map(|b| vec![b.class.clone(), b.method.clone(), short(&b.outcome)]).collect();
    d.push(Table(vec!["input".into(), "method".into(), "what it returned".into()], rows));
    d
}

fn short(s: &str) -> String {
    let s = s.replace('\n', " ");
    if s.chars().count() > 160 { format!("{}…", s.chars().take(160).collect::<String>()) } else { s }
}

/// Splits a Markdown table (as [`headline`] writes it) into header and rows.
fn table_of(md: &str) -> (Vec<String>, Vec<Vec<String>>) {
    let cells =
        |l: &str| l.trim().trim_matches('|').split(" | ").map(|c| c.trim().replace("\\|", "|")).collect::<Vec<_>>();
    let mut lines = md.lines();
    let header = lines.next().map(cells).unwrap_or_default();
    (header, lines.skip(1).map(cells).collect())
}

fn markdown(blocks: &[Block]) -> String {
    let mut s = String::new();
    for b in blocks {
        match b {
            Block::Heading(l, t) => {
                let _ = writeln!(s, "{} {t}\n", "#".repeat(*l as usize));
            }
            Block::Para(t) => {
                let _ = writeln!(s, "{t}\n");
            }
            Block::Image(src, alt) => {
                let _ = writeln!(s, "![{alt}]({src})\n");
            }
            Block::Table(h, rows) => {
                // A `|` inside a cell (`|E − E0|`) would split it: escape it.
                let row =
                    |cells: &[String]| cells.iter().map(|c| c.replace('|', "\\|")).collect::<Vec<_>>().join(" | ");
                let _ = writeln!(s, "| {} |", row(h));
                let _ = writeln!(s, "|{}", " --- |".repeat(h.len()));
                for r in rows {
                    let _ = writeln!(s, "| {} |", row(r));
                }
                s.push('\n');
            }
        }
    }
    s
}

fn escape(t: &str) -> String {
    t.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace("\\|", "|")
}

/// Inline code spans of the Markdown text as `<code>`.
fn inline(t: &str) -> String {
    escape(t)
        .split('`')
        .enumerate()
        .map(|(i, part)| if i % 2 == 1 { format!("<code>{part}</code>") } else { part.to_string() })
        .collect()
}

fn html(blocks: &[Block]) -> String {
    let mut s = String::from(
        "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>lagrangian report</title>\n<style>body{font-family:sans-serif;max-width:1100px;margin:auto}table{border-collapse:collapse;font-size:90%}td,th{border:1px solid #ccc;padding:2px 6px}img{max-width:100%}</style></head><body>\n",
    );
    for b in blocks {
        match b {
            Block::Heading(l, t) => {
                let _ = writeln!(s, "<h{l}>{}</h{l}>", inline(t));
            }
            Block::Para(t) => {
                let _ = writeln!(s, "<p>{}</p>", inline(t));
            }
            Block::Image(src, alt) => {
                let _ = writeln!(s, "<p><img src=\"{}\" alt=\"{}\"></p>", escape(src), escape(alt));
            }
            Block::Table(h, rows) => {
                s.push_str("<table><tr>");
                for c in h {
                    let _ = write!(s, "<th>{}</th>", inline(c));
                }
                s.push_str("</tr>\n");
                for r in rows {
                    s.push_str("<tr>");
                    for c in r {
                        let _ = write!(s, "<td>{}</td>", inline(c));
                    }
                    s.push_str("</tr>\n");
                }
                s.push_str("</table>\n");
            }
        }
    }
    s.push_str("</body></html>\n");
    s
}
