//! Time-dependent Lagrangians and rheonomic constraints `g(t, q) = 0`: a
//! pendulum on an oscillating support under a varying gravity, and a bead
//! on a rotating hoop, each against its minimal-coordinate form.

use lagrangian::galerkin::Galerkin;
use lagrangian::prelude::*;

use super::{fitted_order, rk4};

/// The support's height `s(t) = 0.3 sin 2t` and its derivatives.
fn support(t: f64) -> (f64, f64, f64) {
    (0.3 * (2.0 * t).sin(), 0.6 * (2.0 * t).cos(), -1.2 * (2.0 * t).sin())
}

/// The gravity `γ(t) = 1 + 0.2 cos t`.
fn gravity(t: f64) -> f64 {
    1.0 + 0.2 * t.cos()
}

/// A unit pendulum hanging from a support at `(0, s(t))`, under the gravity
/// `γ(t)`: a time-dependent Lagrangian and a time-dependent constraint.
#[derive(Clone, Debug)]
struct ShakenPendulum;

#[lagrangian]
impl ShakenPendulum {
    fn lagrangian(&self, t: f64, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) - (1.0 + 0.2 * t.cos()) * q[1]
    }
    fn constraints(&self, t: f64, q: [f64; 2]) -> [f64; 1] {
        let dy = q[1] - 0.3 * (2.0 * t).sin();
        [q[0] * q[0] + dy * dy - 1.0]
    }
}

/// A bead on a unit hoop turning at `ω` about the vertical axis, gravity
/// along `−z`: `|q| = 1` and the hoop's plane `−sin(ωt) x + cos(ωt) y = 0`.
#[derive(Clone, Debug)]
pub(crate) struct Hoop {
    pub(crate) omega: f64,
}

#[lagrangian]
impl Hoop {
    fn lagrangian(&self, q: [f64; 3], v: [f64; 3]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) - q[2]
    }
    fn constraints(&self, t: f64, q: [f64; 3]) -> [f64; 2] {
        let angle = self.omega * t;
        [q[0] * q[0] + q[1] * q[1] + q[2] * q[2] - 1.0, angle.cos() * q[1] - angle.sin() * q[0]]
    }
}

const OMEGA: f64 = 1.5;
const T_END: f64 = 3.0;

/// The shaken pendulum from `θ = 1` at rest relative to its support, to
/// `T_END`: the end position and the largest `|g|`, `|G v + ∂g/∂t|`.
fn shaken_run<D: DiscreteLagrangian>(rule: D, h: f64) -> ([f64; 2], f64, f64) {
    let (s, ds, _) = support(0.0);
    let (q0, v0) = ([1f64.sin(), s - 1f64.cos()], [0.0, ds]);
    let method = Constrained::<_, 1>::new(rule);
    let mut sim = Integrator::new(ShakenPendulum, method, h).start(0.0, q0, v0).unwrap();
    let (mut g, mut gv) = (0.0f64, 0.0f64);
    sim.run_until(T_END, |s| {
        g = g.max(s.constraint_values()[0].abs());
        gv = gv.max(s.constraint_velocities().unwrap()[0].abs());
    })
    .unwrap();
    (sim.state().q, g, gv)
}

