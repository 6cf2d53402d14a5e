//! Galerkin rules on forced and dissipative run-time-sized systems (the
//! discrete Lagrange–d'Alembert forces on the node equations, docs/theory.md
//! §6): the same states as the compile-time Galerkin, the fitted order `2s`
//! against the damped and the driven chain's analytic solutions, the
//! midpoint's energy balance for `s = 1`, momentum under internal forces,
//! and a force that is not finite.

use lagrangian::galerkin::StageIteration;
use lagrangian::prelude::*;

use super::run_time_forces::{Breaking, Damped, Driven, Forced, ForcedDyn, Internal, orders, shape};

/// The largest difference of `q` and `p` after `steps` steps of the damped
/// and driven chain under Galerkin degree `S`, at the compile-time size
/// (Newton, so that both solve the same equations) and at the run-time
/// size.
fn path_difference<const S: usize>(h: f64, steps: usize) -> f64 {
    let q0 = shape();
    let v0: [f64; 8] = core::array::from_fn(|i| 0.1 * (i as f64 - 3.5));
    let rule = Galerkin::<S, S>::gauss().with_iteration(StageIteration::Newton);
    let mut fixed = GalerkinIntegrator::new(Forced, rule, h).start(0.0, q0, v0).unwrap();
    let mut dynamic =
        Problem::new(ForcedDyn { n: 8 }, 0.0, q0.to_vec(), v0.to_vec()).stepper(&Scheme::galerkin(S), h).unwrap();
    fixed.run(steps, |_| {}).unwrap();
    dynamic.run(steps, |_| {}).unwrap();
    let (a, b) = (fixed.state(), dynamic.state());
    assert_eq!(a.t, b.t);
    // The motion is damped and driven: far from the start.
    assert!((a.q[0] - q0[0]).abs() > 1e-2, "s = {S}");
    (0..8).map(|i| (a.q[i] - b.q[i]).abs().max((a.p[i] - b.p[i]).abs())).fold(0.0, f64::max)
}

#[test]
fn a_forced_run_time_chain_takes_the_compile_time_galerkin_steps() {
    for (s, d) in [
        (1, path_difference::<1>(0.02, 300)),
        (2, path_difference::<2>(0.05, 300)),
        (3, path_difference::<3>(0.1, 300)),
    ] {
        println!("s = {s}: largest difference {d:.2e}");
        // The same equations; the force's derivatives and sums rounded
        // differently (lanes and a tape against duals over arrays).
        assert!(d < 1e-13, "s = {s}: {d:e}");
    }
}

/// The damped chain's third mode is the damped oscillator `a'' + γa' + a =
/// 0` (see `run_time_forces`): the state converges at order `2s`.
#[test]
fn a_damped_run_time_chain_converges_at_order_2s() {
    let gamma: f64 = 0.2;
    let s = shape();
    let omega = (1.0 - gamma * gamma / 4.0).sqrt();
    let t_end = 10.0;
    let decay = (-gamma * t_end / 2.0).exp();
    let a = decay * ((omega * t_end).cos() + gamma / (2.0 * omega) * (omega * t_end).sin());
    let problem = Problem::new(Damped { n: 8, gamma }, 0.0, s.to_vec(), vec![0.0; 8]);
    for (degree, steps) in [(2, [0.4, 0.2, 0.1]), (3, [1.0, 0.5, 0.25])] {
        let mut errors = Vec::new();
        for h in steps {
            let mut sim = problem.stepper(&Scheme::galerkin(degree), h).unwrap();
            sim.run_until(t_end).unwrap();
            let q = &sim.state().q;
            errors.push((0..8).map(|i| (q[i] - s[i] * a).abs()).fold(0.0, f64::max));
        }
        let expected = 2.0 * degree as f64;
        println!(
            "s = {degree}: errors {:?}, orders {:.2?}",
            errors.iter().map(|e| format!("{e:.2e}")).collect::<Vec<_>>(),
            orders(&errors)
        );
        for order in orders(&errors) {
            assert!((order - expected).abs() < 0.1, "s = {degree}: order {order} from {errors:?}");
        }
    }
}

/// The chain driven in its third mode stays on its periodic response (see
/// `run_time_forces`): the state converges at order `2s`.
#[test]
fn a_driven_run_time_chain_converges_at_order_2s() {
    let (gamma, amplitude, frequency): (f64, f64, f64) = (0.1, 0.5, 0.7);
    let d = (1.0 - frequency * frequency).powi(2) + (gamma * frequency).powi(2);
    let (a, b) = (amplitude * (1.0 - frequency * frequency) / d, amplitude * gamma * frequency / d);
    let response = |t: f64| a * (frequency * t).cos() + b * (frequency * t).sin();
    let s = shape();
    let system = Driven { shape: s.to_vec(), gamma, amplitude, frequency };
    let q0: Vec<f64> = s.iter().map(|x| x * a).collect();
    let v0: Vec<f64> = s.iter().map(|x| x * b * frequency).collect();
    let problem = Problem::new(system, 0.0, q0, v0);
    let t_end = 12.0;
    for (degree, steps) in [(2, [0.4, 0.2, 0.1]), (3, [1.0, 0.5, 0.25])] {
        let mut errors = Vec::new();
        for h in steps {
            let mut sim = problem.stepper(&Scheme::galerkin(degree), h).unwrap();
            sim.run_until(t_end).unwrap();
            let q = &sim.state().q;
            errors.push((0..8).map(|i| (q[i] - s[i] * response(t_end)).abs()).fold(0.0, f64::max));
        }
        let expected = 2.0 * degree as f64;
        println!(
            "s = {degree}: errors {:?}, orders {:.2?}",
            errors.iter().map(|e| format!("{e:.2e}")).collect::<Vec<_>>(),
            orders(&errors)
        );
        for order in orders(&errors) {
            assert!((order - expected).abs() < 0.1, "s = {degree}: order {order} from {errors:?}");
        }
    }
}

