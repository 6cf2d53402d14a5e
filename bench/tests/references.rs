//! Each reference solution against an independent one: the closed forms
//! (pendulum, Kepler) against double-double Galerkin runs; the double-double
//! Galerkin references (Hénon–Heiles, double pendulum, outer solar system)
//! against the hand-written Kahan–Li composition or DOP853 in `f64` at tight
//! tolerances.

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
        for id in ["pendulum", "kepler-0.5", "kepler-0.9"] {
            let p = get(id, 0.1);
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
        for (id, scale, tol) in
            [("henon-heiles", 0.2, 1e-11), ("double-pendulum", 0.3, 1e-9), ("outer-solar-system", 0.02, 1e-9)]
        {
            let p = get(id, scale);
            let t = p.horizon();
            let r = p.reference(t, 1e-14).unwrap();
            assert_eq!(r.kind, "double-double galerkin");
            assert!(r.agreement <= r.accepted);
            let other = if p.separable() {
                p.run(Method::KahanLi8, Setting::Steps(p.coarsest_steps() * 40), t, 0)
            } else {
                p.run(Method::OdeSolversDop853, Setting::Tolerance(1e-14), t, 0)
            };
            let d = diff(&r.q, &other.q);
            assert!(d < tol, "{id}: {d:e}");
        }
    });
}