#[test]
fn shaken_pendulum_under_varying_gravity_matches_the_angle_form_at_order_two() {
    // θ'' = −(γ(t) + s''(t)) sin θ; x = sin θ, y = s(t) − cos θ.
    let rhs = |y: &[f64; 3]| {
        let [theta, omega, t] = *y;
        [omega, -(gravity(t) + support(t).2) * theta.sin(), 1.0]
    };
    let [theta, ..] = rk4(rhs, [1.0, 0.0, 0.0], T_END, 30_000);
    let exact = [theta.sin(), support(T_END).0 - theta.cos()];
    let hs = [0.04, 0.02, 0.01, 0.005];
    for (name, runs) in
        [("midpoint", hs.map(|h| shaken_run(Midpoint, h))), ("trapezoid", hs.map(|h| shaken_run(Trapezoid, h)))]
    {
        let errors: Vec<f64> =
            runs.iter().map(|(q, ..)| (q[0] - exact[0]).abs().max((q[1] - exact[1]).abs())).collect();
        let order = fitted_order(&hs, &errors);
        println!("shaken pendulum, {name}: errors {errors:?}, fitted order {order:.3}");
        assert!((order - 2.0).abs() < 0.1, "{name}: fitted order {order}, errors {errors:?}");
        for (h, (_, g, gv)) in hs.iter().zip(&runs) {
            assert!(*g <= 2e-15 && *gv <= 1e-14, "{name}, h = {h}: max |g| = {g:e}, max |G v + g_t| = {gv:e}");
        }
    }
}

/// The bead from `θ₀` (from the bottom) at rest on the hoop: the initial
/// data, projected so that the bead turns with the hoop.
fn hoop_initial(theta0: f64) -> ([f64; 3], [f64; 3]) {
    let method = Constrained::<Midpoint, 2>::new(Midpoint);
    let q = [theta0.sin(), 0.0, -theta0.cos()];
    method.project(&Hoop { omega: OMEGA }, 0.0, q, [0.0; 3]).unwrap()
}

#[test]
fn projection_gives_the_bead_the_hoops_motion() {
    let (q, v) = hoop_initial(0.5);
    let expected = [0.0, OMEGA * 0.5f64.sin(), 0.0];
    assert!((0..3).all(|i| (v[i] - expected[i]).abs() < 1e-15), "{v:?}");
    assert_eq!(q, [0.5f64.sin(), 0.0, -0.5f64.cos()]);
    // At rest in a turning hoop is not on the moving manifold's tangent space.
    let refused =
        Integrator::new(Hoop { omega: OMEGA }, Constrained::<_, 2>::new(Midpoint), 0.01).start(0.0, q, [0.0; 3]);
    assert!(matches!(refused, Err(Error::InconsistentConstraints { velocity, .. }) if velocity > 0.1), "{refused:?}");
}

#[test]
fn bead_on_a_rotating_hoop_matches_the_angle_form_at_order_two() {
    // θ'' = (ω² cos θ − 1) sin θ; q = (sin θ cos ωt, sin θ sin ωt, −cos θ).
    let rhs = |y: &[f64; 2]| [y[1], (OMEGA * OMEGA * y[0].cos() - 1.0) * y[0].sin()];
    let [theta, _] = rk4(rhs, [0.5, 0.0], T_END, 30_000);
    let (s, c) = (OMEGA * T_END).sin_cos();
    let exact = [theta.sin() * c, theta.sin() * s, -theta.cos()];
    let (q0, v0) = hoop_initial(0.5);
    let hs = [0.04, 0.02, 0.01, 0.005];
    let errors: Vec<f64> = hs
        .iter()
        .map(|&h| {
            let method = Constrained::<_, 2>::new(Midpoint);
            let mut sim = Integrator::new(Hoop { omega: OMEGA }, method, h).start(0.0, q0, v0).unwrap();
            let (mut g, mut gv) = (0.0f64, 0.0f64);
            sim.run_until(T_END, |s| {
                g = s.constraint_values().iter().fold(g, |m, x| m.max(x.abs()));
                gv = s.constraint_velocities().unwrap().iter().fold(gv, |m, x| m.max(x.abs()));
            })
            .unwrap();
            assert!(g <= 2e-15 && gv <= 1e-14, "h = {h}: max |g| = {g:e}, max |G v + g_t| = {gv:e}");
            (0..3).map(|i| (sim.state().q[i] - exact[i]).abs()).fold(0.0, f64::max)
        })
        .collect();
    let order = fitted_order(&hs, &errors);
    println!("rotating hoop, midpoint: errors {errors:?}, fitted order {order:.3}");
    assert!((order - 2.0).abs() < 0.1, "fitted order {order}, errors {errors:?}");
}

