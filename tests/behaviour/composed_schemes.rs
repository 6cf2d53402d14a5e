//! Compositions of the symmetric base methods other than the trapezoid
//! (midpoint, α-β at `α = ½`, the Galerkin rules) through the one way in:
//! `run_until` lands exactly on its targets, `solve` keeps its save times
//! and stops on a `Stop` event, the composed step is the base's steps of
//! sizes `γ_i h` (checked against the closed-form map of each base on the
//! harmonic oscillator, negative sub-steps included), a failed step leaves
//! the stepper as it was, and what is not defined is a typed refusal; at a
//! compile-time size and at a run-time size, where the composed step is
//! the compile-time one to round-off.

use super::run_time_systems::{DoublePendulumDyn, PENDULUM, PENDULUM_DYN};
use lagrangian::prelude::*;
use lagrangian::problem::{Combination, Size, supports};
use lagrangian::{Action, NewtonOptions, Status};

/// `L = ½v² − ½q²`: every base's step is a rotation of `(q, p)` by an
/// angle known in closed form.
#[derive(Clone)]
struct Oscillator;

#[lagrangian]
impl Oscillator {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * (v[0] * v[0] - q[0] * q[0])
    }
}

const Q0: [f64; 2] = [1.0, -0.5];
const V0: [f64; 2] = [0.0, 0.3];

/// The bases composed here, with the step of their runs.
fn bases() -> Vec<(Scheme, f64)> {
    let lobatto =
        Scheme::Galerkin { degree: 3, nodes: NodeFamily::GaussLobatto, quadrature: GalerkinQuadrature::GaussLobatto };
    vec![
        (Scheme::MIDPOINT, 0.02),
        (Scheme::alpha_beta(0.5).unwrap(), 0.02),
        (Scheme::galerkin(2), 0.05),
        (lobatto, 0.05),
        (Scheme::galerkin(4), 0.1),
    ]
}

fn weights() -> [Composition; 3] {
    [Composition::YOSHIDA4, Composition::YOSHIDA6, Composition::KAHAN_LI8]
}

#[test]
fn composed_bases_land_exactly_on_targets() {
    let problem = Problem::new(PENDULUM, 0.0, Q0, V0);
    for (base, h) in bases() {
        for weights in weights() {
            let scheme = base.clone().composed(weights);
            let mut sim = problem.stepper(&scheme, h).unwrap();
            for i in 1..=25 {
                let target = f64::from(i) * 0.0377;
                sim.run_until(target).unwrap();
                assert_eq!(sim.state().t.to_bits(), target.to_bits(), "{}: target {i}", scheme.name());
            }
            // The node counts composed steps; the energy stays near its start.
            let steps = sim.stats().steps;
            assert_eq!(sim.state().step, steps, "{}", scheme.name());
            assert!(steps >= (25.0 * 0.0377 / h) as u64, "{}: {steps} steps", scheme.name());
            let e0 = problem.stepper(&scheme, h).unwrap().energy().unwrap();
            let drift = (sim.energy().unwrap() - e0).abs() / e0.abs();
            assert!(drift < 1e-4, "{}: energy drift {drift:e}", scheme.name());
        }
    }
}

#[test]
fn composed_bases_solve_with_save_times_and_a_stop_event() {
    let problem = Problem::new(PENDULUM, 0.0, Q0, V0);
    let fine = problem.solve(&Scheme::galerkin(6), 0.005, Plan::until(1.3).every(0).save_at(vec![0.3, 0.9])).unwrap();
    for (base, h) in bases() {
        let scheme = base.composed(Composition::YOSHIDA6);
        let plan =
            Plan::until(2.0).every(3).save_at(vec![0.3, 0.9]).event(Event::new(|t, _, _| t - 1.3).action(Action::Stop));
        let mut sim = problem.stepper(&scheme, h).unwrap();
        let solution = sim.solve(plan).unwrap();
        let name = scheme.name();
        assert!(matches!(solution.status, Status::Stopped { event: 0, .. }), "{name}: {:?}", solution.status);
        let end = *solution.t.last().unwrap();
        assert!((end - 1.3).abs() < 1e-12, "{name}: stopped at {end}");
        assert_eq!(sim.state().t, end, "{name}: the stepper is at the stop");
        let saved: Vec<usize> = (0..solution.len()).filter(|&i| solution.step[i].is_none()).collect();
        assert_eq!(saved.iter().map(|&i| solution.t[i]).collect::<Vec<_>>(), [0.3, 0.9], "{name}");
        // The cubic Hermite over a whole step: its own error O(h⁴).
        for (row, &i) in saved.iter().enumerate() {
            for j in 0..2 {
                let error = (solution.q[i][j] - fine.q[row][j]).abs();
                assert!(error < 1e-4 * (h / 0.02).powi(4).max(1.0), "{name}: save {row}, q{j} off by {error:e}");
            }
        }
    }
}

