//! Verification: forces and dissipation (docs/theory.md §6, Fu, Dai & Tang). Order of the
//! forced integrators against analytic solutions, the discrete energy
//! balance, Fu, Dai & Tang's electromechanical sensor and its first integral, and
//! what bad forces do.
use crate::common;

use common::forced::*;
use common::*;
use lagrangian::forcing::{self, EnergyBalance};
use lagrangian::prelude::*;
use lagrangian::{Segment, StepBounds};

/// Fixed-step run to `t_end`, returning the integrator.
fn run_to<S: Lagrangian<N>, M: DiscreteLagrangian, const N: usize>(
    system: S,
    method: M,
    h: f64,
    q0: [f64; N],
    v0: [f64; N],
    t_end: f64,
) -> Integrator<S, M, N> {
    let mut sim = Integrator::new(system, method, h).start(0.0, q0, v0).unwrap();
    let n = (t_end / h).round() as usize;
    sim.run(n, |_| {}).unwrap();
    assert!((sim.state().t - t_end).abs() < 1e-9);
    sim
}

const STEPS: [f64; 5] = [0.08, 0.04, 0.02, 0.01, 0.005];

fn orders<M: DiscreteLagrangian>(method: M, err: fn(M, f64) -> f64) -> f64 {
    let errors: Vec<f64> = STEPS.iter().map(|&h| err(method, h)).collect();
    fitted_order(&STEPS, &errors)
}

fn damped() -> DampedOscillator {
    DampedOscillator { m: 1.0, k: 4.0, c: 0.5 }
}

fn rlc() -> Rlc {
    Rlc { l: 0.5, r: 1.5, c: 0.02, e0: 10.0, omega: 7.0 }
}

/// Relative error in position and momentum (`p = m q̇`) at `t = 4` against
/// the exact damped oscillation.
fn damped_error<M: DiscreteLagrangian>(method: M, h: f64) -> f64 {
    let t_end = 4.0;
    let sim = run_to(damped(), method, h, [1.0], [0.0], t_end);
    let s = sim.state();
    rel_err(&[s.q[0], s.p[0] / damped().m], &damped().exact(1.0, t_end))
}

/// Relative error in charge and current at `t = 4` against the exact
/// driven RLC response; the current from the discrete momentum, `i = p/ℓ`.
fn rlc_error<M: DiscreteLagrangian>(method: M, h: f64) -> f64 {
    let t_end = 4.0;
    let sim = run_to(rlc(), method, h, [0.0], [0.0], t_end);
    let s = sim.state();
    rel_err(&[s.q[0], s.p[0] / rlc().l], &rlc().exact(t_end))
}

#[test]
fn damped_oscillator_converges_with_order_2() {
    let midpoint = orders(Midpoint, damped_error);
    let trapezoid = orders(Trapezoid, damped_error);
    // α = 1 puts the whole impulse on q_k: first order, which the fit must see.
    let euler = orders(AlphaBeta::EULER_A, damped_error);
    eprintln!("damped oscillator: orders midpoint {midpoint:.3}, trapezoid {trapezoid:.3}, α=1 {euler:.3}");
    assert!((midpoint - 2.0).abs() < 0.1, "midpoint order {midpoint}");
    assert!((trapezoid - 2.0).abs() < 0.1, "trapezoid order {trapezoid}");
    assert!((euler - 1.0).abs() < 0.1, "α = 1 order {euler}");
}

#[test]
fn driven_rlc_circuit_converges_with_order_2() {
    let midpoint = orders(Midpoint, rlc_error);
    let trapezoid = orders(Trapezoid, rlc_error);
    eprintln!("rlc: orders midpoint {midpoint:.3}, trapezoid {trapezoid:.3}");
    assert!((midpoint - 2.0).abs() < 0.1, "midpoint order {midpoint}");
    assert!((trapezoid - 2.0).abs() < 0.1, "trapezoid order {trapezoid}");
}

