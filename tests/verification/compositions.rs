//! Verification: the symmetric compositions of the trapezoid rule
//! (`Composition::YOSHIDA4`, `YOSHIDA6`, `KAHAN_LI8`) through the one
//! `Integrator`: fitted orders 4, 6, 8 (± 0.15), symplecticity of the
//! composed map at round-off, explicit sub-steps (no Newton) on a separable
//! system with constant mass, and Newton sub-steps on the double pendulum
//! (position-dependent mass) at the same order.
use crate::common;

use common::{DOUBLE_PENDULUM, DoublePendulum, fitted_order};
use lagrangian::prelude::*;
use lagrangian::{Composition, symplectic};

/// `L = ½ v² + g cos q`: proven separable with constant mass.
pub struct Pendulum;

#[lagrangian]
impl Pendulum {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] + 9.81 * q[0].cos()
    }
}

/// The pendulum at `t = T` by a fine Kahan–Li run (its own error far below the fits' windows).
fn reference(t_end: f64) -> f64 {
    let n = 4096;
    let mut sim = Integrator::new(Pendulum, Composition::KAHAN_LI8, t_end / n as f64).start(0.0, [1.0], [0.0]).unwrap();
    sim.run_until(t_end, |_| {}).unwrap();
    sim.state().q[0]
}

fn order_of(method: Composition, steps: &[usize], t_end: f64, exact: f64) -> (f64, Vec<f64>) {
    let h: Vec<f64> = steps.iter().map(|&n| t_end / n as f64).collect();
    let err: Vec<f64> = steps
        .iter()
        .map(|&n| {
            let mut sim = Integrator::new(Pendulum, method, t_end / n as f64).start(0.0, [1.0], [0.0]).unwrap();
            sim.run(n, |_| {}).unwrap();
            assert_eq!(sim.stats().newton_iterations, 0, "explicit sub-steps");
            (sim.state().q[0] - exact).abs()
        })
        .collect();
    (fitted_order(&h, &err), err)
}

#[test]
fn compositions_have_orders_4_6_8() {
    let t_end = 5.0;
    let exact = reference(t_end);
    for (name, method, steps) in [
        ("Yoshida 4", Composition::YOSHIDA4, [100, 141, 200, 283, 400]),
        ("Yoshida 6", Composition::YOSHIDA6, [50, 71, 100, 141, 200]),
        ("Kahan–Li 8", Composition::KAHAN_LI8, [60, 71, 85, 101, 120]),
    ] {
        let (order, err) = order_of(method, &steps, t_end, exact);
        println!("{name}: fitted order {order:.3}, errors {:.2e} … {:.2e}", err[0], err[4]);
        let want = method.order() as f64;
        assert!((order - want).abs() <= 0.15, "{name}: fitted order {order:.3}, want {want}; errors {err:?}");
        assert!(err[4] > 1e-13, "{name}: smallest error {:e} at round-off", err[4]);
    }
}

#[test]
fn composed_maps_are_symplectic_to_round_off() {
    for (name, method) in [
        ("Yoshida 4", Composition::YOSHIDA4),
        ("Yoshida 6", Composition::YOSHIDA6),
        ("Kahan–Li 8", Composition::KAHAN_LI8),
    ] {
        let mut sim = Integrator::new(Pendulum, method, 0.2).start(0.0, [1.0], [0.3]).unwrap();
        sim.run(50, |_| {}).unwrap();
        let map = sim.last_tangent_map().unwrap();
        let defect = symplectic::defect(&map.matrix()).unwrap();
        println!("{name}: symplecticity defect {defect:.1e}");
        assert!(defect < 1e-13, "{name}: defect {defect:e}");
    }
}

/// On the double pendulum (mass matrix depends on q) the sub-steps are
/// implicit trapezoid steps solved by Newton; the composition keeps order 4.
#[test]
fn yoshida4_with_newton_sub_steps_on_the_double_pendulum() {
    let t_end = 1.0;
    let run = |n: usize, method: Composition| {
        let mut sim = Integrator::new(DoublePendulum { ..DOUBLE_PENDULUM }, method, t_end / n as f64)
            .start(0.0, [1.0, -0.5], [0.0, 0.5])
            .unwrap();
        sim.run(n, |_| {}).unwrap();
        assert!(sim.stats().newton_iterations > 0);
        sim.state().q
    };
    let exact = run(1000, Composition::KAHAN_LI8);
    let steps = [80, 113, 160, 226, 320];
    let h: Vec<f64> = steps.iter().map(|&n| t_end / n as f64).collect();
    let err: Vec<f64> = steps
        .iter()
        .map(|&n| {
            let q = run(n, Composition::YOSHIDA4);
            (q[0] - exact[0]).abs().max((q[1] - exact[1]).abs())
        })
        .collect();
    let order = fitted_order(&h, &err);
    println!("Yoshida 4, double pendulum (Newton sub-steps): fitted order {order:.3}, errors {err:?}");
    assert!((order - 4.0).abs() <= 0.15, "order {order}, errors {err:?}");
}

#[test]
fn compositions_refuse_energy_steps() {
    let err = Integrator::new(Pendulum, Composition::YOSHIDA4, 0.1).energy_preserving(StepBounds::around(0.1)).start(
        0.0,
        [1.0],
        [0.0],
    );
    assert!(matches!(err, Err(Error::Unsupported { .. })), "{:?}", err.map(|_| ()));
}