/// The angle by which a step of size `tau` of `base` rotates the
/// oscillator's `(q, p)`: `2 atan(τ/2)` for the midpoint rule (the Cayley
/// map), the argument of the diagonal Padé approximant `R(iτ)` of `e^{iτ}`
/// for Gauss collocation of degree 2 and 3.
fn angle(base: &Scheme, tau: f64) -> f64 {
    match base.order() {
        2 => 2.0 * (tau / 2.0).atan(),
        4 => 2.0 * (tau / 2.0).atan2(1.0 - tau * tau / 12.0),
        6 => 2.0 * (tau / 2.0 - tau.powi(3) / 120.0).atan2(1.0 - tau * tau / 10.0),
        order => panic!("no closed form for order {order}"),
    }
}

#[test]
fn a_composed_step_is_the_base_steps_of_sizes_gamma_h() {
    let problem = Problem::new(Oscillator, 0.0, [1.0], [0.0]);
    let tight = NewtonOptions { rtol: 1e-15, ..NewtonOptions::default() };
    let h = 0.3;
    for base in [Scheme::MIDPOINT, Scheme::alpha_beta(0.5).unwrap(), Scheme::galerkin(2), Scheme::galerkin(3)] {
        for weights in weights() {
            let scheme = base.clone().composed(weights);
            let mut sim = problem.clone().newton(tight).stepper(&scheme, h).unwrap();
            let steps = 40;
            sim.run(steps, |_| {}).unwrap();
            // Every sub-step, the negative ones too, rotates by its own angle.
            let theta: f64 = weights.weights().iter().map(|g| angle(&base, g * h)).sum::<f64>() * steps as f64;
            let state = sim.state();
            let (q, p) = (state.q[0], state.p[0]);
            let error = (q - theta.cos()).abs().max((p + theta.sin()).abs());
            assert!(error < 1e-12, "{}: off the base's sub-steps by {error:e}", scheme.name());
            assert_eq!(state.t, steps as f64 * h, "{}", scheme.name());
        }
    }
}

#[test]
fn a_composed_midpoint_is_a_composed_alpha_beta_at_one_half() {
    let problem = Problem::new(PENDULUM, 0.0, Q0, V0);
    let mut midpoint = problem.stepper(&Scheme::MIDPOINT.composed(Composition::YOSHIDA4), 0.05).unwrap();
    let mut alpha_beta =
        problem.stepper(&Scheme::alpha_beta(0.5).unwrap().composed(Composition::YOSHIDA4), 0.05).unwrap();
    midpoint.run_until(1.0).unwrap();
    alpha_beta.run_until(1.0).unwrap();
    let (a, b) = (midpoint.state(), alpha_beta.state());
    for j in 0..2 {
        assert!((a.q[j] - b.q[j]).abs() < 1e-12 && (a.p[j] - b.p[j]).abs() < 1e-12, "{a:?} against {b:?}");
    }
}

/// The oscillator with `L` not finite for `a < t < b`: a window in time
/// where a chosen sub-step of a composed step evaluates it.
#[derive(Clone)]
struct Window {
    a: f64,
    b: f64,
}

#[lagrangian]
impl Window {
    fn lagrangian(&self, t: f64, q: [f64; 1], v: [f64; 1]) -> f64 {
        let window = 1.0 + 0.0 * ((t - self.a) * (t - self.b)).sqrt();
        0.5 * (v[0] * v[0] - q[0] * q[0] * window)
    }
}