/// Runs `n` steps and returns every energy balance (from node 1 on).
fn balances<S: Lagrangian<N>, M: DiscreteLagrangian, const N: usize>(
    system: S,
    method: M,
    h: f64,
    q0: [f64; N],
    v0: [f64; N],
    n: usize,
) -> Vec<EnergyBalance> {
    let mut sim = Integrator::new(system, method, h).start(0.0, q0, v0).unwrap();
    let mut out = Vec::with_capacity(n);
    assert!(sim.energy_balance().is_none());
    sim.step().unwrap();
    assert!(sim.energy_balance().is_none(), "node 0 has no step behind it");
    sim.run(n, |s| out.push(s.energy_balance().unwrap())).unwrap();
    out
}

/// Largest `|E_{k+1} − E_k − W_k| / max(|E_k|, |E_{k+1}|)` over a run.
fn worst_relative(balances: &[EnergyBalance]) -> f64 {
    balances.iter().map(|b| b.residual().abs() / b.energy_before.abs().max(b.energy_after.abs())).fold(0.0, f64::max)
}

#[test]
fn energy_balance_closes_to_round_off_for_quadratic_lagrangians() {
    // The midpoint rule with fixed steps on a Lagrangian quadratic in (q, v):
    // E_{k+1} − E_k = W_k exactly (proof in `forcing`), whatever the forces
    // (linear damping, a time-dependent source, a battery). Asserted at every
    // node: |E_{k+1} − E_k − W_k| ≤ 1e-13 max(|E_k|, |E_{k+1}|).
    let n = 20_000;
    let damped = balances(damped(), Midpoint, 0.01, [1.0], [0.0], 2_000);
    // Over 2000 steps (t = 20) the energy decays by e^{-10}: the bound is per node, relative.
    let rlc = balances(rlc(), Midpoint, 0.01, [0.0], [0.0], n);
    let sensor = balances(Sensor { ..SENSOR }, Midpoint, 0.001, [0.0, 0.0], [0.0, 0.0], n);
    for (name, b) in [("damped oscillator", &damped), ("rlc", &rlc), ("sensor, constant L1", &sensor)] {
        let worst = worst_relative(b);
        let work: f64 = b.iter().map(|b| b.work.abs()).sum();
        eprintln!("{name}: worst relative balance residual {worst:.2e} (total |work| {work:.3e})");
        assert!(worst <= 1e-13, "{name}: residual {worst:e}");
        assert!(work > 1e-3, "{name}: the forces must do work for the test to mean anything");
    }
}

#[test]
fn energy_balance_residual_is_third_order_otherwise() {
    // Non-quadratic L (the sensor with L1(x) = L0/(1 + x/a)) and the
    // trapezoid rule: the residual is the local energy error of the method,
    // O(h³) per node. Max over the same time interval at three step sizes.
    let steps = [0.004, 0.002, 0.001];
    let t_end = 0.5;
    let fit = |residuals: Vec<f64>| fitted_order(&steps, &residuals);
    let sensor: Vec<f64> = steps
        .iter()
        .map(|&h| {
            let n = (t_end / h) as usize;
            let b = balances(Sensor { ..SENSOR_VARIABLE }, Midpoint, h, [0.0, 0.0], [0.0, 0.0], n);
            b.iter().map(|b| b.residual().abs()).fold(0.0, f64::max)
        })
        .collect();
    let trapezoid: Vec<f64> = steps
        .iter()
        .map(|&h| {
            let n = (t_end / h) as usize;
            let b = balances(damped(), Trapezoid, h, [1.0], [0.0], n);
            b.iter().map(|b| b.residual().abs()).fold(0.0, f64::max)
        })
        .collect();
    eprintln!("variable-L1 sensor, midpoint: max residuals {sensor:?}, order {:.3}", fit(sensor.clone()));
    eprintln!("damped oscillator, trapezoid: max residuals {trapezoid:?}, order {:.3}", fit(trapezoid.clone()));
    assert!((fit(sensor) - 3.0).abs() < 0.2);
    assert!((fit(trapezoid) - 3.0).abs() < 0.2);
}

