//! Galerkin rules with the constraints imposed at their control nodes:
//! orders against the exact motion (minimal coordinates), the constraints
//! and their hidden form at every node, and a failed step that keeps the
//! state.

use lagrangian::DenseKind;
use lagrangian::galerkin::{Galerkin, NodeFamily, Quadrature};
use lagrangian::prelude::*;

use super::{DoublePendulum, Pendulum, double_pendulum_rhs, fitted_order, rk4};

/// Degree `S` on Gauss–Lobatto nodes with `R` Lobatto points.
fn lobatto<const S: usize, const R: usize>() -> Galerkin<S, R> {
    Galerkin::new(NodeFamily::GaussLobatto, Quadrature::gauss_lobatto())
}

/// The pendulum from `θ₀ = 1` at rest to `t = 2` under `rule`: the error
/// at the end against the exact motion, the largest `|g|` and `|G v|`.
fn pendulum_errors<const S: usize, const R: usize>(rule: Galerkin<S, R>, h: f64) -> (f64, f64, f64) {
    let [theta, _] = rk4(|y| [y[1], -y[0].sin()], [1.0, 0.0], 2.0, 20_000);
    let exact = [theta.sin(), -theta.cos()];
    let q0 = [1f64.sin(), -1f64.cos()];
    let method = Constrained::<_, 1>::galerkin(rule);
    let mut sim = Integrator::new(Pendulum, method, h).start(0.0, q0, [0.0; 2]).unwrap();
    let (mut g, mut gv) = (0.0f64, 0.0f64);
    sim.run_until(2.0, |s| {
        g = g.max(s.constraint_values()[0].abs());
        gv = gv.max(s.constraint_velocities().unwrap()[0].abs());
    })
    .unwrap();
    let q = sim.state().q;
    ((q[0] - exact[0]).abs().max((q[1] - exact[1]).abs()), g, gv)
}

fn pendulum_order<const S: usize, const R: usize>(name: &str, rule: Galerkin<S, R>, hs: &[f64]) -> f64 {
    let mut errors = Vec::new();
    for &h in hs {
        let (e, g, gv) = pendulum_errors(rule, h);
        assert!(g <= 4e-15 && gv <= 4e-15, "{name}, h = {h}: max |g| = {g:e}, max |G v| = {gv:e}");
        errors.push(e);
    }
    let order = fitted_order(hs, &errors);
    println!("pendulum, {name}: errors {errors:?}, fitted order {order:.3}");
    order
}

#[test]
fn cartesian_pendulum_orders() {
    // Measured 2.008, 3.996, 6.000 (Lobatto s = 1, 2, 3) and 3.996, 6.002
    // (Gauss s = 2, 3); errors from 7e-3 down to 3e-12.
    let hs = [0.2, 0.1, 0.05];
    for (name, order, want) in [
        ("lobatto s = 1 (RATTLE trapezoid)", pendulum_order("lobatto s = 1", lobatto::<1, 2>(), &hs), 2.0),
        ("lobatto s = 2", pendulum_order("lobatto s = 2", lobatto::<2, 3>(), &hs), 4.0),
        ("lobatto s = 3", pendulum_order("lobatto s = 3", lobatto::<3, 4>(), &hs), 6.0),
        ("gauss s = 2", pendulum_order("gauss s = 2", Galerkin::<2, 2>::gauss(), &hs), 4.0),
        ("gauss s = 3", pendulum_order("gauss s = 3", Galerkin::<3, 3>::gauss(), &hs), 6.0),
    ] {
        assert!((order - want).abs() < 0.1, "{name}: fitted order {order}, want {want}");
    }
}

/// A bead on the unit circle in the potential `y + 0.3 x³`: not a
/// polynomial of low degree along the step, so Gauss and Lobatto
/// quadratures give different actions.
#[derive(Clone, Debug)]
struct Bead;

#[lagrangian]
impl Bead {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) - q[1] - 0.3 * q[0] * q[0] * q[0]
    }
    fn constraints(&self, q: [f64; 2]) -> [f64; 1] {
        [q[0] * q[0] + q[1] * q[1] - 1.0]
    }
}