#[test]
fn a_failed_composed_step_leaves_the_stepper_as_it_was() {
    let bits = |s: &lagrangian::State<1>| (s.step, s.t.to_bits(), s.q.map(f64::to_bits), s.p.map(f64::to_bits));
    // Yoshida 4 with h = 1 from t = 0: the midpoint sub-steps evaluate `L`
    // at t = 0.676, 0.5, 0.324 (the third fails), the Galerkin s = 2 ones
    // at 0.286, 1.066, then 0.991, 0.009 (the second fails).
    let gamma = Composition::YOSHIDA4.weights();
    let cases = [
        (Scheme::MIDPOINT, Window { a: 0.3, b: 0.35 }, gamma[2]),
        (Scheme::galerkin(2), Window { a: 0.005, b: 0.02 }, gamma[1]),
    ];
    for (base, window, failing) in cases {
        let scheme = base.composed(Composition::YOSHIDA4);
        let problem = Problem::new(window, 0.0, [1.0], [0.0]);
        let mut sim = problem.stepper(&scheme, 1.0).unwrap();
        let before = sim.clone();
        let err = sim.step().unwrap_err();
        let name = scheme.name();
        // The sub-step that fails is the one in the window.
        let h = match &err {
            Error::NonFinite { h, .. }
            | Error::NewtonDidNotConverge { h, .. }
            | Error::SingularJacobian { h, .. }
            | Error::StepRejected { h, .. } => *h,
            other => panic!("{name}: {other}"),
        };
        assert_eq!(h, failing, "{name}: {err}");
        assert_eq!(bits(&sim.state()), bits(&before.state()), "{name}: {err}");
        assert_eq!(sim.velocity().unwrap().map(f64::to_bits), before.velocity().unwrap().map(f64::to_bits), "{name}");
        let carried = err.state().expect("the error carries the state");
        assert_eq!((carried.step, carried.t, &carried.q[..]), (0, 0.0, &[1.0][..]), "{name}: {err}");
        assert_eq!(sim.stats().failed_steps, 1, "{name}");
        // It fails again as its copy from before does, and then steps on
        // past the window as the copy does, to the bit.
        assert_eq!(sim.step().unwrap_err(), before.clone().step().unwrap_err(), "{name}");
        let mut copy = before.clone();
        sim.run_until(0.25).unwrap();
        copy.run_until(0.25).unwrap();
        assert_eq!(bits(&sim.state()), bits(&copy.state()), "{name}");
    }
}

#[test]
fn undefined_compositions_are_typed_refusals() {
    let problem = Problem::new(PENDULUM, 0.0, Q0, V0);
    let curvature = Curvature::new(1.0).unwrap();
    let refusals = [
        (Scheme::alpha_beta(0.3).unwrap().composed(Composition::YOSHIDA4), Policy::fixed(0.01), "α ≠ ½"),
        (
            Scheme::MIDPOINT.composed(Composition::YOSHIDA4).composed(Composition::YOSHIDA4),
            Policy::fixed(0.01),
            "a composition of a composition",
        ),
        (
            Scheme::MIDPOINT.time_transformed(curvature).composed(Composition::YOSHIDA4),
            Policy::fixed(0.01),
            "of a time transformation",
        ),
        (
            Scheme::splitting(TimeFunction::Logarithmic, None).composed(Composition::YOSHIDA4),
            Policy::fixed(0.01),
            "of the splitting",
        ),
        (
            Scheme::MIDPOINT.composed(Composition::YOSHIDA4),
            Policy::energy_preserving(0.01),
            "variable steps with a composition",
        ),
        (Scheme::galerkin(9).composed(Composition::YOSHIDA4), Policy::fixed(0.01), "a Galerkin degree"),
    ];
    for (scheme, policy, says) in refusals {
        let Err(Error::Unsupported { what }) = problem.stepper(&scheme, policy) else {
            panic!("{}: not refused", scheme.name())
        };
        assert!(what.contains(says), "{}: {what}", scheme.name());
    }
    // Sensitivities of a composition of Newton sub-steps, and run-time sizes.
    let midpoint4 = Scheme::MIDPOINT.composed(Composition::YOSHIDA4);
    let mut query = Combination {
        scheme: &midpoint4,
        policy: Policy::fixed(0.01),
        size: Size::Const(2),
        forced: false,
        constraints: 0,
        capability: Capability::Sensitivities,
    };
    assert!(supports(&query).unwrap_err().contains("sensitivities of a composition of midpoint"));
    query.capability = Capability::Solve;
    assert!(supports(&query).is_ok());
    query.size = Size::Dynamic;
    assert!(supports(&query).is_ok());
    // The trapezoid compositions are those they were, and named so.
    let trapezoid = Scheme::composition(Composition::YOSHIDA6, OnePoint::Trapezoid);
    assert_eq!(trapezoid, Scheme::TRAPEZOID.composed(Composition::YOSHIDA6));
    assert_eq!(trapezoid.name(), "order-6 composition of trapezoid");
    assert_eq!(Scheme::galerkin(4).composed(Composition::YOSHIDA4).order(), 8);
    assert_eq!(Scheme::galerkin(4).composed(Composition::YOSHIDA4).name(), "order-8 composition of Galerkin s = 4");
}

