//! Forces and dissipation with constraints (discrete Lagrange–d'Alembert
//! with multipliers): a damped, driven pendulum in Cartesian coordinates
//! against the same pendulum in its angle.

use lagrangian::galerkin::Galerkin;
use lagrangian::prelude::*;

use super::{fitted_order, rk4};

/// A unit pendulum under unit gravity as a point on a circle, damped by
/// `R = ½ c |v|²` and pushed horizontally by `a cos(ω t)`.
#[derive(Clone, Debug)]
struct DampedPendulum;

const C: f64 = 0.3;
const A: f64 = 0.5;
const W: f64 = 1.3;

#[lagrangian]
impl DampedPendulum {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) - q[1]
    }
    fn dissipation(&self, _q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * C * (v[0] * v[0] + v[1] * v[1])
    }
    fn force(&self, t: f64, _q: [f64; 2], _v: [f64; 2]) -> [f64; 2] {
        [A * (W * t).cos(), 0.0 * t]
    }
    fn constraints(&self, q: [f64; 2]) -> [f64; 1] {
        [q[0] * q[0] + q[1] * q[1] - 1.0]
    }
}

/// The angle form: `θ'' = −sin θ − c θ' + a cos(ω t) cos θ`, with the time
/// as a third component.
fn angle_rhs(y: &[f64; 3]) -> [f64; 3] {
    let [theta, omega, t] = *y;
    [omega, -theta.sin() - C * omega + A * (W * t).cos() * theta.cos(), 1.0]
}

/// One run to `t = 3` from `θ = 1` at rest: the end position, the largest
/// `|g|` and `|G v|` on the way, and the largest `|Σ (E_{k+1} − E_k − W_k)|`
/// over the nodes, the accumulated defect of the energy balance.
fn run<D: DiscreteLagrangian>(rule: D, h: f64) -> ([f64; 2], f64, f64, f64) {
    let q0 = [1f64.sin(), -1f64.cos()];
    let method = Constrained::<_, 1>::new(rule);
    let mut sim = Integrator::new(DampedPendulum, method, h).start(0.0, q0, [0.0; 2]).unwrap();
    let (mut g, mut gv, mut balance, mut worst) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    sim.run_until(3.0, |s| {
        g = g.max(s.constraint_values()[0].abs());
        gv = gv.max(s.constraint_velocities().unwrap()[0].abs());
        if let Some(b) = s.energy_balance() {
            balance += b.residual();
            worst = worst.max(balance.abs());
        }
    })
    .unwrap();
    (sim.state().q, g, gv, worst)
}

#[test]
fn damped_driven_cartesian_pendulum_matches_the_angle_form_at_order_two() {
    let [theta, ..] = rk4(angle_rhs, [1.0, 0.0, 0.0], 3.0, 30_000);
    let exact = [theta.sin(), -theta.cos()];
    let hs = [0.04, 0.02, 0.01, 0.005];
    for (name, runs) in [("midpoint", hs.map(|h| run(Midpoint, h))), ("trapezoid", hs.map(|h| run(Trapezoid, h)))] {
        let errors: Vec<f64> =
            runs.iter().map(|(q, ..)| (q[0] - exact[0]).abs().max((q[1] - exact[1]).abs())).collect();
        let balance: Vec<f64> = runs.iter().map(|r| r.3).collect();
        let (order, balance_order) = (fitted_order(&hs, &errors), fitted_order(&hs, &balance));
        println!(
            "damped pendulum, {name}: errors {errors:?}, order {order:.3}; energy balance defect {balance:?}, order {balance_order:.3}"
        );
        assert!((order - 2.0).abs() < 0.1, "{name}: fitted order {order}, errors {errors:?}");
        assert!((balance_order - 2.0).abs() < 0.25, "{name}: balance order {balance_order}, {balance:?}");
        for (h, (_, g, gv, _)) in hs.iter().zip(&runs) {
            assert!(*g <= 2e-15 && *gv <= 1e-14, "{name}, h = {h}: max |g| = {g:e}, max |G v| = {gv:e}");
        }
    }
}