fn bead_order<const S: usize, const R: usize>(name: &str, rule: Galerkin<S, R>, hs: &[f64]) -> f64 {
    // x = sin θ, y = −cos θ: V(θ) = −cos θ + 0.3 sin³θ.
    let [theta, _] = rk4(|y| [y[1], -y[0].sin() - 0.9 * y[0].sin().powi(2) * y[0].cos()], [1.2, 0.0], 2.0, 20_000);
    let exact = [theta.sin(), -theta.cos()];
    let q0 = [1.2f64.sin(), -1.2f64.cos()];
    let mut errors = Vec::new();
    for &h in hs {
        let mut sim = Integrator::new(Bead, Constrained::<_, 1>::galerkin(rule), h).start(0.0, q0, [0.0; 2]).unwrap();
        let mut g = 0.0f64;
        sim.run_until(2.0, |s| g = g.max(s.constraint_values()[0].abs())).unwrap();
        assert!(g <= 4e-15, "{name}, h = {h}: max |g| = {g:e}");
        let q = sim.state().q;
        errors.push((q[0] - exact[0]).abs().max((q[1] - exact[1]).abs()));
    }
    let order = fitted_order(hs, &errors);
    println!("bead, {name}: errors {errors:?}, fitted order {order:.3}");
    order
}

#[test]
fn bead_in_a_cubic_potential_orders() {
    // The pendulum's potential is linear and its kinetic energy quadratic:
    // both quadratures integrate its action exactly, so they agree there.
    // Here they do not (the errors differ by 0.3 % to 7 %), and both keep
    // order 2s: measured 4.003, 5.991 (Lobatto) and 4.000, 5.999 (Gauss).
    let hs = [0.2, 0.1, 0.05];
    for (name, order, want) in [
        ("lobatto s = 2", bead_order("lobatto s = 2", lobatto::<2, 3>(), &hs), 4.0),
        ("lobatto s = 3", bead_order("lobatto s = 3", lobatto::<3, 4>(), &hs), 6.0),
        ("gauss s = 2", bead_order("gauss s = 2", Galerkin::<2, 2>::gauss(), &hs), 4.0),
        ("gauss s = 3", bead_order("gauss s = 3", Galerkin::<3, 3>::gauss(), &hs), 6.0),
    ] {
        assert!((order - want).abs() < 0.1, "{name}: fitted order {order}, want {want}");
    }
}

/// The Cartesian double pendulum under `rule` to `t = 1`: the largest
/// coordinate error against the minimal-coordinate motion, and the largest
/// `|g|` and `|G v|` over the run.
fn double_pendulum_errors<const S: usize, const R: usize>(rule: Galerkin<S, R>, h: f64) -> (f64, f64, f64) {
    let (a0, b0) = (0.8f64, -0.4f64);
    let [a, b, ..] = rk4(double_pendulum_rhs, [a0, b0, 0.0, 0.0], 1.0, 20_000);
    let exact = [a.sin(), -a.cos(), a.sin() + b.sin(), -a.cos() - b.cos()];
    let q0 = [a0.sin(), -a0.cos(), a0.sin() + b0.sin(), -a0.cos() - b0.cos()];
    let mut sim =
        Integrator::new(DoublePendulum, Constrained::<_, 2>::galerkin(rule), h).start(0.0, q0, [0.0; 4]).unwrap();
    let (mut g, mut gv) = (0.0f64, 0.0f64);
    sim.run_until(1.0, |s| {
        g = s.constraint_values().iter().fold(g, |m, x| m.max(x.abs()));
        gv = s.constraint_velocities().unwrap().iter().fold(gv, |m, x| m.max(x.abs()));
    })
    .unwrap();
    let error = (0..4).map(|i| (sim.state().q[i] - exact[i]).abs()).fold(0.0, f64::max);
    (error, g, gv)
}