fn run_time_problem() -> Problem<DoublePendulumDyn, Dyn> {
    Problem::new(PENDULUM_DYN, 0.0, Q0.to_vec(), V0.to_vec())
}

#[test]
fn run_time_composed_bases_land_exactly_on_targets() {
    let problem = run_time_problem();
    for (base, h) in bases() {
        for weights in weights() {
            let scheme = base.clone().composed(weights);
            let mut sim = problem.stepper(&scheme, h).unwrap();
            for i in 1..=25 {
                let target = f64::from(i) * 0.0377;
                sim.run_until(target).unwrap();
                assert_eq!(sim.state().t.to_bits(), target.to_bits(), "{}: target {i}", scheme.name());
            }
            let steps = sim.stats().steps;
            assert_eq!(sim.state().step, steps, "{}", scheme.name());
            assert!(steps >= (25.0 * 0.0377 / h) as u64, "{}: {steps} steps", scheme.name());
            assert_eq!(sim.last_step_size().map(f64::is_sign_positive), Some(true), "{}", scheme.name());
            assert_eq!(sim.step_size(), h, "{}: the step is restored after a landing", scheme.name());
            let e0 = problem.stepper(&scheme, h).unwrap().energy().unwrap();
            let drift = (sim.energy().unwrap() - e0).abs() / e0.abs();
            assert!(drift < 1e-4, "{}: energy drift {drift:e}", scheme.name());
        }
    }
}

/// The composed steps at a run-time size are those at a compile-time size:
/// the same sub-steps, each solved to `1e-15` by Newton (a tape in reverse
/// mode there, dual numbers here), so the nodes agree to round-off.
#[test]
fn run_time_composed_steps_are_the_compile_time_ones() {
    let tight = NewtonOptions { rtol: 1e-15, ..NewtonOptions::default() };
    let compiled = Problem::new(PENDULUM, 0.0, Q0, V0).newton(tight);
    let dynamic = run_time_problem().newton(tight);
    for (base, h) in bases() {
        for weights in weights() {
            let scheme = base.clone().composed(weights);
            let mut a = compiled.stepper(&scheme, h).unwrap();
            let mut b = dynamic.stepper(&scheme, h).unwrap();
            let mut gap: f64 = 0.0;
            for _ in 0..10 {
                let (x, y) = (a.step().unwrap(), b.step().unwrap().clone());
                assert_eq!((x.step, x.t.to_bits()), (y.step, y.t.to_bits()), "{}", scheme.name());
                for j in 0..2 {
                    gap = gap.max((x.q[j] - y.q[j]).abs()).max((x.p[j] - y.p[j]).abs());
                }
            }
            assert!(gap < 1e-12, "{}: {gap:e} between the sizes", scheme.name());
            assert_eq!(a.stats().newton_iterations > 0, b.stats().newton_iterations > 0, "{}", scheme.name());
        }
    }
}

/// [`Window`] over slices.
#[derive(Clone)]
struct WindowDyn {
    a: f64,
    b: f64,
}

#[lagrangian]
impl WindowDyn {
    fn dimension(&self) -> usize {
        1
    }

    fn lagrangian(&self, t: f64, q: &[f64], v: &[f64]) -> f64 {
        let window = 1.0 + 0.0 * ((t - self.a) * (t - self.b)).sqrt();
        0.5 * (v[0] * v[0] - q[0] * q[0] * window)
    }
}

