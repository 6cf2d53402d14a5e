//! Galerkin degrees 2 to 8 chosen at run time through `Scheme` on a
//! compile-time-sized `Problem`: each is the const-generic kernel of that
//! degree behind the dispatch (the same steps, bit for bit), with its own
//! step polynomial as dense output; other degrees are refused, typed.

use lagrangian::prelude::*;
use lagrangian::{Error, GalerkinIntegrator};

/// A quartic oscillator coupled to a harmonic one: non-linear, so that each
/// degree's steps differ in every bit.
#[derive(Clone)]
pub struct Coupled;

#[lagrangian]
impl Coupled {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) - 0.25 * q[0].powi(4) - 0.5 * q[1] * q[1] - 0.1 * q[0] * q[1]
    }
}

/// The harmonic oscillator `q = cos t`.
#[derive(Clone)]
pub struct Harmonic;

#[lagrangian]
impl Harmonic {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * (v[0] * v[0] - q[0] * q[0])
    }
}

const Q0: [f64; 2] = [1.0, -0.5];
const V0: [f64; 2] = [0.0, 0.3];

/// 60 steps of `Scheme::galerkin(S)` through `Problem` and of the
/// const-generic `Galerkin::<S, S>` named directly: the same nodes to the bit.
fn same_steps<const S: usize>() {
    let problem = Problem::new(Coupled, 0.0, Q0, V0);
    let mut dispatched = problem.stepper(&Scheme::galerkin(S), 0.2).unwrap();
    let direct = Galerkin::<S, S>::new(NodeFamily::GaussLobatto, Quadrature::gauss_legendre());
    let mut direct = GalerkinIntegrator::new(Coupled, direct, 0.2).start(0.0, Q0, V0).unwrap();
    for _ in 0..60 {
        let a = dispatched.step().unwrap();
        let b = *direct.step().unwrap();
        assert_eq!((a.t, a.q, a.p), (b.t, b.q, b.p), "degree {S}, step {}", b.step);
    }
    assert_eq!(dispatched.stats().newton_iterations, direct.stats().newton_iterations);
}

#[test]
fn degrees_five_to_eight_step_as_their_const_generic_kernels() {
    same_steps::<5>();
    same_steps::<6>();
    same_steps::<7>();
    same_steps::<8>();
}

#[test]
fn energy_preserving_steps_of_a_high_degree_are_its_kernels_steps() {
    // Energy-preserving steps of degree 6: each step size solves the
    // discrete energy equation; through `Scheme` the same steps as the
    // kernel named directly, and the energy stays at its start.
    let problem = Problem::new(Coupled, 0.0, Q0, V0);
    let mut dispatched = problem.stepper(&Scheme::galerkin(6), Policy::energy_preserving(0.2)).unwrap();
    let rule = Galerkin::<6, 6>::new(NodeFamily::GaussLobatto, Quadrature::gauss_legendre());
    let mut direct = GalerkinIntegrator::new(Coupled, rule, 0.2)
        .energy_preserving(StepBounds::around(0.2))
        .start(0.0, Q0, V0)
        .unwrap();
    let e0 = dispatched.energy().unwrap();
    let mut worst = 0.0f64;
    for _ in 0..100 {
        let a = dispatched.step().unwrap();
        let b = *direct.step().unwrap();
        assert_eq!((a.t, a.q, a.p), (b.t, b.q, b.p), "step {}", b.step);
        worst = worst.max((dispatched.energy().unwrap() - e0).abs());
    }
    // Order 12 at h = 0.2: the energy of the nodes within 1e-9 of its start.
    assert!(worst < 1e-9, "energy error {worst:.2e}");
}

#[test]
fn a_high_degree_interpolates_with_its_step_polynomial() {
    // Steps of 0.5: the cubic Hermite of the nodes misses `cos t` between
    // them by about h⁴/384 ≈ 2e-4; the step polynomial of degree 8 (order 16
    // at the nodes, degree 8 between them) by about 1e-9.
    let problem = Problem::new(Harmonic, 0.0, [1.0], [0.0]);
    let save: Vec<f64> = (0..20).map(|i| 0.37 + 0.5 * i as f64).collect();
    let plan = Plan::until(10.0).every(0).save_at(save.clone());
    let solution = problem.solve(&Scheme::galerkin(8), 0.5, plan).unwrap().into_result().unwrap();
    assert_eq!(solution.t, save);
    let worst = (0..solution.len()).map(|i| (solution.q[i][0] - solution.t[i].cos()).abs()).fold(0.0, f64::max);
    assert!(worst < 1e-8, "dense output error {worst:.2e}");
    // At the nodes, order 16: round-off.
    let mut sim = problem.stepper(&Scheme::galerkin(8), 0.5).unwrap();
    sim.run_until(10.0).unwrap();
    assert!((sim.state().q[0] - 10f64.cos()).abs() < 1e-13);
}

#[test]
fn other_degrees_are_refused_naming_what_is_offered() {
    let problem = Problem::new(Harmonic, 0.0, [1.0], [0.0]);
    let lobatto = |degree| Scheme::Galerkin {
        degree,
        nodes: NodeFamily::GaussLobatto,
        quadrature: GalerkinQuadrature::GaussLobatto,
    };
    assert!(problem.stepper(&lobatto(4), 0.1).is_ok());
    for scheme in [Scheme::galerkin(1), Scheme::galerkin(9), lobatto(5)] {
        let refused = problem.stepper(&scheme, 0.1).unwrap_err();
        let Error::Unsupported { what } = refused else { panic!("{scheme:?}: {refused:?}") };
        assert!(
            what.contains("other than 2 to 8 with Gauss–Legendre quadrature or 2 to 4 with Gauss–Lobatto"),
            "{what}"
        );
        assert_eq!(
            problem.supports(&scheme, 0.1, Capability::Step).unwrap_err().to_string(),
            format!("not supported yet: {what}")
        );
    }
    // Under a time transformation the degrees in `s` stay 2 to 4.
    let density = Curvature::new(1.0).unwrap();
    assert!(problem.stepper(&Scheme::galerkin(4).time_transformed(density), 0.1).is_ok());
    assert!(matches!(
        problem.stepper(&Scheme::galerkin(6).time_transformed(density), 0.1),
        Err(Error::Unsupported { .. })
    ));
}
