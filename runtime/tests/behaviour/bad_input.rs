//! Inputs that must not slip through: every one is a typed error or a
//! correct result, and a failed step keeps the state.
#![allow(missing_docs)]

use lagrangian_runtime::galerkin::{Galerkin, GalerkinIntegrator};
use lagrangian_runtime::{
    Curvature, Error, Integrator, Lagrangian, Midpoint, NewtonOptions, Scalar, StepBounds, TimeTransformed, Trapezoid,
    symplectic,
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
#[derive(Clone, Copy)]
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
    let infinite = StepBounds { h_min: 1e-3, h_max: 0.02, max_ratio: f64::INFINITY, accuracy: None };
    let start = |b| Integrator::new(Pendulum, Midpoint, 0.01).energy_preserving(b).start(0.0, [1.0], [0.0]);
    assert!(matches!(start(infinite), Err(Error::InvalidStepBounds { .. })));
    let one = StepBounds { max_ratio: 1.0, ..infinite };
    assert!(matches!(start(one), Err(Error::InvalidStepBounds { .. })));

    let bounds = StepBounds { h_min: 1e-3, h_max: 0.02, max_ratio: 2.0, accuracy: None };
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

/// A time-transformed system steps with a fixed `σ`: energy-preserving steps
/// of it are refused at `start`, whatever the method (and their code is not
/// compiled for it).
#[test]
fn energy_steps_of_a_time_transformed_system_are_refused() {
    let system = || TimeTransformed::new(Pendulum, Curvature::new(0.1).unwrap());
    let bounds = StepBounds::around(0.01);
    let (x0, w0) = ([1.0, 0.0], [0.0, 1.0]);
    let r = Integrator::new(system(), Midpoint, 0.01).energy_preserving(bounds).start(0.0, x0, w0);
    assert!(matches!(r, Err(Error::Unsupported { .. })), "{:?}", r.err());
    let r = Integrator::new(system(), Galerkin::<2, 2>::gauss(), 0.01).energy_preserving(bounds).start(0.0, x0, w0);
    assert!(matches!(r, Err(Error::Unsupported { .. })), "{:?}", r.err());
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

/// `L = ½v² + 10⁻³ ln((q − 2)(q − 3))`: not defined (NaN) for `2 < q < 3`,
/// where its derivatives `10⁻³ (2q − 5)/((q − 2)(q − 3))` stay finite.
#[derive(Clone, Copy)]
struct NanBand;
impl Lagrangian<1> for NanBand {
    const AUTONOMOUS: bool = true;
    const CYCLIC: [bool; 1] = [false];
    fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 1], v: [D; 1]) -> D {
        v[0] * v[0] * 0.5 + ((q[0] - 2.0) * (q[0] - 3.0)).ln() * 1e-3
    }
}

/// A system with its structure declared as the macro would (gradient code,
/// and for `SEPARABLE` the constant-mass form that makes the trapezoid rule
/// explicit): the one-point rules take their gradient-code and
/// Störmer–Verlet paths on it.
#[derive(Clone, Copy)]
struct Declared<S, const SEPARABLE: bool>(S);
impl<S: Lagrangian<1>, const SEPARABLE: bool> Lagrangian<1> for Declared<S, SEPARABLE> {
    const AUTONOMOUS: bool = S::AUTONOMOUS;
    const CYCLIC: [bool; 1] = S::CYCLIC;
    const HAS_GRADIENT: bool = true;
    const HAS_GRADIENT_QV: bool = true;
    const SEPARABILITY: lagrangian_runtime::Separability = if SEPARABLE {
        lagrangian_runtime::Separability::ConstantMass
    } else {
        lagrangian_runtime::Separability::NotProven
    };
    fn lagrangian<D: Scalar>(&self, t: D, q: [D; 1], v: [D; 1]) -> D {
        self.0.lagrangian(t, q, v)
    }
}