/// The shaken pendulum to `T_END` under any constrained method, from `θ = 1`
/// at rest relative to its support: the end position, the largest
/// `|g(t, q)|` and the largest `|G v + ∂g/∂t|` over the nodes (unit mass:
/// `v = p`, so the latter is the momentum's distance from the moving
/// manifold's cotangent space).
fn shaken_method_run<M: Method<f64>>(method: M, h: f64) -> ([f64; 2], f64, f64) {
    let (s, ds, _) = support(0.0);
    let (q0, v0) = ([1f64.sin(), s - 1f64.cos()], [0.0, ds]);
    let mut sim = Integrator::new(ShakenPendulum, method, h).start(0.0, q0, v0).unwrap();
    let (mut g, mut gv) = (0.0f64, 0.0f64);
    sim.run_until(T_END, |s| {
        let State { t, q, p, .. } = *s.state();
        let (height, rate, _) = support(t);
        g = g.max(ShakenPendulum.constraints(t, q)[0].abs());
        gv = gv.max((2.0 * q[0] * p[0] + 2.0 * (q[1] - height) * (p[1] - rate)).abs());
    })
    .unwrap();
    (sim.state().q, g, gv)
}

#[test]
fn shaken_pendulum_under_galerkin_rules_matches_the_angle_form_at_order_2s() {
    // θ'' = −(γ(t) + s''(t)) sin θ; x = sin θ, y = s(t) − cos θ. The
    // reference's own error is bounded by its change when its step is halved
    // (fourth order: about 15 times the error).
    let rhs = |y: &[f64; 3]| {
        let [theta, omega, t] = *y;
        [omega, -(gravity(t) + support(t).2) * theta.sin(), 1.0]
    };
    let exact = |n: usize| {
        let [theta, ..] = rk4(rhs, [1.0, 0.0, 0.0], T_END, n);
        [theta.sin(), support(T_END).0 - theta.cos()]
    };
    let (reference, coarser) = (exact(240_000), exact(120_000));
    let reference_error = (reference[0] - coarser[0]).abs().max((reference[1] - coarser[1]).abs());
    let gauss2 = Constrained::<_, 1>::galerkin(Galerkin::<2, 2>::gauss());
    let gauss3 = Constrained::<_, 1>::galerkin(Galerkin::<3, 3>::gauss());
    let (hs2, hs3) = ([0.2, 0.1, 0.05], [0.3, 0.2, 0.15, 0.1]);
    let runs2: Vec<_> = hs2.iter().map(|&h| shaken_method_run(gauss2, h)).collect();
    let runs3: Vec<_> = hs3.iter().map(|&h| shaken_method_run(gauss3, h)).collect();
    for (name, hs, runs, want) in [("gauss s = 2", &hs2[..], runs2, 4.0), ("gauss s = 3", &hs3[..], runs3, 6.0)] {
        let errors: Vec<f64> =
            runs.iter().map(|(q, ..)| (q[0] - reference[0]).abs().max((q[1] - reference[1]).abs())).collect();
        for (h, (_, g, gv)) in hs.iter().zip(&runs) {
            println!("shaken pendulum, {name}, h = {h}: max |g| {g:.1e}, max |G v + g_t| {gv:.1e}");
            assert!(*g <= 2e-15 && *gv <= 4e-15, "{name}, h = {h}: max |g| = {g:e}, max |G v + g_t| = {gv:e}");
        }
        let smallest = errors.iter().fold(f64::INFINITY, |m, &e| m.min(e));
        assert!(reference_error < 1e-3 * smallest, "reference error {reference_error:e} against {errors:?}");
        let order = fitted_order(hs, &errors);
        println!(
            "shaken pendulum, {name}: errors {errors:?}, fitted order {order:.3} (reference {reference_error:.1e})"
        );
        assert!((order - want).abs() < 0.15, "{name}: fitted order {order}, errors {errors:?}");
    }
}
