//! Regression tests for inputs that used to slip through: every one is now a
//! typed error or a correct result, and a failed step keeps the state.
#![allow(missing_docs)]

use lagrangian_runtime::galerkin::{Galerkin, GalerkinIntegrator};
use lagrangian_runtime::{
    Error, Integrator, Lagrangian, Midpoint, NewtonOptions, Scalar, StepBounds, Trapezoid, symplectic,
};
use nalgebra::DMatrix;

struct Free;
impl Lagrangian<1> for Free {
    const AUTONOMOUS: bool = true;
    const CYCLIC: [bool; 1] = [true];
    fn lagrangian<D: Scalar>(&self, _t: D, _q: [D; 1], v: [D; 1]) -> D {
        v[0] * v[0] * 0.5
    }
}

/// A free particle of mass 1e300, whose DEL stays well scaled at h = 1e307.
struct Heavy;
impl Lagrangian<1> for Heavy {
    const AUTONOMOUS: bool = true;
    const CYCLIC: [bool; 1] = [true];
    fn lagrangian<D: Scalar>(&self, _t: D, _q: [D; 1], v: [D; 1]) -> D {
        v[0] * v[0] * 0.5e300
    }
}

struct Pendulum;
impl Lagrangian<1> for Pendulum {
    const AUTONOMOUS: bool = true;
    const CYCLIC: [bool; 1] = [false];
    fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 1], v: [D; 1]) -> D {
        v[0] * v[0] * 0.5 + q[0].cos() * 9.81
    }
}

/// A potential with a wall at q = 1 where `L` stops being defined.
struct LogWall;
impl Lagrangian<1> for LogWall {
    const AUTONOMOUS: bool = true;
    const CYCLIC: [bool; 1] = [false];
    fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 1], v: [D; 1]) -> D {
        v[0] * v[0] * 0.5 - (-q[0] + 1.0).ln() * 0.01
    }
}

/// A stiff quartic, `V = k q⁴ / 4` with `k = 1e12`.
struct StiffQuartic;
impl Lagrangian<1> for StiffQuartic {
    const AUTONOMOUS: bool = true;
    const CYCLIC: [bool; 1] = [false];
    fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 1], v: [D; 1]) -> D {
        v[0] * v[0] * 0.5 - q[0].powi(4) * 0.25e12
    }
}

struct Nothing;
impl Lagrangian<0> for Nothing {
    const AUTONOMOUS: bool = true;
    const CYCLIC: [bool; 0] = [];
    fn lagrangian<D: Scalar>(&self, _t: D, _q: [D; 0], _v: [D; 0]) -> D {
        D::zero()
    }
}

/// `t_{k+1} = f64::MAX + h` overflows. (For such `h` the second derivatives
/// of the action underflow too, `∂²A/∂q_k∂q_{k+1} ~ 1/h²·…`, so the step may
/// fail on its Jacobian before it reaches the time check; what matters is
/// that it is never `Ok` with `t = ∞`. The time check itself is unit-tested.)
#[test]
fn a_step_to_an_infinite_time_is_refused_and_the_state_kept() {
    for h in [1e300, 1e307, f64::MAX] {
        let mut sim = Integrator::new(Pendulum, Midpoint, h).start(f64::MAX, [0.5], [0.0]).unwrap();
        let before = *sim.state();
        assert!(sim.step().is_err());
        assert_eq!(*sim.state(), before);
        let mut sim =
            GalerkinIntegrator::new(Heavy, Galerkin::<2, 2>::gauss(), h).start(f64::MAX, [0.5], [0.0]).unwrap();
        let before = *sim.state();
        assert!(sim.step().is_err());
        assert_eq!(*sim.state(), before);
    }
}