/// Steps until the first error, checking that it is the non-finite
/// Lagrangian, that it leaves the state as it was, and that no published
/// state lies where `defined` says `L` is not. A step's action is `L` at its
/// quadrature points, so the last state may lie up to half a step (the
/// midpoint rule's point) beyond the region where `L` is defined: `defined`
/// takes that margin into account.
fn stops_at_the_undefined_lagrangian<S: Lagrangian<1>, M: lagrangian_runtime::F64Readouts>(
    sim: Integrator<S, M, 1>,
    defined: impl Fn(f64) -> bool,
    name: &str,
) {
    match stops_before_the_undefined_lagrangian(sim, defined, name) {
        Error::NonFinite { quantity: "lagrangian", .. } => {}
        other => panic!("{name}: {other}"),
    }
}

/// [`stops_at_the_undefined_lagrangian`] accepting any typed error (an
/// energy-preserving step may find no step size that solves its energy
/// equation before it reaches the region): the error.
fn stops_before_the_undefined_lagrangian<S: Lagrangian<1>, M: lagrangian_runtime::F64Readouts>(
    mut sim: Integrator<S, M, 1>,
    defined: impl Fn(f64) -> bool,
    name: &str,
) -> Error {
    let mut last = *sim.state();
    let err = loop {
        let before = *sim.state();
        match sim.step() {
            Ok(s) => last = *s,
            Err(e) => {
                assert_eq!(*sim.state(), before, "{name}: a failed step changed the state");
                break e;
            }
        }
        assert!(sim.state().step < 10_000, "{name}: never stopped (q = {})", sim.state().q[0]);
    };
    assert!(defined(last.q[0]), "{name}: stepped to q = {} where L is not defined", last.q[0]);
    err
}

/// Every method stops with a typed error at the step whose action is not
/// finite, where `L` is NaN with finite derivatives, and at the wall of a
/// logarithmic potential.
#[test]
fn every_method_stops_where_the_lagrangian_is_not_defined() {
    use lagrangian_runtime::{AlphaBeta, Composition, Derivatives};
    fn all<S: Lagrangian<1> + Copy>(system: S, q0: f64, defined: fn(f64) -> bool, name: &str) {
        let h = 0.01;
        let start = |q0: f64| (0.0, [q0], [1.0]);
        let (t0, q, v) = start(q0);
        for derivatives in [Derivatives::Forward, Derivatives::Reverse] {
            let tag = |rule: &str| format!("{name}, {rule}, {derivatives:?}");
            stops_at_the_undefined_lagrangian(
                Integrator::new(system, Midpoint, h).derivatives(derivatives).start(t0, q, v).unwrap(),
                defined,
                &tag("midpoint"),
            );
            stops_at_the_undefined_lagrangian(
                Integrator::new(system, Trapezoid, h).derivatives(derivatives).start(t0, q, v).unwrap(),
                defined,
                &tag("trapezoid"),
            );
            stops_at_the_undefined_lagrangian(
                Integrator::new(system, AlphaBeta::new(0.3).unwrap(), h)
                    .derivatives(derivatives)
                    .start(t0, q, v)
                    .unwrap(),
                defined,
                &tag("α-β"),
            );
            stops_at_the_undefined_lagrangian(
                Integrator::new(system, Composition::YOSHIDA4, h).derivatives(derivatives).start(t0, q, v).unwrap(),
                defined,
                &tag("Yoshida 4"),
            );
        }
        stops_before_the_undefined_lagrangian(
            Integrator::new(system, Midpoint, h).energy_preserving(StepBounds::around(h)).start(t0, q, v).unwrap(),
            defined,
            &format!("{name}, energy-preserving midpoint"),
        );
        stops_at_the_undefined_lagrangian(
            GalerkinIntegrator::new(system, Galerkin::<2, 2>::gauss(), h).start(t0, q, v).unwrap(),
            defined,
            &format!("{name}, galerkin"),
        );
    }
    // Half a step of margin (|v| ≈ 1, h = 0.01).
    let band = |q: f64| !(2.006..=2.994).contains(&q);
    let wall = |q: f64| q < 1.006;
    all(NanBand, 1.5, band, "NaN band");
    all(Declared::<_, false>(NanBand), 1.5, band, "NaN band, gradient code");
    all(Declared::<_, true>(NanBand), 1.5, band, "NaN band, separable");
    all(LogWall, 0.9, wall, "log wall");
    all(Declared::<_, false>(LogWall), 0.9, wall, "log wall, gradient code");
    all(Declared::<_, true>(LogWall), 0.9, wall, "log wall, separable");
}
