//! Verification: how increments are added to the state (`Summation`).
//!
//! Every method here is exact for a body falling in a uniform field (the
//! trapezoid rule is Störmer–Verlet, which integrates a constant force
//! exactly; so do its compositions and the midpoint rule), so what separates
//! a run from `q(t) = q_0 + v_0 t − ½ g t²` is round-off alone. With
//! compensated sums (the default) the state stays within a few ulp of it
//! after 10⁵ steps at coordinates of a thousand; with plain sums each step
//! rounds `q_k + Δq` to `ulp(q)`, and the error grows with the number of
//! steps, as it does in a hand-written integrator. Plain summation is the
//! same method otherwise: forward and reverse mode, and the const-size and
//! run-time-sized integrators, take the same steps bit for bit, and a failed
//! step leaves no trace.
use lagrangian::prelude::*;
use lagrangian::{Composition, Derivatives, Summation};
// The run-time-sized driver named directly: `Summation::Plain` is its
// setting (`Problem` keeps the compensated sums).
use lagrangian_runtime::{DynIntegrator, DynMethod};

/// The field's strengths: a drop of 50 and 100 over `t = 1000`.
const G: [f64; 2] = [1e-4, 2e-4];

/// `L = ½|v|² − g·q`: a body falling in a uniform field.
#[derive(Clone)]
struct Falling;

#[lagrangian]
impl Falling {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) - (1e-4 * q[0] + 2e-4 * q[1])
    }
}

/// [`Falling`] of run-time size (two coordinates).
struct DynFalling;

#[lagrangian]
impl DynFalling {
    fn dimension(&self) -> usize {
        2
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) - (1e-4 * q[0] + 2e-4 * q[1])
    }
}

/// `L = ½|v|² + 1/|q|`: separable, unit mass.
#[derive(Clone)]
struct Kepler;

#[lagrangian]
impl Kepler {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) + 1.0 / (q[0] * q[0] + q[1] * q[1]).sqrt()
    }
}

/// The falling body's start: far from the origin, so that `ulp(q) ≈ 2e-13`
/// is large against the increments `|Δq| ≈ 0.01`.
const Q0: [f64; 2] = [1000.0, -3000.0];
const V0: [f64; 2] = [1.0, 0.5];
const H: f64 = 0.01;
const STEPS: usize = 100_000;

/// Largest `|q − q_exact|` after [`STEPS`] steps of `method`.
fn error<M: Method<f64>>(method: M, summation: Summation, derivatives: Derivatives) -> f64 {
    let mut sim =
        Integrator::new(Falling, method, H).summation(summation).derivatives(derivatives).start(0.0, Q0, V0).unwrap();
    sim.run(STEPS, |_| {}).unwrap();
    let t = sim.state().t;
    let exact = |i: usize| Q0[i] + V0[i] * t - 0.5 * G[i] * t * t;
    (0..2).map(|i| (sim.state().q[i] - exact(i)).abs()).fold(0.0, f64::max)
}

/// A run of [`error`] with one method.
type Run = fn(Summation, Derivatives) -> f64;

#[test]
fn compensated_sums_keep_the_state_at_round_off_and_plain_ones_do_not() {
    let runs: [(&str, Run); 3] = [
        ("trapezoid (explicit)", |s, d| error(Trapezoid, s, d)),
        ("yoshida 4 (fused)", |s, d| error(Composition::YOSHIDA4, s, d)),
        ("midpoint (newton)", |s, d| error(Midpoint, s, d)),
    ];
    for (name, run) in runs {
        for derivatives in [Derivatives::Forward, Derivatives::Reverse] {
            let compensated = run(Summation::Compensated, derivatives);
            let plain = run(Summation::Plain, derivatives);
            println!(
                "{name}, {derivatives:?}: 1e5 steps at |q| ~ 1e3, error compensated {compensated:.1e}, plain {plain:.1e}"
            );
            // A few ulp(3000) = 4.5e-13 (the exact solution is itself
            // evaluated in `f64`).
            assert!(compensated <= 2e-12, "{name} {derivatives:?}: {compensated:e}");
            // Each plain step rounds to ulp(q) ≈ 2.3e-13–4.5e-13: over 1e5
            // steps the errors add up to far more than the compensated run's.
            assert!(plain >= 100.0 * compensated.max(1e-13), "{name} {derivatives:?}: {plain:e}");
        }
    }
}

/// Max |difference| of two states.
fn state_difference(a: &State<2>, b: &State<2>) -> f64 {
    (0..2).map(|i| (a.q[i] - b.q[i]).abs().max((a.p[i] - b.p[i]).abs())).fold(0.0, f64::max)
}

#[test]
fn plain_sums_are_the_same_method_to_round_off() {
    // An eccentric Kepler orbit (e = 0.44) over 1000 steps: plain and
    // compensated sums differ by round-off only.
    fn run<M: Method<f64>>(method: M, summation: Summation) -> Integrator<Kepler, M, 2> {
        let mut sim =
            Integrator::new(Kepler, method, 0.01).summation(summation).start(0.0, [1.0, 0.0], [0.0, 1.2]).unwrap();
        sim.run(1000, |_| {}).unwrap();
        sim
    }
    let trapezoid =
        state_difference(run(Trapezoid, Summation::Plain).state(), run(Trapezoid, Summation::Compensated).state());
    let midpoint =
        state_difference(run(Midpoint, Summation::Plain).state(), run(Midpoint, Summation::Compensated).state());
    let kahan_li = state_difference(
        run(Composition::KAHAN_LI8, Summation::Plain).state(),
        run(Composition::KAHAN_LI8, Summation::Compensated).state(),
    );
    println!(
        "kepler, 1000 steps, plain against compensated: trapezoid {trapezoid:.1e}, midpoint {midpoint:.1e}, kahan-li 8 {kahan_li:.1e}"
    );
    for (name, d) in [("trapezoid", trapezoid), ("midpoint", midpoint), ("kahan-li 8", kahan_li)] {
        assert!(d > 0.0 && d <= 1e-12, "{name}: {d:e}");
    }
}