#[test]
fn galerkin_stops_where_the_lagrangian_is_not_defined() {
    let mut sim = GalerkinIntegrator::new(LogWall, Galerkin::<2, 2>::gauss(), 0.01).start(0.0, [0.9], [1.0]).unwrap();
    let err = loop {
        let before = *sim.state();
        match sim.step() {
            Ok(s) => assert!(s.q[0] < 1.0, "stepped past the wall to q = {}", s.q[0]),
            Err(e) => {
                assert_eq!(*sim.state(), before);
                break e;
            }
        }
        assert!(sim.state().step < 10_000, "never stopped");
    };
    println!("stopped at q = {}: {err}", sim.state().q[0]);
}

#[test]
fn step_bounds_are_validated_and_enforced() {
    let infinite = StepBounds { h_min: 1e-3, h_max: 0.02, max_ratio: f64::INFINITY };
    let start = |b| Integrator::new(Pendulum, Midpoint, 0.01).energy_preserving(b).start(0.0, [1.0], [0.0]);
    assert!(matches!(start(infinite), Err(Error::InvalidStepBounds { .. })));
    let one = StepBounds { max_ratio: 1.0, ..infinite };
    assert!(matches!(start(one), Err(Error::InvalidStepBounds { .. })));

    let bounds = StepBounds { h_min: 1e-3, h_max: 0.02, max_ratio: 2.0 };
    let mut sim = start(bounds).unwrap();
    assert!(matches!(sim.set_step_size(1e300), Err(Error::InvalidStepSize { .. })));
    let mut t = 0.0;
    let mut largest = 0.0f64;
    sim.run_until(9.957, |s| {
        largest = largest.max(s.state().t - t);
        t = s.state().t;
    })
    .unwrap();
    assert_eq!(sim.state().t, 9.957);
    assert!(largest <= bounds.h_max * (1.0 + 1e-12), "a step of {largest}");
}

#[test]
fn run_until_lands_exactly_on_its_target() {
    let mut sim = Integrator::new(Pendulum, Midpoint, 0.01).start(0.0, [1.0], [0.0]).unwrap();
    for k in 1..=1000 {
        let target = k as f64 / 100.0;
        sim.run_until(target, |_| {}).unwrap();
        assert_eq!(sim.state().t, target);
        // The same target again is a no-op.
        let before = *sim.state();
        sim.run_until(target, |_| {}).unwrap();
        assert_eq!(*sim.state(), before);
    }
    // The landing steps did not change the step size.
    assert_eq!(sim.step_size(), 0.01);

    let mut sim = Integrator::new(Free, Midpoint, 1e6).start(0.0, [0.0], [1.0]).unwrap();
    sim.run_until(5.0, |_| {}).unwrap();
    assert_eq!(sim.state().t, 5.0);
    assert!((sim.state().q[0] - 5.0).abs() < 1e-14);

    let mut sim = GalerkinIntegrator::new(Pendulum, Galerkin::<2, 2>::gauss(), 0.01).start(0.0, [1.0], [0.0]).unwrap();
    for k in 1..=300 {
        let target = k as f64 / 100.0;
        sim.run_until(target, |_| {}).unwrap();
        assert_eq!(sim.state().t, target);
    }
}

#[test]
fn an_unstable_step_is_rejected_instead_of_published() {
    // ωh ≈ 1.7e5 for the explicit trapezoid (Störmer–Verlet): the discrete
    // equations have a solution, but increments grow by ~1e29 per step.
    let mut sim = Integrator::new(StiffQuartic, Trapezoid, 0.1).start(0.0, [1.0], [0.0]).unwrap();
    let mut failure = None;
    for _ in 0..5 {
        let before = *sim.state();
        match sim.step() {
            Ok(s) => assert!(s.q[0].abs() < 1e12, "published q = {}", s.q[0]),
            Err(e) => {
                assert_eq!(*sim.state(), before);
                failure = Some(e);
                break;
            }
        }
    }
    let failure = failure.expect("the unstable run was not stopped");
    assert!(matches!(failure, Error::StepRejected { .. }), "{failure}");
}