#[test]
fn the_forces_do_the_work_the_energy_loses() {
    // The energy flows in (drive) and out (damping) by O(0.1) over the run;
    // the balance against the work of the forces closes to O(h²).
    let q0 = [1f64.sin(), -1f64.cos()];
    let method = Constrained::<_, 1>::new(Midpoint);
    let mut sim = Integrator::new(DampedPendulum, method, 0.005).start(0.0, q0, [0.0; 2]).unwrap();
    let (mut flow, mut defect) = (0.0f64, 0.0f64);
    sim.run_until(3.0, |s| {
        if let Some(b) = s.energy_balance() {
            flow += b.work.abs();
            defect += b.residual();
        }
    })
    .unwrap();
    println!("damped pendulum: energy flow {flow:.3e}, accumulated balance defect {defect:.2e}");
    assert!(flow > 0.1, "{flow}");
    assert!(defect.abs() < 1e-4 * flow, "defect {defect:e} against the flow {flow:e}");
    let f = sim.last_forces().unwrap();
    assert!(f.minus.iter().chain(&f.plus).any(|x| *x != 0.0));
    // A forced step map is not symplectic: no tangent map, as without constraints.
    assert!(sim.last_tangent_map().is_none());
}

/// A spherical pendulum with drag `R = ½ c |v|²`: its vertical angular
/// momentum decays, and only by the forces' impulse.
#[derive(Clone, Debug)]
struct DampedSpherical;

#[lagrangian]
impl DampedSpherical {
    fn lagrangian(&self, q: [f64; 3], v: [f64; 3]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) - q[2]
    }
    fn dissipation(&self, _q: [f64; 3], v: [f64; 3]) -> f64 {
        0.5 * C * (v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    }
    fn constraints(&self, q: [f64; 3]) -> [f64; 1] {
        [q[0] * q[0] + q[1] * q[1] + q[2] * q[2] - 1.0]
    }
}

#[test]
fn damped_spherical_pendulum_loses_angular_momentum_by_the_forces_impulse_alone() {
    // The constraint force 2λq has no moment about the z axis: the discrete
    // Noether balance J_{k+1} − J_k = F_k^−·ξ(q_k) + F_k^+·ξ(q_{k+1}) holds
    // on the manifold as without constraints.
    impulse_balance("", Constrained::<_, 1>::new(Midpoint), 0.01, 2000);
}

/// Steps the damped spherical pendulum with `method` and checks that each
/// step changes `L_z` by the forcing impulse alone (relative 1e-14) and
/// that damping takes more than half of it.
fn impulse_balance<M: F64Readouts>(label: &str, method: M, h: f64, steps: usize) {
    let rotation = Symmetry::<3>::rotation(0, 1).unwrap();
    let mut sim = Integrator::new(DampedSpherical, method, h).start(0.0, [0.6, 0.0, -0.8], [0.0, 1.1, 0.0]).unwrap();
    let first = sim.momentum_map(&rotation);
    let mut worst = 0.0f64;
    for _ in 0..steps {
        let before = sim.momentum_map(&rotation);
        sim.step().unwrap();
        let after = sim.momentum_map(&rotation);
        let impulse = sim.forcing_impulse(&rotation).unwrap();
        worst = worst.max((after - before - impulse).abs() / before.abs());
    }
    let last = sim.momentum_map(&rotation);
    println!("damped spherical pendulum{label}: L_z {first:.4} → {last:.4}, worst step balance {worst:.2e}");
    assert!(last < 0.5 * first, "L_z {first} → {last}");
    assert!(worst < 1e-14, "J_(k+1) − J_k − impulse, relative: {worst:e}");
}

/// The angle form to `t = 3` from `θ = 1` at rest by classical Runge–Kutta
/// in `n` steps: `(x, y)`.
fn angle_reference(n: usize) -> [f64; 2] {
    let [theta, ..] = rk4(angle_rhs, [1.0, 0.0, 0.0], 3.0, n);
    [theta.sin(), -theta.cos()]
}

