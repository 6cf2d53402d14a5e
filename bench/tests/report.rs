//! The report end to end: the binary's tiny suite writes every file, the JSON
//! parses into the schema, the calibrated numbers equal a direct run; bad
//! command lines and output directories fail cleanly.

use std::path::{Path, PathBuf};
use std::process::Command;

use lagrangian_bench::calibrate::{self, Limits};
use lagrangian_bench::methods::{Method, Setting};
use lagrangian_bench::problem;
use lagrangian_bench::report::{Report, SCHEMA_VERSION};

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_lagrangian-bench"))
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("lagrangian-bench-test-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn read(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

#[test]
fn tiny_report_writes_every_file() {
    let dir = scratch("tiny");
    let out = dir.join("report");
    let status = bin()
        .args(["--tiny", "--no-progress", "--problem", "pendulum,kepler-0.5", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(status.status.success(), "{}", String::from_utf8_lossy(&status.stderr));
    let report: Report = serde_json::from_slice(&read(&out.join("report.json"))).expect("the JSON matches the schema");
    assert_eq!(report.schema_version, SCHEMA_VERSION);
    assert_eq!(report.suite, "tiny");
    assert!(report.command.starts_with("cargo run --release -p lagrangian-bench -- --tiny --no-progress"));
    assert_eq!(report.problems.iter().map(|p| p.id.as_str()).collect::<Vec<_>>(), ["pendulum", "kepler-0.5"]);
    for p in &report.problems {
        // Every method but the time-transformed ones, which need a step density (Kepler's r^{3/2}),
        // and the peers of problems with constraints.
        let expected = Method::all()
            .iter()
            .filter(|m| (!m.needs_time_transform() || p.id.starts_with("kepler-")) && !m.needs_constraints())
            .count();
        assert_eq!(p.sweeps.len(), expected, "every applicable method on {}", p.id);
        assert!(p.recommendations.iter().all(|r| r.best.is_some()), "{}: some method meets each tiny target", p.id);
        assert!(!p.energy.is_empty());
        for kind in ["work-precision", "energy"] {
            let png = read(&out.join(format!("{}-{kind}.png", p.id)));
            assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n", "{} {kind}", p.id);
            let svg = String::from_utf8(read(&out.join(format!("{}-{kind}.svg", p.id)))).unwrap();
            assert!(svg.starts_with("<svg") && svg.trim_end().ends_with("</svg>"), "{} {kind}", p.id);
        }
    }
    assert!(!report.stress.largest_step.is_empty() && !report.stress.hard_orbits.is_empty());
    // Angular momentum on Kepler: the variational methods conserve it to round-off (Noether;
    // a rotation-invariant discrete Lagrangian), DOP853 does not; the pendulum has none.
    let kepler = report.problems.iter().find(|p| p.id == "kepler-0.5").unwrap();
    let momentum = |m: &str| kepler.energy.iter().find(|s| s.method == m).and_then(|s| s.momentum_max_abs);
    for m in ["midpoint", "verlet"] {
        let l = momentum(m).unwrap_or_else(|| panic!("{m}: no angular momentum"));
        assert!(l <= 1e-13, "{m}: {l}");
    }
    let dop = momentum("ode_solvers-dop853").unwrap();
    assert!(dop > 1e3 * momentum("midpoint").unwrap().max(1e-16), "dop853: {dop}");
    assert!(report.problems[0].energy.iter().all(|s| s.momentum_max_abs.is_none() && s.momentum_samples.is_empty()));
    // The many-step runs: every method on both problems, each to its full step count.
    for p in ["pendulum", "kepler-0.5"] {
        let runs: Vec<_> = report.stress.long_runs.iter().filter(|l| l.problem == p).collect();
        assert_eq!(runs.len(), 6, "{p}: {runs:?}");
        for l in runs.iter().filter(|l| l.outcome == "ok" && matches!(l.setting, Setting::Steps(_))) {
            assert_eq!(l.steps, 1000, "{p} {}", l.method);
        }
    }
    // Project compositions against their hand-written twins, on both (separable) problems.
    for p in &report.problems {
        for (g, h) in
            [("trapezoid", "verlet"), ("composition-yoshida6", "yoshida6"), ("composition-kahan-li8", "kahan-li8")]
        {
            let t = p.twins.iter().find(|t| t.generated == g && t.target == report.targets[0]);
            let t = t.unwrap_or_else(|| panic!("{}: no {g} against {h}", p.id));
            assert_eq!(t.hand_written, h);
            if let (Some(a), Some(b), Some(r)) = (t.generated_seconds, t.hand_written_seconds, t.ratio) {
                // serde_json's default float parser may be off by an ulp.
                assert!((r - a / b).abs() <= 1e-12 * r, "{}: {g}: {r} against {a} / {b}", p.id);
            }
        }
    }
    // Step costs: every generated and hand-written step of both systems, and Galerkin s = 1…8.
    let costs: Vec<(&str, &str)> = report.step_costs.iter().map(|c| (c.system.as_str(), c.method.as_str())).collect();
    for system in ["pendulum", "double pendulum"] {
        for m in ["generated midpoint", "generated trapezoid", "hand-written midpoint", "hand-written verlet"] {
            assert!(costs.contains(&(system, m)), "{system} {m}: {costs:?}");
        }
    }
    assert_eq!(report.step_costs.iter().filter(|c| c.method.starts_with("galerkin-")).count(), 8);
    assert!(report.step_costs.iter().all(|c| c.ns_per_step.is_finite() && c.ns_per_step > 0.0));
    assert!(report.stress.bad_input.iter().any(|b| b.method == "midpoint" && b.outcome.contains("must be finite")));
    let md = String::from_utf8(read(&out.join("report.md"))).unwrap();
    assert!(md.contains("![pendulum work–precision](pendulum-work-precision.svg)"));
    // Iterations and evaluations per step of the implicit methods: a Galerkin
    // rule (Newton and fixed point) and the time-transformed Galerkin on
    // Kepler have numbers in both columns of the first target.
    for (problem, method) in
        [("pendulum", "galerkin-4"), ("pendulum", "galerkin-fp-4"), ("kepler-0.5", "tt-galerkin-4")]
    {
        let section = &md[md.find(&format!("{problem}-work-precision.svg")).unwrap()..];
        let section = &section[section.find("Work per step").unwrap()..];
        let row =
            section.lines().find(|l| l.starts_with(&format!("| {method} | "))).unwrap_or_else(|| panic!("{method}"));
        let cells: Vec<&str> = row.trim_matches('|').split(" | ").map(str::trim).collect();
        let number = |c: &str| c.parse::<f64>().is_ok_and(|x| x > 0.0);
        assert!(number(cells[1]) && number(cells[2]), "{problem} {method}: {row}");
    }
    let html = String::from_utf8(read(&out.join("report.html"))).unwrap();
    assert!(html.contains("<img src=\"kepler-0.5-energy.svg\""));
    // Nothing temporary left beside it.
    let left: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(left, [std::ffi::OsString::from("report")]);
    // The README section is generated from this JSON.
    let readme = dir.join("README.md");
    std::fs::write(
        &readme,
        "intro\n<!-- bench:headline:begin -->\nstale\n<!-- bench:headline:end -->\nmiddle\n\
         <!-- bench:step-cost:begin -->\nstale\n<!-- bench:step-cost:end -->\nrest\n",
    )
    .unwrap();
    let status =
        bin().arg("readme").arg("--from").arg(out.join("report.json")).arg("--readme").arg(&readme).output().unwrap();
    assert!(status.status.success(), "{}", String::from_utf8_lossy(&status.stderr));
    let text = std::fs::read_to_string(&readme).unwrap();
    assert!(text.starts_with("intro\n") && text.ends_with("rest\n") && !text.contains("stale"));
    assert!(text.contains("| pendulum | 1.0e-3 |"), "{text}");
    // Each section says which command and day made it.
    assert!(text.contains("`cargo run --release -p lagrangian-bench -- --tiny"), "{text}");
    assert!(text.contains("Suite `tiny` of 20"), "{text}");
    assert!(text.contains("\nmiddle\n") && text.contains("| double pendulum | "), "{text}");
    // One section only, and an unknown one refused.
    std::fs::write(&readme, "<!-- bench:compositions:begin -->\n<!-- bench:compositions:end -->\n").unwrap();
    let status = bin()
        .args(["readme", "--section", "compositions", "--from"])
        .arg(out.join("report.json"))
        .arg("--readme")
        .arg(&readme)
        .output()
        .unwrap();
    assert!(status.status.success(), "{}", String::from_utf8_lossy(&status.stderr));
    let text = std::fs::read_to_string(&readme).unwrap();
    assert!(text.contains("| kepler-0.5 | 1.0e-3 | composition-kahan-li8 "), "{text}");
    let status = bin().args(["readme", "--section", "nope", "--readme"]).arg(&readme).output().unwrap();
    assert!(!status.status.success());
    assert!(String::from_utf8_lossy(&status.stderr).contains("unknown README section `nope`"));
    std::fs::remove_dir_all(&dir).unwrap();
}

/// Progress: a line per unit of work as it starts (number of all, problem,
/// method), then `done`; the headline and the report's path on stdout.
#[test]
fn progress_lines_name_problem_method_and_count() {
    let dir = scratch("progress");
    let out = dir.join("report");
    let run = bin()
        .args(["--tiny", "--problem", "pendulum", "--method", "verlet,midpoint", "--calibration-only", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let err = String::from_utf8_lossy(&run.stderr);
    // Without the stress section: the reference, the methods in the order given, the twins.
    let lines: Vec<&str> = err.lines().map(|l| l.split_once("] ").map_or(l, |(_, rest)| rest)).collect();
    assert_eq!(
        lines,
        [
            "1/4 problem 1/1 pendulum: reference",
            "2/4 problem 1/1 pendulum: method 1/2 verlet",
            "3/4 problem 1/1 pendulum: method 2/2 midpoint",
            "4/4 problem 1/1 pendulum: generated against hand-written",
            "done",
        ],
        "{err}"
    );
    let stdout = String::from_utf8_lossy(&run.stdout);
    assert!(stdout.contains("| pendulum | 1.0e-3 |"), "{stdout}");
    assert!(stdout.contains(&format!("report: {}", out.join("report.md").display())), "{stdout}");
    std::fs::remove_dir_all(&dir).unwrap();
}

/// The default suite names problems that exist, one of each family.
#[test]
fn the_default_suite_runs_known_problems() {
    let known = lagrangian_bench::suite::problem_ids();
    let default = lagrangian_bench::suite::DEFAULT_PROBLEMS;
    assert!(default.iter().all(|id| known.contains(id)), "{default:?} against {known:?}");
    // One Cartesian Kepler orbit (the polar one is the long non-separable run).
    assert_eq!(default.iter().filter(|id| id.starts_with("kepler-0.")).count(), 1);
    assert!(default.contains(&"kepler-polar"));
    assert_eq!(default.len(), known.len() - 1, "every problem but the second Cartesian Kepler orbit");
}

#[test]
fn bad_command_lines_fail_with_a_message() {
    for (args, expected) in [
        (vec!["--problem", "pendulum,nope"], "unknown problem `nope`"),
        (vec!["--method", "rk4"], "unknown method `rk4`"),
        (vec!["--frobnicate"], "unknown argument `--frobnicate`"),
        (vec!["--out"], "`--out` needs a directory"),
    ] {
        let out = bin().args(&args).output().unwrap();
        assert!(!out.status.success(), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(expected), "{args:?}: {err}");
    }
}

#[test]
fn unwritable_output_and_failing_reference_leave_nothing() {
    let dir = scratch("bad");
    // A file where a directory is needed.
    let blocker = dir.join("file");
    std::fs::write(&blocker, "x").unwrap();
    let out = bin()
        .args(["--tiny", "--no-progress", "--problem", "pendulum", "--method", "verlet", "--out"])
        .arg(blocker.join("report"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("cannot"), "{}", String::from_utf8_lossy(&out.stderr));
    // A reference check that cannot pass (double-double runs never agree to 0 exactly on Hénon–Heiles).
    let target = dir.join("report");
    let out = bin()
        .args(["--tiny", "--no-progress", "--problem", "henon-heiles", "--method", "verlet"])
        .args(["--reference-tolerance", "0", "--out"])
        .arg(&target)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("failed its check"), "{err}");
    let left: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(left, [std::ffi::OsString::from("file")], "nothing written");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn calibration_meets_the_target_and_matches_a_direct_run() {
    let p = problem::all(0.1).into_iter().find(|p| p.id() == "pendulum").unwrap();
    let t = p.horizon();
    let reference = p.reference(t, 1e-14).unwrap();
    let target = 1e-6;
    for method in [Method::Galerkin(3), Method::Midpoint, Method::OdeSolversDop853] {
        let limits = Limits { smallest_target: target, run_budget: 5.0, per_octave: 4 };
        let points = calibrate::sweep(&*p, method, &reference.q, t, limits, |_| {});
        let k = calibrate::select(&points, target).unwrap_or_else(|| panic!("{method:?}: {points:?}"));
        // The rule: the selected setting and the next two meet the target, and it is the coarsest such.
        assert!(points[k..k + 3].iter().all(|pt| pt.error.unwrap() <= target));
        assert!((0..k).all(|j| points[j..j + 3].iter().any(|pt| pt.error.is_none_or(|e| e > target))));
        // The recorded error is that of a direct run with the same setting (runs are deterministic).
        let direct = p.run(method, points[k].setting, t, 0);
        let error = calibrate::error_of(&direct.q, &reference.q).unwrap();
        assert_eq!(error, points[k].error.unwrap(), "{method:?}");
        if let Setting::Steps(n) = points[k].setting {
            assert_eq!(direct.steps, n as u64);
        }
    }
}

#[test]
fn a_sweep_that_fails_at_every_setting_gives_up_after_three_octaves() {
    // Energy-preserving midpoint steps lose the energy root on the double pendulum near
    // t = 0.29 at every step size: the sweep must stop, not refine towards 1e9 steps.
    let p = problem::all(1.0).into_iter().find(|p| p.id() == "double-pendulum").unwrap();
    let t = p.horizon();
    let reference = p.reference(t, 1e-14).unwrap();
    let limits = Limits { smallest_target: 1e-10, run_budget: 5.0, per_octave: 2 };
    let points = calibrate::sweep(&*p, Method::EnergyMidpoint, &reference.q, t, limits, |_| {});
    let window = calibrate::FAILED_OCTAVES * 2;
    assert!(points.iter().all(|pt| pt.failure.is_some()), "{points:?}");
    assert_eq!(points.len(), window, "{points:?}");
}

/// `--scale` and `--calibration-only`: the horizon grows by the factor, only
/// the calibration runs, and `readme` rewrites the matching
/// `calibrated-ID-xK` section while leaving the suite-wide ones alone (and
/// refusing them when asked by name).
#[test]
fn a_scaled_calibration_fills_only_its_own_readme_section() {
    let dir = scratch("scaled");
    let out = dir.join("report");
    let run = |scale: &str, out: &Path| {
        let status = bin()
            .args(["--tiny", "--no-progress", "--problem", "pendulum", "--targets", "1e-3", "--scale", scale])
            .args(["--calibration-only", "--out"])
            .arg(out)
            .output()
            .unwrap();
        assert!(status.status.success(), "{}", String::from_utf8_lossy(&status.stderr));
        let report: Report = serde_json::from_slice(&read(&out.join("report.json"))).unwrap();
        report
    };
    let scaled = run("3", &out);
    let plain = run("1", &dir.join("plain"));
    assert_eq!(scaled.horizon_scale, 3.0);
    assert!(scaled.calibration_only);
    assert_eq!(scaled.targets, [1e-3]);
    let ratio = scaled.problems[0].horizon / plain.problems[0].horizon;
    // The pendulum's horizon is (50 s + ¼) periods: not exactly proportional to s.
    assert!((ratio - (150.0 * 0.02 + 0.25) / (50.0 * 0.02 + 0.25)).abs() < 1e-12, "{ratio}");
    assert!(scaled.stress.long_runs.is_empty() && scaled.step_costs.is_empty());
    assert!(scaled.problems[0].energy.is_empty());

    let readme = dir.join("README.md");
    let text = "intro\n<!-- bench:calibrated-pendulum-x3:begin -->\nold\n<!-- bench:calibrated-pendulum-x3:end -->\n\
                <!-- bench:headline:begin -->\nkept\n<!-- bench:headline:end -->\n";
    std::fs::write(&readme, text).unwrap();
    let update = |section: Option<&str>| {
        let mut c = bin();
        c.arg("readme").arg("--from").arg(out.join("report.json")).arg("--readme").arg(&readme);
        if let Some(s) = section {
            c.args(["--section", s]);
        }
        c.output().unwrap()
    };
    assert!(update(None).status.success());
    let new = std::fs::read_to_string(&readme).unwrap();
    assert!(new.contains("kept") && !new.contains("old"), "{new}");
    assert!(new.contains("run at 3× that horizon") && new.contains("| 1.0e-3 | "), "{new}");
    // Asked by name, a section the report cannot supply is an error, and nothing is written.
    let refused = update(Some("headline"));
    assert!(!refused.status.success());
    assert!(String::from_utf8_lossy(&refused.stderr).contains("cannot supply section `headline`"));
    assert_eq!(std::fs::read_to_string(&readme).unwrap(), new);
    assert!(!update(Some("calibrated-pendulum-x2")).status.success());
}

/// The date in a generated section's header is the report file's day.
#[test]
fn day_counts_become_calendar_dates() {
    use lagrangian_bench::readme::civil_from_days;
    assert_eq!(civil_from_days(0), (1970, 1, 1));
    assert_eq!(civil_from_days(-1), (1969, 12, 31));
    assert_eq!(civil_from_days(11_016), (2000, 2, 29));
    assert_eq!(civil_from_days(20_000), (2024, 10, 4));
    assert_eq!(civil_from_days(20_785), (2026, 11, 28));
}