/// Degree 1 with one Gauss point is the midpoint rule, forces included
/// (`F^0 = F^1 = (h/2) F` at the midpoint): the same states as the
/// run-time midpoint, and the midpoint's discrete energy balance
/// `E_{k+1} − E_k = W_k = −(hγ/4) |v̂_{k−1} + v̂_k|²` at every node of a
/// linearly damped chain.
#[test]
fn degree_one_balances_the_energy_of_a_damped_run_time_chain_as_the_midpoint_does() {
    let (n, gamma, h) = (8, 0.2, 0.05);
    let problem = Problem::new(Damped { n, gamma }, 0.0, shape().to_vec(), vec![0.0; 8]);
    let mut sim = problem.stepper(&Scheme::galerkin(1), h).unwrap();
    let mut midpoint = problem.stepper(&Scheme::MIDPOINT, h).unwrap();
    let (mut q, mut e) = (vec![sim.state().q.clone()], vec![sim.discrete_energy()]);
    let mut gap = 0.0f64;
    for _ in 0..200 {
        sim.step().unwrap();
        midpoint.step().unwrap();
        let (a, b) = (sim.state(), midpoint.state());
        gap = (0..n).map(|i| (a.q[i] - b.q[i]).abs().max((a.p[i] - b.p[i]).abs())).fold(gap, f64::max);
        q.push(a.q.clone());
        e.push(sim.discrete_energy());
    }
    assert!(gap < 1e-14, "against the midpoint rule: {gap:e}");
    let mut largest = 0.0f64;
    for k in 1..200 {
        let work: f64 = (0..n)
            .map(|i| {
                let sum = (q[k][i] - q[k - 1][i]) / h + (q[k + 1][i] - q[k][i]) / h;
                -(h * gamma / 4.0) * sum * sum
            })
            .sum();
        largest = largest.max((e[k + 1] - e[k] - work).abs());
    }
    println!("against the midpoint {gap:.1e}, largest residual of the balance {largest:.1e}");
    assert!(largest < 1e-13, "largest residual of the balance {largest:e}");
    assert!(e[200] < 0.5 * e[1], "{} against {}", e[200], e[1]);
}

#[test]
fn internal_forces_conserve_the_momentum_of_a_run_time_galerkin_chain() {
    let n = 16;
    let q0: Vec<f64> = (0..n).map(|i| 0.3 * (0.9 * i as f64).sin()).collect();
    let v0: Vec<f64> = (0..n).map(|i| 0.5 + 0.4 * (1.7 * i as f64).cos()).collect();
    let problem = Problem::new(Internal { n }, 0.0, q0, v0.clone());
    let total: f64 = v0.iter().sum();
    for degree in [1, 2, 3] {
        let mut sim = problem.stepper(&Scheme::galerkin(degree), 0.05).unwrap();
        sim.run(400, |_| {}).unwrap();
        let p: f64 = sim.momenta().iter().sum();
        println!("s = {degree}: Σp − Σp_0 = {:.1e}", p - total);
        // 400 steps of sums of 16 terms of order 1.
        assert!((p - total).abs() < 1e-12, "s = {degree}: Σp {p} against {total}");
        let v = sim.velocity().unwrap();
        let spread = v.iter().map(|x| (x - total / n as f64).abs()).fold(0.0, f64::max);
        assert!(spread < 0.4, "s = {degree}: spread {spread}");
    }
}

#[test]
fn a_force_that_is_not_finite_stops_a_galerkin_step_and_changes_nothing() {
    let bits = |s: &PhasePoint| {
        let mut b: Vec<u64> = s.q.iter().chain(&s.p).map(|x| x.to_bits()).collect();
        b.extend([s.t.to_bits(), s.step]);
        b
    };
    for degree in [1, 2, 3] {
        let problem = Problem::new(Breaking, 0.0, vec![0.0, 0.0], vec![1.0, 0.0]);
        let mut sim = problem.stepper(&Scheme::galerkin(degree), 0.05).unwrap();
        let (before, error) = loop {
            let before = sim.clone();
            match sim.step() {
                Ok(_) => assert!(sim.state().t < 2.0, "s = {degree}: never failed"),
                Err(error) => break (before, error),
            }
        };
        match &error {
            lagrangian::Error::NonFinite { state, quantity, .. } => {
                assert_eq!(*quantity, "force", "s = {degree}");
                assert_eq!(state, before.state(), "s = {degree}: the error carries the state the step started from");
            }
            other => panic!("s = {degree}: {other:?}"),
        }
        assert_eq!(bits(sim.state()), bits(before.state()), "s = {degree}: the stepper is unchanged");
        let again = sim.step().unwrap_err();
        assert_eq!(format!("{again:?}"), format!("{error:?}"), "s = {degree}");
    }
}
