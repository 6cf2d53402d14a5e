//! Bad input to a Galerkin rule on a run-time-sized system: a degree or a
//! quadrature that is not offered is a typed refusal, and a step whose
//! Newton iteration fails returns the typed error with the state and leaves
//! the stepper bit-identical, so that a retry with a smaller step takes the
//! steps of a run that never failed.

use lagrangian::prelude::*;
use lagrangian::problem::supports;

/// A pendulum of run-time size one, swinging over the top.
#[derive(Clone, Debug)]
struct Pendulum;

#[lagrangian]
impl Pendulum {
    fn dimension(&self) -> usize {
        1
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        0.5 * v[0] * v[0] + 9.81 * q[0].cos()
    }
}

/// The bits of a state, to compare states for identity.
fn bits(state: &PhasePoint) -> (u64, u64, Vec<u64>, Vec<u64>) {
    let f = |x: &[f64]| x.iter().map(|x| x.to_bits()).collect();
    (state.step, state.t.to_bits(), f(&state.q), f(&state.p))
}

#[test]
fn a_failed_galerkin_step_at_a_run_time_size_changes_nothing() {
    let options = NewtonOptions { max_iterations: 3, ..NewtonOptions::default() };
    let problem = Problem::new(Pendulum, 0.0, vec![3.0], vec![4.0]).newton(options);
    let start = || problem.stepper(&Scheme::galerkin(3), 0.05).unwrap();
    let (mut sim, mut clean) = (start(), start());
    sim.run(10, |_| {}).unwrap();
    clean.run(10, |_| {}).unwrap();
    let before = bits(sim.state());
    let (stats, energy) = (sim.stats(), sim.discrete_energy());
    sim.set_step_size(4.0).unwrap();
    let err = sim.step().unwrap_err();
    match &err {
        Error::NewtonDidNotConverge { state, h, .. } => {
            assert_eq!(bits(state), before);
            assert_eq!(*h, 4.0);
        }
        Error::SingularJacobian { state, .. } | Error::NonFinite { state, .. } | Error::StepRejected { state, .. } => {
            assert_eq!(bits(state), before)
        }
        other => panic!("unexpected error {other}"),
    }
    assert_eq!(bits(sim.state()), before);
    assert_eq!(sim.discrete_energy().to_bits(), energy.to_bits());
    assert_eq!((sim.stats().steps, sim.stats().failed_steps), (stats.steps, stats.failed_steps + 1));
    // The retry goes on from the same state, and with the same start of
    // Newton (the last step's polynomial): the steps of the clean run, bit
    // for bit.
    sim.set_step_size(0.05).unwrap();
    sim.run(20, |_| {}).unwrap();
    clean.run(20, |_| {}).unwrap();
    assert_eq!(bits(sim.state()), bits(clean.state()));
}

#[test]
fn a_failed_step_through_the_problem_is_the_typed_error_with_the_state() {
    let options = NewtonOptions { max_iterations: 2, ..NewtonOptions::default() };
    let problem = Problem::new(Pendulum, 0.0, vec![3.0], vec![4.0]).newton(options);
    let mut sim = problem.stepper(&Scheme::galerkin(4), 4.0).unwrap();
    let before = bits(sim.state());
    let err = sim.step().unwrap_err();
    let state = match &err {
        Error::NewtonDidNotConverge { state, .. }
        | Error::SingularJacobian { state, .. }
        | Error::NonFinite { state, .. }
        | Error::StepRejected { state, .. } => state,
        other => panic!("unexpected error {other}"),
    };
    assert_eq!(bits(state), before);
    assert_eq!(bits(sim.state()), before);
    assert!(sim.run_until(8.0).is_err());
    assert_eq!(bits(sim.state()), before);
}

#[test]
fn degrees_and_quadratures_not_offered_are_refused() {
    let problem = Problem::new(Pendulum, 0.0, vec![1.0], vec![0.0]);
    for degree in [0, 17] {
        let scheme = Scheme::galerkin(degree);
        let Err(Error::Unsupported { what }) = problem.stepper(&scheme, 0.1) else { panic!("degree {degree}") };
        let query = lagrangian::problem::Combination {
            scheme: &scheme,
            policy: Policy::fixed(0.1),
            size: lagrangian::problem::Size::Dynamic,
            forced: false,
            constraints: 0,
            capability: Capability::Step,
        };
        assert_eq!(supports(&query), Err(what));
    }
    for degree in 1..=16 {
        assert!(problem.stepper(&Scheme::galerkin(degree), 0.1).is_ok(), "degree {degree}");
    }
    // Energy-balance steps with a Galerkin rule are refused at every size.
    let refused = problem.stepper(&Scheme::galerkin(2), Policy::energy_balance(0.1));
    assert!(matches!(refused, Err(Error::Unsupported { .. })));
    // The const-generic rule at a run-time size (the driver named directly:
    // `Scheme` has no such rule): a quadrature too weak for the degree.
    let weak = Galerkin::<3, 1>::new(NodeFamily::GaussLobatto, Quadrature::gauss_legendre());
    let err = lagrangian_runtime::DynIntegrator::new(Pendulum, weak, 0.1).start(0.0, &[1.0], &[0.0]).unwrap_err();
    assert!(matches!(err, Error::InvalidMethod { .. }), "{err}");
}