#[test]
fn cartesian_double_pendulum_matches_minimal_coordinates_at_order_2s() {
    let hs = [0.1, 0.05, 0.025];
    let mut orders = Vec::new();
    for s in [2, 3] {
        let mut errors = Vec::new();
        for &h in &hs {
            let (e, g, gv) = match s {
                2 => double_pendulum_errors(Galerkin::<2, 2>::gauss(), h),
                _ => double_pendulum_errors(Galerkin::<3, 3>::gauss(), h),
            };
            // The velocities reach about 3: |G v| is relative to that.
            assert!(g <= 1e-14 && gv <= 1e-14, "s = {s}, h = {h}: max |g| = {g:e}, max |G v| = {gv:e}");
            errors.push(e);
        }
        let order = fitted_order(&hs, &errors);
        println!("double pendulum, gauss s = {s}: errors {errors:?}, fitted order {order:.3}");
        orders.push((s, order));
    }
    for (s, order) in orders {
        assert!((order - 2.0 * s as f64).abs() < 0.15, "s = {s}: fitted order {order}");
    }
}

#[test]
fn a_failed_galerkin_step_keeps_the_state_and_bad_input_is_typed() {
    let q0 = [1f64.sin(), -1f64.cos()];
    let method = Constrained::<_, 1>::galerkin(Galerkin::<2, 2>::gauss());
    let options = NewtonOptions { max_iterations: 1, ..NewtonOptions::default() };
    let mut one = Integrator::new(Pendulum, method, 0.1).newton(options).start(0.0, q0, [0.0; 2]).unwrap();
    assert!(matches!(one.step(), Err(Error::NewtonDidNotConverge { .. })));
    assert_eq!(one.state().q, q0);

    // Inconsistent initial data, a wrong count: refused.
    let off = Integrator::new(Pendulum, method, 0.01).start(0.0, [0.8, -0.7], [0.0; 2]);
    assert!(matches!(off, Err(Error::InconsistentConstraints { .. })), "{off:?}");
    let wrong = Integrator::new(Pendulum, Constrained::<_, 2>::galerkin(Galerkin::<2, 2>::gauss()), 0.01)
        .start(0.0, q0, [0.0; 2]);
    assert!(matches!(wrong, Err(Error::Unsupported { .. })), "{wrong:?}");
}

#[test]
fn nan_constraints_fail_a_galerkin_step_typed() {
    let method = Constrained::<_, 1>::galerkin(Galerkin::<2, 2>::gauss());
    // From the bottom with enough speed to swing past y = 0.5, where g is NaN.
    let mut sim = Integrator::new(super::Undefined, method, 0.05).start(0.0, [0.0, -1.0], [2.5, 0.0]).unwrap();
    let (error, before) = loop {
        let before = sim.clone();
        if let Err(error) = sim.step() {
            break (error, before);
        }
        assert!(sim.state().q[1] < 0.5);
    };
    assert!(matches!(error, Error::NonFiniteConstraints { .. }), "{error:?}");
    assert_eq!(format!("{:?}", sim.state()), format!("{:?}", before.state()));
    assert_eq!(sim.multipliers(), before.multipliers());
    // A shorter step after the failure is the one a run without it takes, bit for bit.
    let mut reference = before;
    for it in [&mut sim, &mut reference] {
        it.set_step_size(0.001).unwrap();
        it.step().unwrap();
    }
    assert_eq!(format!("{:?}", sim.state()), format!("{:?}", reference.state()));
    assert_eq!(sim.multipliers(), reference.multipliers());
}

#[test]
fn solve_gives_dense_output_of_a_constrained_galerkin_run() {
    let q0 = [1f64.sin(), -1f64.cos()];
    let method = Constrained::<_, 1>::galerkin(Galerkin::<3, 3>::gauss());
    let mut sim = Integrator::new(Pendulum, method, 0.05).start(0.0, q0, [0.0; 2]).unwrap();
    let times: Vec<f64> = (0..40).map(|k| 0.0125 + 0.025 * k as f64).collect();
    let solution = sim.solve(Plan::until(1.0).every(0).save_at(times).dense(DenseKind::Native)).unwrap();
    assert!(solution.is_finished() && solution.len() == 40, "{:?}", solution.status);
    // The cubic Hermite interpolant leaves the circle between nodes by O(h⁴).
    let off = solution.q.iter().map(|q| (q[0] * q[0] + q[1] * q[1] - 1.0).abs()).fold(0.0, f64::max);
    assert!(off < 1e-5, "{off:e}");
    let [x, y] = sim.state().q;
    assert!((x * x + y * y - 1.0).abs() < 4e-15);
}