/// The discrete first integral of Fu, Dai & Tang §4 along a run: returns the
/// largest `|I_k − I_0| / scale_k` with `I_k = p_{q,k} + r Q_k − E t_k`,
/// `scale_k = max(|p_{q,k}|, r |Q_k|, E t_k)`, and `Q_k = q_k − q_0` the charge
/// that has flowed, summed (compensated) from the step increments: the
/// stored `q_k` also carries the rounding of `q_k + Δq`, which in the steady
/// state has the same sign at every step and adds up to 2e-12 over 1e4 steps
/// (measured); that is round-off in the positions, not in the integral.
fn first_integral_drift<M: DiscreteLagrangian>(sensor: Sensor, method: M, h: f64, n: usize) -> f64 {
    let (r, e) = (sensor.r, sensor.e);
    let mut sim = Integrator::new(sensor, method, h).start(0.0, [0.0, 0.0], [0.0, 0.0]).unwrap();
    let i0 = sim.state().p[1];
    let (mut charge, mut compensation) = (0.0f64, 0.0f64);
    let mut worst = 0.0f64;
    sim.run(n, |s| {
        // Neumaier's compensated sum of the increments.
        let dq = s.last_step().unwrap().dq[1];
        let sum = charge + dq;
        compensation += if charge.abs() >= dq.abs() { (charge - sum) + dq } else { (dq - sum) + charge };
        charge = sum;
        let q = charge + compensation;
        let st = s.state();
        let i = st.p[1] + r * q - e * st.t;
        let scale = st.p[1].abs().max((r * q).abs()).max(e * st.t);
        worst = worst.max((i - i0).abs() / scale);
    })
    .unwrap();
    worst
}

#[test]
fn paper_002_first_integral_holds_along_the_discrete_solution() {
    // Fu, Dai & Tang §4: L = ½ m ẋ² + ½ L1 q̇² − ½ k x² + m g x, resistor ½ r q̇²,
    // battery E on the charge. The charge q is cyclic (the macro proves it,
    // `CYCLIC = [false, true]`), so ξ = e_q (the paper's η = 1) generates a
    // symmetry of every discrete Lagrangian, with momentum map J_k = p_{q,k}.
    // The forcing impulse of step k is F_k^−[q] + F_k^+[q] = h (E − r v̂_q)
    // = E h − r (q_{k+1} − q_k) for each quadrature (E is constant and the
    // resistor force −r q̇ is taken at the secant velocity), so the discrete
    // Noether theorem J_{k+1} − J_k = impulse reads, summed,
    //
    //     I_k = p_{q,k} + r q_k − E t_k = const,
    //
    // (checked with q_k − q_0 summed from the increments, see
    // `first_integral_drift`),
    //
    // which is the charge part of (27)–(28) with v = −½ L1 Δq + R q_k + E t:
    // the paper's D1 L_d is −L1 Δq = −p_q with h = 1, and its battery enters
    // (25) with the opposite sign, E_d = −E. The x-terms of (27),
    // −m Δx − k x + m g, are the x-part of the DEL (25), not a conserved
    // quantity: the spring and gravity break the translation of x (see
    // `tests/verification/noether.rs`, where that shows up as the symmetry defect).
    // Asserted: |I_k − I_0| ≤ 1e-13 · max(|p_q|, r|q_k|, E t_k) at every step.
    assert_eq!(<Sensor as Lagrangian<2>>::CYCLIC, [false, true]);
    let n = 20_000;
    for (name, drift) in [
        ("midpoint", first_integral_drift(Sensor { ..SENSOR }, Midpoint, 0.001, n)),
        ("trapezoid", first_integral_drift(Sensor { ..SENSOR }, Trapezoid, 0.001, n)),
        ("α = 0.3", first_integral_drift(Sensor { ..SENSOR }, AlphaBeta::new(0.3).unwrap(), 0.001, n)),
    ] {
        eprintln!("sensor, constant L1, {name}: max |I_k − I_0| / scale = {drift:.2e} over {n} steps");
        assert!(drift <= 1e-13, "{name}: {drift:e}");
    }
}

