//! Each reference solution against an independent one: the closed forms
//! (pendulum, Kepler) against double-double Galerkin runs; the double-double
//! Galerkin references (Hénon–Heiles, double pendulum, outer solar system,
//! FPU-β chain, perturbed pendulum, sensor) against the hand-written Kahan–Li
//! composition or DOP853 in `f64` at tight tolerances, which integrate the
//! hand-written equations of motion rather than the Lagrangian.

use core::f64::consts::PI;
use lagrangian::prelude::DoubleDouble;
use lagrangian_bench::exact::*;
use lagrangian_bench::methods::{Method, Setting};
use lagrangian_bench::problem::{self, Problem};

fn get(id: &str, scale: f64) -> Box<dyn Problem> {
    problem::all(scale).into_iter().find(|p| p.id() == id).unwrap()
}

/// Double-double Galerkin with s = 8 on 18 degrees of freedom keeps large
/// blocks on the stack: more than a test thread's default.
fn big_stack(f: impl FnOnce() + Send + 'static) {
    std::thread::Builder::new().stack_size(256 << 20).spawn(f).unwrap().join().unwrap();
}

fn diff(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max)
}

#[test]
fn closed_forms_agree_with_double_double_galerkin() {
    big_stack(|| {
        // One orbit of the polar Kepler problem (its horizon is 1000 orbits).
        for (id, scale) in [("pendulum", 0.1), ("kepler-0.5", 0.1), ("kepler-0.9", 0.1), ("kepler-polar", 0.001)] {
            let p = get(id, scale);
            let t = p.horizon();
            let exact = p.reference(t, 1e-14).unwrap();
            assert_eq!(exact.kind, "exact");
            // The same model integrated in double-double (order 16, small steps).
            let dd = p.double_double_galerkin(t, (t / 0.005).ceil() as usize).unwrap();
            let d = diff(&exact.q, &dd);
            assert!(d < 1e-13, "{id}: {d:e}");
        }
    });
}

#[test]
fn double_double_references_agree_with_independent_f64_methods() {
    big_stack(|| {
        // differential-equations' DOP853 for the time-dependent problem: ode_solvers 0.6 evaluates
        // DOP853's last stage at the start of the step (c₁₂ = 0), which only autonomous systems forgive.
        for (id, scale, tol, peer) in [
            ("henon-heiles", 0.2, 1e-11, Method::OdeSolversDop853),
            ("double-pendulum", 0.3, 1e-9, Method::OdeSolversDop853),
            ("outer-solar-system", 0.02, 1e-9, Method::OdeSolversDop853),
            ("fpu-beta", 0.2, 1e-12, Method::OdeSolversDop853),
            ("perturbed-pendulum", 0.1, 1e-12, Method::DiffEqDop853),
            ("sensor", 0.5, 1e-12, Method::OdeSolversDop853),
        ] {
            let p = get(id, scale);
            let t = p.horizon();
            let r = p.reference(t, 1e-14).unwrap();
            assert_eq!(r.kind, "double-double galerkin");
            assert!(r.agreement <= r.accepted);
            let other = if p.separable() {
                p.run(Method::KahanLi8, Setting::Steps(p.coarsest_steps() * 40), t, 0)
            } else {
                p.run(peer, Setting::Tolerance(1e-14), t, 0)
            };
            assert!(other.failure.is_none(), "{id}: {:?}", other.failure);
            let d = diff(&r.q, &other.q);
            assert!(d < tol, "{id}: {d:e}");
        }
    });
}