#[test]
fn a_galerkin_step_across_a_singular_configuration_fails_typed_with_the_state_kept() {
    let method = Constrained::<_, 1>::galerkin(Galerkin::<2, 2>::gauss());
    // Along the line y = x towards the crossing of x² − y² = 0 at the
    // origin, where G = 0; h = 0.03 does not land on it.
    let mut sim = Integrator::new(super::Crossing, method, 0.03).start(0.0, [-1.0, -1.0], [1.0, 1.0]).unwrap();
    let error = loop {
        let before = sim.clone();
        match sim.step() {
            Ok(_) => assert!(sim.state().t < 1.1, "passed the crossing at t = {}", sim.state().t),
            Err(error) => {
                assert_eq!(format!("{:?}", sim.state()), format!("{:?}", before.state()));
                assert_eq!(sim.multipliers(), before.multipliers());
                break error;
            }
        }
    };
    assert!(matches!(error, Error::SingularConstraints { .. }), "{error:?}");
}

#[test]
fn spherical_pendulum_keeps_its_vertical_angular_momentum_under_galerkin() {
    // The action and the constraint are invariant under rotations about z:
    // the discrete Noether theorem on the manifold holds at every node.
    let (q0, v0) = ([0.6, 0.0, -0.8], [0.0, 1.1, 0.0]);
    let method = Constrained::<_, 1>::galerkin(Galerkin::<2, 2>::gauss());
    let mut sim = Integrator::new(super::Spherical, method, 0.05).start(0.0, q0, v0).unwrap();
    let lz = |s: &State<3>| s.q[0] * s.p[1] - s.q[1] * s.p[0];
    let l0 = lz(sim.state());
    let (mut drift, mut g) = (0.0f64, 0.0f64);
    sim.run(5000, |s| {
        drift = drift.max((lz(s.state()) - l0).abs() / l0.abs());
        g = g.max(s.constraint_values()[0].abs());
    })
    .unwrap();
    println!("spherical pendulum, gauss s = 2, 5000 steps: L_z drift {drift:.2e}, max |g| {g:.2e}");
    assert!(drift < 1e-13 && g <= 4e-15, "relative drift of L_z {drift:e}, max |g| {g:e}");
}

/// The four-bar under Gauss s = 2 for `n` steps of 0.02: the largest `|g|`,
/// the largest `|G v| / |v|`, and the largest energy errors of the two halves.
fn four_bar_galerkin_run(n: usize) -> (f64, f64, f64, f64) {
    let (q0, v0) = super::four_bar_initial();
    let method = Constrained::<_, 3>::galerkin(Galerkin::<2, 2>::gauss());
    let mut sim = Integrator::new(super::FourBar, method, 0.02).start(0.0, q0, v0).unwrap();
    let e0 = sim.energy().unwrap();
    let speed = v0.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let (mut g, mut gv) = (0.0f64, 0.0f64);
    let mut energy = Vec::with_capacity(n);
    sim.run(n, |s| {
        g = s.constraint_values().iter().fold(g, |m, x| m.max(x.abs()));
        gv = s.constraint_velocities().unwrap().iter().fold(gv, |m, x| m.max(x.abs() / speed));
        energy.push(s.energy().unwrap() - e0);
    })
    .unwrap();
    let half = energy.len() / 2;
    let first = energy[..half].iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let second = energy[half..].iter().fold(0.0f64, |m, x| m.max(x.abs()));
    println!(
        "four-bar, gauss s = 2, {n} steps of 0.02: max |g| {g:.2e}, max |G v|/|v| {gv:.2e}, energy error {first:.2e} then {second:.2e}"
    );
    (g, gv, first, second)
}