#[test]
fn unusable_settings_are_typed_errors() {
    let bad = [
        NewtonOptions { rtol: f64::NAN, ..NewtonOptions::default() },
        NewtonOptions { rtol: 0.0, ..NewtonOptions::default() },
        NewtonOptions { rtol: f64::INFINITY, ..NewtonOptions::default() },
        NewtonOptions { atol: -1.0, ..NewtonOptions::default() },
        NewtonOptions { max_iterations: 0, ..NewtonOptions::default() },
        NewtonOptions { min_rcond: f64::NAN, ..NewtonOptions::default() },
    ];
    for options in bad {
        let r = Integrator::new(Pendulum, Midpoint, 0.01).newton(options).start(0.0, [1.0], [0.0]);
        assert!(matches!(r, Err(Error::InvalidNewtonOptions { .. })), "{options:?}");
        let r =
            GalerkinIntegrator::new(Pendulum, Galerkin::<2, 2>::gauss(), 0.01).newton(options).start(0.0, [1.0], [0.0]);
        assert!(matches!(r, Err(Error::InvalidNewtonOptions { .. })), "{options:?}");
    }
    // No degrees of freedom.
    let r = Integrator::new(Nothing, Midpoint, 0.01).start(0.0, [], []);
    assert!(matches!(r, Err(Error::InvalidInitialData { .. })));
    let r = GalerkinIntegrator::new(Nothing, Galerkin::<2, 2>::gauss(), 0.01).start(0.0, [], []);
    assert!(matches!(r, Err(Error::InvalidInitialData { .. })));
    // Matrices that are no tangent map.
    assert_eq!(symplectic::defect(&DMatrix::zeros(3, 3)), None);
    assert_eq!(symplectic::defect(&DMatrix::zeros(2, 4)), None);
    assert_eq!(symplectic::defect(&DMatrix::identity(4, 4)), Some(0.0));
}

/// A particle meeting a potential step of height 0.3 at q = 0.5, declared
/// discontinuous.
struct PotentialStep;
impl Lagrangian<1> for PotentialStep {
    const AUTONOMOUS: bool = true;
    const CYCLIC: [bool; 1] = [false];
    const DISCONTINUOUS: bool = true;
    fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 1], v: [D; 1]) -> D {
        let step = if q[0].re() > 0.5 { 0.3 } else { 0.0 };
        v[0] * v[0] * 0.5 - step
    }
}

/// The same particle without the step, declared discontinuous all the same.
struct FreeDeclared;
impl Lagrangian<1> for FreeDeclared {
    const AUTONOMOUS: bool = true;
    const CYCLIC: [bool; 1] = [true];
    const DISCONTINUOUS: bool = true;
    fn lagrangian<D: Scalar>(&self, _t: D, _q: [D; 1], v: [D; 1]) -> D {
        v[0] * v[0] * 0.5
    }
}

#[test]
fn a_declared_discontinuity_shows_as_an_energy_jump() {
    // From q = 0 at speed 1: the step is crossed at t ≈ 0.5; E = 0.5.
    let mut sim = Integrator::new(PotentialStep, Midpoint, 0.01).start(0.0, [0.0], [1.0]).unwrap();
    sim.run_until(1.0, |_| {}).unwrap();
    let stats = sim.stats();
    println!("largest energy jump {:.3} at t = {:.3}", stats.largest_energy_jump, stats.largest_energy_jump_at);
    assert!(stats.largest_energy_jump > 0.1, "{stats:?}");
    assert!((0.49..0.53).contains(&stats.largest_energy_jump_at), "{stats:?}");
    // Smooth motion: no jump beyond round-off.
    let mut free = Integrator::new(FreeDeclared, Midpoint, 0.01).start(0.0, [0.0], [1.0]).unwrap();
    free.run_until(1.0, |_| {}).unwrap();
    assert!(free.stats().largest_energy_jump < 1e-12, "{:?}", free.stats());
}