#[test]
fn a_failed_run_time_composed_step_leaves_the_stepper_as_it_was() {
    let bits = |s: &lagrangian::PhasePoint| {
        let v = |x: &[f64]| x.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        (s.step, s.t.to_bits(), v(&s.q), v(&s.p))
    };
    // The windows of the compile-time test: the third sub-step of Yoshida 4
    // of midpoint fails, the second of Galerkin s = 2.
    let gamma = Composition::YOSHIDA4.weights();
    let cases = [
        (Scheme::MIDPOINT, WindowDyn { a: 0.3, b: 0.35 }, gamma[2]),
        (Scheme::galerkin(2), WindowDyn { a: 0.005, b: 0.02 }, gamma[1]),
    ];
    for (base, window, failing) in cases {
        let scheme = base.composed(Composition::YOSHIDA4);
        let problem = Problem::new(window, 0.0, vec![1.0], vec![0.0]);
        let mut sim = problem.stepper(&scheme, 1.0).unwrap();
        let before = sim.clone();
        let err = sim.step().unwrap_err();
        let name = scheme.name();
        let h = match &err {
            Error::NonFinite { h, .. }
            | Error::NewtonDidNotConverge { h, .. }
            | Error::SingularJacobian { h, .. }
            | Error::StepRejected { h, .. } => *h,
            other => panic!("{name}: {other}"),
        };
        assert_eq!(h, failing, "{name}: {err}");
        assert_eq!(bits(sim.state()), bits(before.state()), "{name}: {err}");
        let v = |s: &Stepper<WindowDyn, Dyn>| s.velocity().unwrap().iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(v(&sim), v(&before), "{name}");
        assert_eq!(sim.discrete_energy().to_bits(), before.discrete_energy().to_bits(), "{name}");
        let carried = err.state().expect("the error carries the state");
        assert_eq!((carried.step, carried.t, &carried.q[..]), (0, 0.0, &[1.0][..]), "{name}: {err}");
        assert_eq!(sim.stats().failed_steps, 1, "{name}");
        assert_eq!(sim.step().unwrap_err(), before.clone().step().unwrap_err(), "{name}");
        // Past the window, as the copy from before does, to the bit.
        let mut copy = before.clone();
        sim.run_until(0.25).unwrap();
        copy.run_until(0.25).unwrap();
        assert_eq!(bits(sim.state()), bits(copy.state()), "{name}");
        sim.run_until(2.5).unwrap();
        copy.run_until(2.5).unwrap();
        assert_eq!(bits(sim.state()), bits(copy.state()), "{name}: after the window");
    }
}

#[test]
fn undefined_compositions_at_a_run_time_size_are_typed_refusals() {
    let problem = run_time_problem();
    let refusals = [
        (Scheme::alpha_beta(0.3).unwrap().composed(Composition::YOSHIDA4), Policy::fixed(0.01), "α ≠ ½"),
        (
            Scheme::galerkin(2).composed(Composition::YOSHIDA4).composed(Composition::YOSHIDA4),
            Policy::fixed(0.01),
            "a composition of a composition",
        ),
        (
            Scheme::MIDPOINT.time_transformed(Curvature::new(1.0).unwrap()).composed(Composition::YOSHIDA4),
            Policy::fixed(0.01),
            "of a time transformation",
        ),
        (
            Scheme::galerkin(2).composed(Composition::YOSHIDA4),
            Policy::energy_preserving(0.01),
            "variable steps with a composition",
        ),
        (Scheme::galerkin(17).composed(Composition::YOSHIDA4), Policy::fixed(0.01), "a Galerkin degree"),
    ];
    for (scheme, policy, says) in refusals {
        let Err(Error::Unsupported { what }) = problem.stepper(&scheme, policy) else {
            panic!("{}: not refused", scheme.name())
        };
        assert!(what.contains(says), "{}: {what}", scheme.name());
    }
    let midpoint4 = Scheme::MIDPOINT.composed(Composition::YOSHIDA4);
    let refused = problem.supports(&midpoint4, 0.01, Capability::Sensitivities).unwrap_err();
    assert!(refused.to_string().contains("sensitivities"), "{refused}");
    assert!(problem.supports(&midpoint4, 0.01, Capability::Solve).is_ok());
}