#[test]
fn four_bar_under_galerkin_holds_its_constraints_and_energy() {
    let (g, gv, first, second) = four_bar_galerkin_run(5000);
    assert!(g <= 1e-12 && gv <= 1e-12, "max |g| = {g:e}, max |G v| / |v| = {gv:e}");
    assert!(second < 1.5 * first, "energy error grows: {first:e} then {second:e}");
}

/// The long run: `cargo test --release --test constraints -- --ignored four_bar_under_galerkin`.
#[test]
#[ignore = "1e6 steps; run with --ignored"]
fn four_bar_under_galerkin_over_1e6_steps() {
    let (g, gv, first, second) = four_bar_galerkin_run(1_000_000);
    assert!(g <= 1e-12 && gv <= 1e-12, "max |g| = {g:e}, max |G v| / |v| = {gv:e}");
    assert!(second < 1.5 * first, "energy error grows: {first:e} then {second:e}");
}

/// A damped pendulum on a circle whose support rises at a constant speed:
/// dissipation and a moving constraint at once.
struct Moving {
    damping: f64,
    speed: f64,
}

#[lagrangian]
impl Moving {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) - q[1]
    }

    fn dissipation(&self, _q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * self.damping * (v[0] * v[0] + v[1] * v[1])
    }

    fn constraints(&self, t: f64, q: [f64; 2]) -> [f64; 1] {
        let dy = q[1] - self.speed * t;
        [q[0] * q[0] + dy * dy - 1.0]
    }
}

/// The damped pendulum on the rising support to `t = 2` under `method`,
/// from rest relative to the support: the end position and the largest
/// `|g(t, q)|` and `|G v + ∂g/∂t|` over the nodes (unit mass: `v = p`).
fn moving_run<M: Method<f64>>(method: M, h: f64) -> ([f64; 2], f64, f64) {
    let (damping, speed) = (0.3, 0.2);
    let (q0, v0) = ([0.6, -0.8], [0.0, speed]);
    let mut sim = Integrator::new(Moving { damping, speed }, method, h).start(0.0, q0, v0).unwrap();
    let (mut g, mut gv) = (0.0f64, 0.0f64);
    sim.run_until(2.0, |s| {
        let State { t, q, p, .. } = *s.state();
        let dy = q[1] - speed * t;
        g = g.max((q[0] * q[0] + dy * dy - 1.0).abs());
        gv = gv.max((2.0 * q[0] * p[0] + 2.0 * dy * (p[1] - speed)).abs());
    })
    .unwrap();
    (sim.state().q, g, gv)
}

/// The Galerkin and composition families carry dissipation and a moving
/// constraint at once: two fourth-order methods of different construction
/// (Gauss collocation through the nodes, Yoshida's composition of RATTLE
/// trapezoid steps) agree to their error, on the moving circle at every node.
#[test]
fn galerkin_and_compositions_carry_dissipation_on_a_moving_circle() {
    let gauss = moving_run(Constrained::<_, 1>::galerkin(Galerkin::<2, 2>::gauss()), 0.02);
    let yoshida = moving_run(Constrained::<_, 1>::composition(Composition::YOSHIDA4), 0.02);
    let apart = (gauss.0[0] - yoshida.0[0]).abs().max((gauss.0[1] - yoshida.0[1]).abs());
    println!("damped pendulum on a rising support: gauss s = 2 and yoshida 4 apart by {apart:.1e}");
    // Measured 2.0e-8 apart: the composition's error (its constant is the
    // larger; 6e-8 on the damped, driven pendulum to t = 3 at this step).
    assert!(apart < 1e-7, "gauss s = 2 and yoshida 4 apart by {apart:e}");
    for (name, (_, g, gv)) in [("gauss s = 2", gauss), ("yoshida 4", yoshida)] {
        assert!(g <= 2e-15 && gv <= 4e-15, "{name}: max |g| = {g:e}, max |G v + g_t| = {gv:e}");
    }
}