#[test]
fn constant_inductance_decouples_the_armature() {
    // With L1 constant the armature is a harmonic oscillator about m g / k,
    // untouched by the circuit: the midpoint step energy of x alone,
    // ½ m v̂_x² + ½ k x̄² − m g x̄, is conserved to round-off.
    let sensor = Sensor { ..SENSOR };
    let (m, k, g) = (sensor.m, sensor.k, sensor.g);
    let mut sim = Integrator::new(sensor, Midpoint, 0.001).start(0.0, [0.0, 0.0], [0.0, 0.0]).unwrap();
    let mut energies = Vec::new();
    let mut q_prev = sim.state().q[0];
    sim.run(20_000, |s| {
        let (x, h) = (s.state().q[0], 0.001);
        let (v, mid) = ((x - q_prev) / h, 0.5 * (x + q_prev));
        energies.push(0.5 * m * v * v + 0.5 * k * mid * mid - m * g * mid);
        q_prev = x;
    })
    .unwrap();
    let scale = (m * g).powi(2) / k;
    let spread = energies.iter().fold(0.0f64, |w, e| w.max((e - energies[0]).abs())) / scale;
    eprintln!("sensor, constant L1: armature energy spread {spread:.2e} of (m g)²/k");
    // The secant velocity from absolute positions loses a few digits: bound 1e-10.
    assert!(spread <= 1e-10, "{spread:e}");
}

/// `y = (x, q, ẋ, q̇)` of the sensor with `L1(x) = L0/(1 + x/a)`:
/// `m ẍ = −k x + m g + ½ L1'(x) q̇²`, `L1 q̈ = E − r q̇ − L1'(x) ẋ q̇`.
fn sensor_rhs(s: &Sensor, y: &[f64; 4]) -> [f64; 4] {
    let [x, _, vx, vq] = *y;
    let l1 = s.l0 / (1.0 + x / s.a);
    let dl1 = -s.l0 / (s.a * (1.0 + x / s.a).powi(2));
    [vx, vq, (-s.k * x + s.m * s.g + 0.5 * dl1 * vq * vq) / s.m, (s.e - s.r * vq - dl1 * vx * vq) / l1]
}

#[test]
fn sensor_with_variable_inductance_converges_and_keeps_its_first_integral() {
    // L1(x) = L0/(1 + x/a): the magnetic force ½ L1'(x) q̇² couples the
    // armature to the current, so no energy is conserved and the balance is
    // only O(h³) per node (previous tests). What must still hold: the charge
    // is cyclic whatever L1(x) is, so I_k = p_{q,k} + r q_k − E t_k stays
    // constant to round-off; and the motion converges with order 2 (against
    // RK4 with h = 1e-4, error in (x, q, p_x, p_q) at t = 1).
    let sensor = || Sensor { ..SENSOR_VARIABLE };
    let n = 20_000;
    let drift = first_integral_drift(sensor(), Midpoint, 0.001, n);
    eprintln!("sensor, variable L1, midpoint: max |I_k − I_0| / scale = {drift:.2e} over {n} steps");
    assert!(drift <= 1e-13, "{drift:e}");

    let s = sensor();
    let y = rk4(|y| sensor_rhs(&s, y), [0.0; 4], 1e-4, 10_000);
    let l1 = s.l0 / (1.0 + y[0] / s.a);
    let reference = [y[0], y[1], s.m * y[2], l1 * y[3]];
    let steps = [0.02, 0.01, 0.005, 0.0025];
    let errors: Vec<f64> = steps
        .iter()
        .map(|&h| {
            let sim = run_to(sensor(), Midpoint, h, [0.0, 0.0], [0.0, 0.0], 1.0);
            let st = sim.state();
            rel_err(&[st.q[0], st.q[1], st.p[0], st.p[1]], &reference)
        })
        .collect();
    let order = fitted_order(&steps, &errors);
    eprintln!("sensor, variable L1: errors {errors:?}, order {order:.3}");
    assert!((order - 2.0).abs() < 0.1, "{order}");
}

