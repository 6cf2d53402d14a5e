//! Bad input to the Galerkin integrator: typed errors, state kept, no panic.
use crate::common;
use crate::common::galerkin_reference;

use common::*;
use lagrangian::galerkin::StageIteration;
use lagrangian::prelude::*;
use lagrangian::{Error, Galerkin, GalerkinIntegrator, NewtonOptions, NodeFamily, Quadrature, StepBounds};

#[test]
fn degree_zero_is_refused() {
    let g = Galerkin::<0, 1>::new(NodeFamily::GaussLobatto, Quadrature::gauss_legendre());
    assert!(g.check().is_err());
    assert_eq!(g.order(), 0);
    let err = GalerkinIntegrator::new(Pendulum { ..PENDULUM }, g, 0.1).start(0.0, [0.1], [0.0]).unwrap_err();
    assert!(matches!(err, Error::InvalidMethod { .. }), "{err}");
    assert!(err.to_string().contains("degree"), "{err}");
}

#[test]
fn an_accuracy_bound_on_galerkin_energy_steps_is_refused_not_ignored() {
    // The capped step of least mismatch is the one-point rules' in f64: a
    // Galerkin rule (and a one-point rule in double-double, which runs as
    // one) refuses the bound at the start and through `Problem`.
    let bounds = StepBounds::around(0.1).with_accuracy(1e-3);
    let galerkin = Galerkin::<2, 2>::gauss();
    let err = GalerkinIntegrator::new(Pendulum { ..PENDULUM }, galerkin, 0.1)
        .energy_preserving(bounds)
        .start(0.0, [0.1], [0.0])
        .unwrap_err();
    let Error::Unsupported { what } = err else { panic!("{err}") };
    assert!(what.contains("accuracy bound"), "{what}");
    let problem = Problem::new(Pendulum { ..PENDULUM }, 0.0, [0.1], [0.0]);
    let policy = Policy::EnergyPreserving { h: 0.1, bounds };
    let refused = problem.stepper(&Scheme::galerkin(3), policy).unwrap_err();
    assert_eq!(refused.to_string(), format!("not supported yet: {what}"));
    // The one-point rules in f64 take it.
    assert!(problem.stepper(&Scheme::MIDPOINT, policy).is_ok());
}

#[test]
fn too_weak_or_invalid_quadratures_are_refused() {
    // s = 3 needs degree 4 exactly: 2 Gauss points (degree 3) and 3 Lobatto points (degree 3) are too weak.
    let weak = Galerkin::<3, 2>::new(NodeFamily::GaussLobatto, Quadrature::gauss_legendre());
    let err = GalerkinIntegrator::new(Pendulum { ..PENDULUM }, weak, 0.1).start(0.0, [0.1], [0.0]).unwrap_err();
    assert!(matches!(err, Error::InvalidMethod { .. }), "{err}");
    assert!(err.to_string().contains("too weak"), "{err}");
    let weak = Galerkin::<3, 3>::new(NodeFamily::Equispaced, Quadrature::gauss_lobatto());
    assert!(GalerkinIntegrator::new(Pendulum { ..PENDULUM }, weak, 0.1).start(0.0, [0.1], [0.0]).is_err());
    // The quadratic element with the midpoint rule leaves the interior node undetermined.
    assert!(Galerkin::<2, 1>::quadratic_with(Quadrature::midpoint()).check().is_err());
    // A one-point Lobatto rule, or a rule without points, does not exist.
    let none = Galerkin::<1, 1>::new(NodeFamily::GaussLobatto, Quadrature::gauss_lobatto());
    assert!(matches!(
        GalerkinIntegrator::new(Pendulum { ..PENDULUM }, none, 0.1).start(0.0, [0.1], [0.0]),
        Err(Error::InvalidMethod { .. })
    ));
    let empty = Galerkin::<1, 0>::new(NodeFamily::GaussLobatto, Quadrature::gauss_legendre());
    assert!(empty.check().is_err());
    // The weakest valid rules are accepted, with the order they give.
    assert_eq!(Galerkin::<3, 3>::gauss().order(), 6);
    assert_eq!(Galerkin::<3, 4>::new(NodeFamily::GaussLobatto, Quadrature::gauss_lobatto()).order(), 6);
    assert_eq!(Galerkin::<3, 5>::new(NodeFamily::GaussLobatto, Quadrature::gauss_legendre()).order(), 6);
    assert_eq!(Galerkin::linear_simpson().order(), 2);
}