/// The damped, driven pendulum to `t = 3` from `θ = 1` at rest under any
/// constrained method: the end position, the largest `|g|` and the largest
/// `|G v|` over the nodes (unit mass: `v = p`, so `G v = 2 q·p` is the
/// momentum's distance from the cotangent space).
fn method_run<M: Method<f64>>(method: M, h: f64) -> ([f64; 2], f64, f64) {
    let q0 = [1f64.sin(), -1f64.cos()];
    let mut sim = Integrator::new(DampedPendulum, method, h).start(0.0, q0, [0.0; 2]).unwrap();
    let (mut g, mut gv) = (0.0f64, 0.0f64);
    sim.run_until(3.0, |s| {
        let State { q, p, .. } = *s.state();
        g = g.max(DampedPendulum.constraints(q)[0].abs());
        gv = gv.max((2.0 * (q[0] * p[0] + q[1] * p[1])).abs());
    })
    .unwrap();
    (sim.state().q, g, gv)
}

/// The fitted order of `method` over `hs` against the angle form, after
/// checking `|g|` and `|G v|` at every node of every run and that the
/// reference's own error (bounded by its change when its step is halved)
/// is below a thousandth of the smallest error measured.
fn damped_order<M: Method<f64> + Copy>(name: &str, method: M, hs: &[f64]) -> f64 {
    // Fourth order: the change from half the steps is about 15 times the
    // reference's own error (measured 2e-14 at 120 000 steps, against 3.5e-13
    // at 30 000).
    let exact = angle_reference(240_000);
    let coarser = angle_reference(120_000);
    let reference_error = (exact[0] - coarser[0]).abs().max((exact[1] - coarser[1]).abs());
    let mut errors = Vec::new();
    for &h in hs {
        let (q, g, gv) = method_run(method, h);
        assert!(g <= 2e-15 && gv <= 4e-15, "{name}, h = {h}: max |g| = {g:e}, max |G v| = {gv:e}");
        println!("damped pendulum, {name}, h = {h}: max |g| {g:.1e}, max |G v| {gv:.1e}");
        errors.push((q[0] - exact[0]).abs().max((q[1] - exact[1]).abs()));
    }
    let smallest = errors.iter().fold(f64::INFINITY, |m, &e| m.min(e));
    assert!(reference_error < 1e-3 * smallest, "reference error {reference_error:e} against errors {errors:?}");
    let order = fitted_order(hs, &errors);
    println!("damped pendulum, {name}: errors {errors:?}, fitted order {order:.3} (reference {reference_error:.1e})");
    order
}

#[test]
fn damped_driven_cartesian_pendulum_under_galerkin_rules_has_order_2s() {
    let gauss2 = Constrained::<_, 1>::galerkin(Galerkin::<2, 2>::gauss());
    let gauss3 = Constrained::<_, 1>::galerkin(Galerkin::<3, 3>::gauss());
    for (name, order, want) in [
        ("gauss s = 2", damped_order("gauss s = 2", gauss2, &[0.2, 0.1, 0.05]), 4.0),
        ("gauss s = 3", damped_order("gauss s = 3", gauss3, &[0.3, 0.2, 0.15, 0.1]), 6.0),
    ] {
        assert!((order - want).abs() < 0.15, "{name}: fitted order {order}, want {want}");
    }
}

#[test]
fn damped_driven_cartesian_pendulum_under_yoshida4_over_rattle_has_order_4() {
    let yoshida = Constrained::<_, 1>::composition(Composition::YOSHIDA4);
    let order = damped_order("yoshida 4", yoshida, &[0.1, 0.05, 0.025]);
    assert!((order - 4.0).abs() < 0.15, "fitted order {order}");
}

#[test]
fn damped_spherical_pendulum_under_galerkin_loses_angular_momentum_by_the_forces_impulse_alone() {
    // The interior and end constraint forces G(Q_m)ᵀΛ_m are along Q_m, with
    // no moment about z: J_{k+1} − J_k = Σ_m F^m·ξ(Q_m) over the step's nodes.
    impulse_balance(", gauss s = 2", Constrained::<_, 1>::galerkin(Galerkin::<2, 2>::gauss()), 0.05, 400);
}