#[test]
fn the_new_problems_are_what_they_claim() {
    // The FPU-β chain is separable: the hand-written compositions apply and its energy is recorded.
    let fpu = get("fpu-beta", 0.1);
    assert!(fpu.separable() && fpu.conservative());
    let run = fpu.run(Method::Verlet, Setting::Steps(100), fpu.horizon(), 10);
    assert!(run.failure.is_none() && run.energy.len() > 5);
    assert!(run.energy.iter().all(|s| s.1.abs() < 1e-2), "{:?}", run.energy);
    // Time-dependent and forced: no energy errors recorded (the energy changes by physics), no compositions.
    for id in ["perturbed-pendulum", "sensor"] {
        let p = get(id, 0.1);
        assert!(!p.conservative() && !p.separable(), "{id}");
        let run = p.run(Method::Midpoint, Setting::Steps(200), p.horizon(), 10);
        assert!(run.failure.is_none() && run.energy.is_empty(), "{id}: {run:?}");
    }
    // The forcing acts: switched on at rest, the sensor's charge grows and the armature moves.
    let sensor = get("sensor", 1.0);
    let r = sensor.reference(sensor.horizon(), 1e-14).unwrap();
    let (x, charge) = (r.q[0], r.q[1]);
    // After 40 time constants the current is near E/r = 1.2 A: q(2) ≈ 1.2·(2 − L0/r) with L1 ≈ L0.
    assert!((charge - 1.2 * (2.0 - 0.05)).abs() < 0.05, "{charge}");
    assert!(x != 0.0 && x.abs() < 0.05, "{x}");
}

#[test]
fn a_run_that_blows_up_records_only_finite_energies() {
    // Störmer–Verlet on the chain at h = 2.5 (h·ω_max ≈ 5, beyond its stability bound 2).
    let fpu = get("fpu-beta", 1.0);
    let run = fpu.run(Method::Verlet, Setting::Steps(20), fpu.horizon(), 20);
    assert_eq!(run.failure.as_deref(), Some("non-finite state"));
    assert!(!run.energy.is_empty() && run.energy.iter().all(|s| s.1.is_finite()), "{:?}", run.energy);
}

#[test]
fn pendulum_formulas_are_consistent() {
    assert!((jacobi_cd(0.0, 0.3) - 1.0f64).abs() < 1e-15);
    let (w, th) = (3.0, 1.0);
    let period = pendulum_period(w, th);
    assert!((pendulum_angle(w, th, period) - th).abs() < 1e-13);
    assert!(pendulum_angle(w, th, 0.25 * period).abs() < 1e-13);
    assert!((pendulum_period(w, 1e-6) - 2.0 * PI / w).abs() < 1e-12);
}

#[test]
fn kepler_formulas_are_consistent() {
    for e in [0.0, 0.5, 0.9, 0.99] {
        // Back at pericentre after 2π; the energy −1/2 and angular momentum √(1−e²) hold on the orbit.
        let q = kepler_position(e, 2.0 * PI);
        assert!((q[0] - (1.0 - e)).abs() < 1e-13 && q[1].abs() < 1e-12, "{e}: {q:?}");
        let (dt, t) = (1e-5, 1.234);
        let (a, b) = (kepler_position(e, t - dt), kepler_position(e, t + dt));
        let q = kepler_position(e, t);
        let v = [(b[0] - a[0]) / (2.0 * dt), (b[1] - a[1]) / (2.0 * dt)];
        let r = q[0].hypot(q[1]);
        let energy = 0.5 * (v[0] * v[0] + v[1] * v[1]) - 1.0 / r;
        assert!((energy + 0.5).abs() < 1e-7, "{e}: {energy}");
        assert!((q[0] * v[1] - q[1] * v[0] - (1.0 - e * e).sqrt()).abs() < 1e-7);
    }
}

#[test]
fn double_double_agrees_with_f64() {
    let dd = |x: f64| DoubleDouble::from(x);
    let q = kepler_position(dd(0.9), dd(7.5));
    let f = kepler_position(0.9, 7.5);
    assert!((q[0].to_f64() - f[0]).abs() < 1e-14 && (q[1].to_f64() - f[1]).abs() < 1e-14);
    let th = pendulum_angle(dd(3.0), dd(1.0), dd(40.0)).to_f64();
    assert!((th - pendulum_angle(3.0, 1.0, 40.0)).abs() < 1e-13);
}