#[test]
fn invalid_step_sizes_and_initial_data_are_refused() {
    for h in [0.0, -0.1, f64::NAN, f64::INFINITY] {
        let err =
            GalerkinIntegrator::new(Pendulum { ..PENDULUM }, Galerkin::<2, 2>::gauss(), h).start(0.0, [0.1], [0.0]);
        assert!(matches!(err, Err(Error::InvalidStepSize { .. })), "h = {h}");
    }
    let err = GalerkinIntegrator::new(Pendulum { ..PENDULUM }, Galerkin::<2, 2>::gauss(), 0.1)
        .start(0.0, [f64::NAN], [0.0])
        .unwrap_err();
    assert!(matches!(err, Error::InvalidInitialData { .. }), "{err}");
    let mut sim = GalerkinIntegrator::new(Pendulum { ..PENDULUM }, Galerkin::<2, 2>::gauss(), 0.1)
        .start(0.0, [0.1], [0.0])
        .unwrap();
    assert!(matches!(sim.set_step_size(-1.0), Err(Error::InvalidStepSize { .. })));
    assert_eq!(sim.step_size(), 0.1);
    assert!(matches!(sim.run_until(-1.0, |_| {}), Err(Error::InvalidTarget { .. })));
}

/// `L = q v − ½ q²` is linear in `v`: the Legendre transform is singular.
#[derive(Debug)]
struct Degenerate;

#[lagrangian]
impl Degenerate {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        q[0] * v[0] - 0.5 * q[0] * q[0]
    }
}

#[test]
fn a_degenerate_lagrangian_is_refused() {
    let err = GalerkinIntegrator::new(Degenerate, Galerkin::<2, 2>::gauss(), 0.1).start(0.0, [1.0], [0.0]).unwrap_err();
    assert!(matches!(err, Error::InvalidInitialData { .. }), "{err}");
}

#[test]
fn newton_failure_keeps_the_state_and_a_smaller_step_recovers() {
    let options = NewtonOptions { max_iterations: 3, ..NewtonOptions::default() };
    // Newton alone: the ladder of its attempts is what is counted below.
    let newton = Galerkin::<3, 3>::gauss().with_iteration(StageIteration::Newton);
    let mut sim = GalerkinIntegrator::new(Pendulum { ..PENDULUM }, newton, 0.05)
        .newton(options)
        .start(0.0, [3.0], [4.0])
        .unwrap();
    sim.run(10, |_| {}).unwrap();
    let before = *sim.state();
    let nodes_before = sim.last_nodes();
    let stats_before = *sim.stats();
    sim.set_step_size(4.0).unwrap();
    let err = sim.step().unwrap_err();
    match &err {
        Error::NewtonDidNotConverge { state, iterations, residual_norm, h, .. } => {
            assert_eq!(*state, before);
            // Three attempts (simplified Newton, full Newton, full Newton from a straight line) of 3 iterations each.
            assert_eq!(*iterations, 9);
            assert!(*residual_norm > 0.0);
            assert_eq!(*h, 4.0);
        }
        Error::SingularJacobian { state, .. } | Error::NonFinite { state, .. } => assert_eq!(*state, before),
        other => panic!("unexpected error {other}"),
    }
    assert_eq!(*sim.state(), before);
    assert_eq!(sim.last_nodes(), nodes_before);
    assert_eq!(sim.stats().steps, stats_before.steps);
    assert_eq!(sim.stats().failed_steps, stats_before.failed_steps + 1);
    // A smaller step goes on from the same state.
    sim.set_step_size(0.05).unwrap();
    sim.step().unwrap();
    assert_eq!(sim.state().step, before.step + 1);
}

#[test]
fn run_until_lands_on_the_target() {
    let mut sim = GalerkinIntegrator::new(Pendulum { ..PENDULUM }, Galerkin::<4, 4>::gauss(), 0.3)
        .start(0.0, [1.0], [0.0])
        .unwrap();
    sim.run_until(10.0, |_| {}).unwrap();
    assert_eq!(sim.state().t, 10.0);
    assert_eq!(sim.step_size(), 0.3);
    // The shortened last step is a proper step: against the elliptic-function solution.
    let exact = galerkin_reference::pendulum_angle((PENDULUM.g / PENDULUM.l).sqrt(), 1.0, 10.0);
    assert!((sim.state().q[0] - exact).abs() < 1e-5, "{} vs {exact}", sim.state().q[0]);
}
