//! Symmetric compositions of constrained trapezoid steps (RATTLE): the
//! orders of the compositions on the Cartesian pendulum and double
//! pendulum, with the constraints held at every node.

use lagrangian::prelude::*;

use super::{DoublePendulum, Pendulum, double_pendulum_rhs, fitted_order, rk4};

/// The pendulum from `θ₀ = 1` at rest to `t = 2`: the error at the end
/// against the exact motion, and the largest `|g|` and `|G v|` over the run.
fn pendulum_errors(composition: Composition, h: f64) -> (f64, f64, f64) {
    let [theta, _] = rk4(|y| [y[1], -y[0].sin()], [1.0, 0.0], 2.0, 20_000);
    let exact = [theta.sin(), -theta.cos()];
    let q0 = [1f64.sin(), -1f64.cos()];
    let method = Constrained::<_, 1>::composition(composition);
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

#[test]
fn compositions_of_rattle_reach_their_orders_on_the_cartesian_pendulum() {
    let mut fitted = Vec::new();
    for (name, composition, hs) in [
        ("yoshida 4", Composition::YOSHIDA4, [0.1, 0.05, 0.025]),
        ("yoshida 6", Composition::YOSHIDA6, [0.2, 0.1, 0.05]),
    ] {
        let mut errors = Vec::new();
        for h in hs {
            let (e, g, gv) = pendulum_errors(composition, h);
            assert!(g <= 4e-15 && gv <= 4e-15, "{name}, h = {h}: max |g| = {g:e}, max |G v| = {gv:e}");
            errors.push(e);
        }
        let order = fitted_order(&hs, &errors);
        println!("pendulum, {name}: errors {errors:?}, fitted order {order:.3}");
        fitted.push((name, order, composition.order()));
    }
    for (name, order, want) in fitted {
        assert!((order - want as f64).abs() < 0.15, "{name}: fitted order {order}, want {want}");
    }
}

#[test]
fn yoshida4_over_rattle_matches_the_minimal_double_pendulum_at_order_4() {
    let (a0, b0) = (0.8f64, -0.4f64);
    let [a, b, ..] = rk4(double_pendulum_rhs, [a0, b0, 0.0, 0.0], 1.0, 20_000);
    let exact = [a.sin(), -a.cos(), a.sin() + b.sin(), -a.cos() - b.cos()];
    let q0 = [a0.sin(), -a0.cos(), a0.sin() + b0.sin(), -a0.cos() - b0.cos()];
    let hs = [0.05, 0.025, 0.0125];
    let mut errors = Vec::new();
    for h in hs {
        let method = Constrained::<_, 2>::composition(Composition::YOSHIDA4);
        let mut sim = Integrator::new(DoublePendulum, method, h).start(0.0, q0, [0.0; 4]).unwrap();
        let mut g = 0.0f64;
        sim.run_until(1.0, |s| g = s.constraint_values().iter().fold(g, |m, x| m.max(x.abs()))).unwrap();
        assert!(g <= 1e-14, "h = {h}: max |g| = {g:e}");
        errors.push((0..4).map(|i| (sim.state().q[i] - exact[i]).abs()).fold(0.0, f64::max));
    }
    let order = fitted_order(&hs, &errors);
    println!("double pendulum, yoshida 4 over RATTLE: errors {errors:?}, fitted order {order:.3}");
    assert!((order - 4.0).abs() < 0.15, "fitted order {order}, errors {errors:?}");
}

#[test]
fn a_failed_composed_step_keeps_the_state() {
    let q0 = [1f64.sin(), -1f64.cos()];
    let options = NewtonOptions { max_iterations: 1, ..NewtonOptions::default() };
    let method = Constrained::<_, 1>::composition(Composition::YOSHIDA4);
    let mut sim = Integrator::new(Pendulum, method, 0.1).newton(options).start(0.0, q0, [0.0; 2]).unwrap();
    let before = sim.clone();
    assert!(matches!(sim.step(), Err(Error::NewtonDidNotConverge { .. })));
    assert_eq!(format!("{:?}", sim.state()), format!("{:?}", before.state()));
    assert_eq!(sim.multipliers(), before.multipliers());
    assert_eq!(sim.stats().failed_steps, 1);
    let energy =
        Integrator::new(Pendulum, method, 0.01).energy_preserving(StepBounds::around(0.01)).start(0.0, q0, [0.0; 2]);
    assert!(matches!(energy, Err(Error::Unsupported { .. })), "{energy:?}");
}

#[test]
fn yoshida6_over_rattle_passes_turning_points_with_bounded_energy() {
    // 4000 steps (about 30 swings, each through two turning points, where
    // |v| passes far below |p̂| within a sub-step).
    let q0 = [1f64.sin(), -1f64.cos()];
    let method = Constrained::<_, 1>::composition(Composition::YOSHIDA6);
    let mut sim = Integrator::new(Pendulum, method, 0.05).start(0.0, q0, [0.0; 2]).unwrap();
    let e0 = sim.energy().unwrap();
    let (mut g, mut de) = (0.0f64, 0.0f64);
    sim.run(4000, |s| {
        g = g.max(s.constraint_values()[0].abs());
        de = de.max((s.energy().unwrap() - e0).abs());
    })
    .unwrap();
    println!("pendulum, yoshida 6, 4000 steps of 0.05: max |g| {g:.2e}, max energy error {de:.2e}");
    assert!(g <= 4e-15, "max |g| = {g:e}");
    // Measured 3.6e-10 (max |g| 4.4e-16).
    assert!(de < 4e-9, "max energy error {de:e}");
}