#[test]
fn forced_newton_jacobian_matches_finite_differences() {
    // ∂(∂A/∂q_k + F_k^−)/∂q_{k+1}, from the dual seeding, against central
    // differences of the residual: drag, thrust depending on q, every method.
    let system = KeplerCartesian { mu: 1.0, c: 0.3, s: 0.2 };
    let seg = Segment { t0: 0.3, h: 0.05, q0: [0.9, 0.2], dq: [-0.01, 0.05] };
    fn check<M: DiscreteLagrangian>(system: &KeplerCartesian, method: M, seg: &Segment<2>) -> f64 {
        let d = forcing::forced_step_derivatives(system, &method, seg);
        let mut worst = 0.0f64;
        for j in 0..2 {
            let eps = 1e-6;
            let mut plus = *seg;
            plus.dq[j] += eps;
            let mut minus = *seg;
            minus.dq[j] -= eps;
            let rp = forcing::forced_step_derivatives(system, &method, &plus).d_q0;
            let rm = forcing::forced_step_derivatives(system, &method, &minus).d_q0;
            for i in 0..2 {
                let fd = (rp[i] - rm[i]) / (2.0 * eps);
                worst = worst.max((fd - d.d2_q0_q1[(i, j)]).abs() / d.d2_q0_q1.amax());
            }
        }
        worst
    }
    for (name, err) in [
        ("midpoint", check(&system, Midpoint, &seg)),
        ("trapezoid", check(&system, Trapezoid, &seg)),
        ("α = 0.3", check(&system, AlphaBeta::new(0.3).unwrap(), &seg)),
    ] {
        assert!(err < 1e-8, "{name}: jacobian off by {err:e}");
    }
    // The forces are really in there: without them the Jacobian differs.
    let bare = lagrangian::derivatives::step_derivatives(&system, &Midpoint, &seg).d2_q0_q1;
    let forced = forcing::forced_step_derivatives(&system, &Midpoint, &seg).d2_q0_q1;
    assert!((bare - forced).amax() > 0.1);
}

#[test]
fn galerkin_energy_preserving_steps_refuse_forced_systems() {
    // One-point rules in f64 take energy-balance steps instead
    // (`tests/verification/forced_variable_steps.rs`); Galerkin rules do not have them.
    let result = Integrator::new(damped(), Galerkin::<2, 2>::gauss(), 0.01)
        .energy_preserving(StepBounds::around(0.01))
        .start(0.0, [1.0], [0.0]);
    match result {
        Err(Error::Unsupported { what }) => assert!(what.contains("energy-balance"), "{what}"),
        other => panic!("expected Unsupported, got {other:?}"),
    }
}

/// A particle pushed towards a wall at `q = wall` by `√(wall − q)`, which is
/// NaN past the wall.
#[derive(Debug)]
struct Wall {
    wall: f64,
}

#[lagrangian]
impl Wall {
    fn lagrangian(&self, _q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0]
    }

    fn force(&self, q: [f64; 1], _v: [f64; 1]) -> [f64; 1] {
        [(self.wall - q[0]).sqrt()]
    }
}

