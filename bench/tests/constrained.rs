//! The double pendulum in Cartesian coordinates: its reference (the angle
//! problem's, mapped) against an independent formulation, the constraint
//! errors each method leaves, the orders of the constrained rules, and the
//! report's drift table.

use std::path::PathBuf;
use std::process::Command;

use lagrangian_bench::cartesian;
use lagrangian_bench::constrained::CartesianDoublePendulum;
use lagrangian_bench::methods::{Method, Setting};
use lagrangian_bench::problem::{self, Problem};
use lagrangian_bench::report::Report;
use lagrangian_bench::run::Run;

fn get(scale: f64) -> Box<dyn Problem> {
    problem::all(scale).into_iter().find(|p| p.id() == CartesianDoublePendulum::ID).expect("the problem is listed")
}

fn diff(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max)
}

/// `(max position error, max velocity error)` over the run's samples.
fn drift(run: &Run) -> (f64, f64) {
    assert!(!run.constraints.is_empty(), "no constraint samples");
    run.constraints.iter().fold((0.0, 0.0), |(a, b), s| (f64::max(a, s.1[0]), f64::max(b, s.1[1])))
}

/// Double-double Galerkin on 2 degrees of freedom in a debug build: more
/// stack than a test thread's default.
fn big_stack(f: impl FnOnce() + Send + 'static) {
    std::thread::Builder::new().stack_size(256 << 20).spawn(f).unwrap().join().unwrap();
}

#[test]
fn the_reference_agrees_with_dop853_on_the_cartesian_equations() {
    big_stack(|| {
        let p = get(0.3);
        let t = p.horizon();
        let r = p.reference(t, 1e-14).unwrap();
        assert!(r.agreement <= r.accepted, "{r:?}");
        // The index-1 Cartesian equations are another formulation of the same motion: the
        // positions agree to DOP853's tolerance (the chaotic motion amplifies it over t = 3).
        let run = p.run(Method::Dop853Baumgarte, Setting::Tolerance(1e-13), t, 0);
        assert!(run.failure.is_none(), "{:?}", run.failure);
        let d = diff(&r.q, &run.q);
        assert!(d < 1e-8, "{d:e}");
        // The rods have their lengths at the reference.
        let [e, _] = cartesian::constraint_errors(&<[f64; 4]>::try_from(r.q.as_slice()).unwrap(), &[0.0; 4]);
        assert!(e < 1e-15, "{e:e}");
    });
}

#[test]
fn constrained_rules_hold_the_constraints_to_round_off_and_baumgarte_drifts() {
    let p = get(0.2);
    let t = p.horizon();
    for m in [Method::Midpoint, Method::Trapezoid, Method::Galerkin(2), Method::GeneratedYoshida4] {
        let run = p.run(m, Setting::Steps(200), t, 100);
        assert!(run.failure.is_none(), "{m:?}: {:?}", run.failure);
        let (g, gv) = drift(&run);
        assert!(g < 1e-14 && gv < 1e-13, "{m:?}: {g:e} {gv:e}");
        let e = run.energy.iter().map(|s| s.1.abs()).fold(0.0, f64::max);
        assert!(e > 0.0 && e < 1e-2, "{m:?}: energy {e:e}");
    }
    // The angle equations know no constraints: only the round-off of the map to positions.
    let (g, gv) = drift(&p.run(Method::Dop853Angles, Setting::Tolerance(1e-6), t, 100));
    assert!(g < 1e-15 && gv < 1e-13, "angles: {g:e} {gv:e}");
    // Baumgarte's stabilisation damps the drift of the index-1 equations, it does not remove it.
    let (g, gv) = drift(&p.run(Method::Dop853Baumgarte, Setting::Tolerance(1e-6), t, 100));
    assert!(g > 1e-11 && gv > 1e-10, "Baumgarte: {g:e} {gv:e}");
}

#[test]
fn constrained_rules_have_their_orders_against_the_reference() {
    big_stack(|| {
        let p = get(0.2);
        let t = p.horizon();
        let reference = p.reference(t, 1e-14).unwrap().q;
        for (m, order, steps) in [(Method::Midpoint, 2.0, [400, 800]), (Method::Galerkin(2), 4.0, [100, 200])] {
            let errors = steps.map(|n| diff(&p.run(m, Setting::Steps(n), t, 0).q, &reference));
            let fitted = (errors[0] / errors[1]).log2();
            assert!((fitted - order).abs() < 0.3, "{m:?}: {errors:?} {fitted}");
        }
    });
}

#[test]
fn the_report_shows_the_drift_of_each_calibrated_run() {
    let dir = std::env::temp_dir().join(format!("lagrangian-bench-test-{}-constrained", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let out: PathBuf = dir.join("report");
    let status = Command::new(env!("CARGO_BIN_EXE_lagrangian-bench"))
        .args(["--tiny", "--no-progress", "--calibration-only", "--problem", CartesianDoublePendulum::ID, "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(status.status.success(), "{}", String::from_utf8_lossy(&status.stderr));
    let report: Report = serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
    let p = &report.problems[0];
    let applicable = Method::all().into_iter().filter(|&m| CartesianDoublePendulum::method_applies(m)).count();
    assert_eq!(p.sweeps.len(), applicable);
    let reached = p.calibrated.iter().filter(|c| c.setting.is_some()).count();
    assert!(reached > 0 && p.constraints.len() == reached, "{:?}", p.constraints);
    for c in &p.constraints {
        let (g, gv) = (c.position_max.unwrap(), c.velocity_max.unwrap());
        if c.method != "ode_solvers-dop853-baumgarte" {
            assert!(g < 1e-14 && gv < 1e-13, "{}: {g:e} {gv:e}", c.method);
        }
    }
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(md.contains("max rod length error / length"), "{md}");
    std::fs::remove_dir_all(&dir).unwrap();
}