#[test]
fn plain_sums_take_the_same_steps_in_forward_and_reverse_mode() {
    fn start<M: Method<f64>>(method: M, derivatives: Derivatives) -> Integrator<Kepler, M, 2> {
        Integrator::new(Kepler, method, 0.01)
            .summation(Summation::Plain)
            .derivatives(derivatives)
            .start(0.0, [1.0, 0.0], [0.0, 1.2])
            .unwrap()
    }
    for (name, method) in [
        ("yoshida 4", Composition::YOSHIDA4),
        ("yoshida 6", Composition::YOSHIDA6),
        ("kahan-li 8", Composition::KAHAN_LI8),
    ] {
        let mut forward = start(method, Derivatives::Forward);
        let mut reverse = start(method, Derivatives::Reverse);
        forward.run(1000, |_| {}).unwrap();
        reverse.run(1000, |_| {}).unwrap();
        assert_eq!(forward.state(), reverse.state(), "{name}");
        // The readouts of the last sub-step, rebuilt from the in-place sums
        // (forward mode) or kept (reverse mode); the two modes evaluate the
        // energy with different derivative code, hence a tolerance.
        let (e_forward, e_reverse) = (forward.discrete_energy(), reverse.discrete_energy());
        assert!((e_forward - e_reverse).abs() <= 1e-15 * e_forward.abs(), "{name}: {e_forward} {e_reverse}");
        let (v_forward, v_reverse) = (forward.velocity().unwrap(), reverse.velocity().unwrap());
        assert!((0..2).all(|i| (v_forward[i] - v_reverse[i]).abs() <= 1e-15), "{name}: {v_forward:?} {v_reverse:?}");
    }
    let (mut forward, mut reverse) = (start(Trapezoid, Derivatives::Forward), start(Trapezoid, Derivatives::Reverse));
    forward.run(1000, |_| {}).unwrap();
    reverse.run(1000, |_| {}).unwrap();
    assert_eq!(forward.state(), reverse.state(), "trapezoid");
    assert_eq!(forward.velocity().unwrap(), reverse.velocity().unwrap(), "trapezoid");
}

#[test]
fn run_time_sized_plain_steps_are_the_const_size_ones() {
    fn compare<M: Method<f64> + DynMethod + Copy>(name: &str, method: M) {
        let mut fixed = Integrator::new(Falling, method, H)
            .summation(Summation::Plain)
            .derivatives(Derivatives::Reverse)
            .start(0.0, Q0, V0)
            .unwrap();
        let mut dynamic =
            DynIntegrator::new(DynFalling, method, H).summation(Summation::Plain).start(0.0, &Q0, &V0).unwrap();
        assert_eq!(dynamic.summation(), Summation::Plain);
        fixed.run(2000, |_| {}).unwrap();
        dynamic.run(2000, |_| {}).unwrap();
        assert_eq!(&fixed.state().q[..], &dynamic.state().q[..], "{name}");
        assert_eq!(&fixed.state().p[..], &dynamic.state().p[..], "{name}");
    }
    compare("trapezoid", Trapezoid);
    compare("yoshida 4", Composition::YOSHIDA4);
    compare("midpoint", Midpoint);
}

#[test]
fn a_failed_plain_step_leaves_no_trace() {
    // A step of 1e300 overflows the positions; the retry with the old step
    // size continues as if it had never been tried.
    fn check<M: Method<f64> + Copy>(name: &str, method: M, derivatives: Derivatives) {
        let start = || {
            Integrator::new(Falling, method, H)
                .summation(Summation::Plain)
                .derivatives(derivatives)
                .start(0.0, Q0, V0)
                .unwrap()
        };
        let (mut clean, mut retried) = (start(), start());
        clean.run(20, |_| {}).unwrap();
        retried.run(10, |_| {}).unwrap();
        retried.set_step_size(1e300).unwrap();
        assert!(retried.step().is_err(), "{name}: the step of 1e300 must fail");
        retried.set_step_size(H).unwrap();
        retried.run(10, |_| {}).unwrap();
        assert_eq!(clean.state(), retried.state(), "{name} {derivatives:?}");
    }
    for derivatives in [Derivatives::Forward, Derivatives::Reverse] {
        check("trapezoid", Trapezoid, derivatives);
        check("yoshida 4", Composition::YOSHIDA4, derivatives);
        check("midpoint", Midpoint, derivatives);
    }
    let start = || {
        DynIntegrator::new(DynFalling, Composition::YOSHIDA4, H)
            .summation(Summation::Plain)
            .start(0.0, &Q0, &V0)
            .unwrap()
    };
    let (mut clean, mut retried) = (start(), start());
    clean.run(20, |_| {}).unwrap();
    retried.run(10, |_| {}).unwrap();
    retried.set_step_size(1e300).unwrap();
    assert!(retried.step().is_err(), "run-time-sized: the step of 1e300 must fail");
    retried.set_step_size(H).unwrap();
    retried.run(10, |_| {}).unwrap();
    assert_eq!(clean.state(), retried.state(), "run-time-sized");
}