#[test]
fn a_non_finite_force_is_a_typed_error_and_the_state_is_kept() {
    match Integrator::new(Wall { wall: 0.5 }, Midpoint, 0.01).start(0.0, [1.0], [0.0]) {
        Err(Error::InvalidInitialData { reason }) => assert!(reason.contains("force"), "{reason}"),
        other => panic!("expected InvalidInitialData, got {other:?}"),
    }
    let mut sim = Integrator::new(Wall { wall: 0.5 }, Midpoint, 0.01).start(0.0, [0.0], [1.0]).unwrap();
    let mut last = *sim.state();
    let error = loop {
        match sim.step() {
            Ok(state) => last = *state,
            Err(error) => break error,
        }
        assert!(sim.state().t < 1.0, "the particle should have reached the wall");
    };
    match error {
        Error::NonFinite { state, quantity, .. } => {
            assert_eq!(state, last);
            assert_eq!(quantity, "residual");
        }
        other => panic!("expected NonFinite, got {other:?}"),
    }
    assert_eq!(*sim.state(), last, "a failed step leaves the state alone");
    assert!(sim.state().q[0] < 0.5 && sim.state().q[0] > 0.4);
}

/// Negative damping: `R = −½ c q̇²` (linear) or `R = −¼ c q̇⁴` (cubic, which
/// blows up in finite time).
#[derive(Debug)]
struct Pumped {
    c: f64,
    cubic: bool,
}

#[lagrangian]
impl Pumped {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] - 0.5 * q[0] * q[0]
    }

    fn dissipation(&self, _q: [f64; 1], v: [f64; 1]) -> f64 {
        if self.cubic { -0.25 * self.c * v[0] * v[0] * v[0] * v[0] } else { -0.5 * self.c * v[0] * v[0] }
    }
}

#[test]
fn negative_damping_is_integrated_as_given_and_blow_up_is_a_typed_error() {
    // Documented behaviour: `dissipation` need not be convex; a negative
    // damping pumps energy in, and the balance E_{k+1} − E_k = W_k shows it
    // (W_k > 0), to round-off for this quadratic L. `dissipated_power` lets a
    // caller check the sign.
    let pumped = Pumped { c: 0.1, cubic: false };
    assert!(forcing::dissipated_power(&pumped, [0.0], [1.0]) < 0.0);
    let b = balances(pumped, Midpoint, 0.01, [1.0], [0.0], 5_000);
    assert!(b.last().unwrap().energy_after > 100.0 * b[0].energy_before, "the energy grows");
    assert!(b.iter().map(|b| b.work).sum::<f64>() > 0.0);
    assert!(worst_relative(&b) <= 1e-13);

    // The cubic one has no solution past a finite time: the step that
    // cannot be solved is a typed error, nothing panics, and the integrator
    // keeps its last (finite) state.
    let mut sim = Integrator::new(Pumped { c: 1.0, cubic: true }, Midpoint, 0.01).start(0.0, [0.0], [1.0]).unwrap();
    let mut last = *sim.state();
    let error = loop {
        match sim.step() {
            Ok(state) => last = *state,
            Err(error) => break error,
        }
        assert!(sim.state().step < 100_000, "expected a failure before the blow-up time");
    };
    eprintln!("cubic negative damping: {error}");
    assert!(matches!(
        error,
        Error::NewtonDidNotConverge { .. } | Error::SingularJacobian { .. } | Error::NonFinite { .. }
    ));
    assert_eq!(*sim.state(), last);
    assert!(last.q[0].is_finite() && last.p[0].is_finite());
}

#[test]
fn systems_without_forces_report_zero_forces() {
    let mut sim = Integrator::new(Oscillator { m: 1.0, k: 1.0 }, Midpoint, 0.1).start(0.0, [1.0], [0.0]).unwrap();
    assert!(sim.last_forces().is_none());
    sim.run(3, |_| {}).unwrap();
    assert_eq!(sim.last_forces(), Some(lagrangian::forcing::DiscreteForces::ZERO));
    assert!(sim.last_tangent_map().is_some());
    let mut forced = Integrator::new(damped(), Midpoint, 0.1).start(0.0, [1.0], [0.0]).unwrap();
    forced.run(3, |_| {}).unwrap();
    assert!(forced.last_forces().unwrap().minus[0] != 0.0);
    assert!(forced.last_tangent_map().is_none(), "a forced step is not symplectic");
}
