//! Every capability on a chain of `N` masses in a thread with the default
//! 2 MiB stack: it takes a few steps, or `start` refuses it with
//! [`Error::Unsupported`] where no path exists at that size (forward-mode
//! capabilities above `Derivatives::FORWARD_MAX_N`); it never overflows the
//! stack (which aborts the whole test process, naming the thread of the case
//! that overflowed).
//!
//! The sizes are 32, the largest forward-mode system
//! (`Derivatives::FORWARD_MAX_N`, where the forward paths' `N²` dual values
//! are largest), and 256, far into reverse mode: every size between runs the
//! code of one of these two with smaller arrays, so a stack use growing with
//! `N`, with `N²` or with the integrator's size shows at these two first
//! (each size compiles every capability once more). The chain is written by
//! hand, without the macro's gradient code, so that every path takes its
//! derivatives from dual numbers, the largest values any path carries.

use std::fmt::Debug;

use lagrangian_runtime::dim::{Dim, ExtendedSize};
use lagrangian_runtime::galerkin::Galerkin;
use lagrangian_runtime::{
    Action, AlphaBeta, Composition, DenseKind, Derivatives, DoubleDouble, Error, Event, ExplicitTimeTransformed,
    Integrator, Lagrangian, Midpoint, Plan, RadiusPower, Real, Scalar, Separability, SolveError, Status, StepBounds,
    Stepping, TimeFunction, TimeTransformed, Trapezoid,
};

/// The default stack of a spawned thread.
const STACK: usize = 2 << 20;

/// An FPU-β chain with fixed ends, `L = ½|v|² − Σ ½(Δq)² + ¼β(Δq)⁴`; with
/// `FORCED` a linear drag `−γv` as an applied force; with `SEPARABLE` its
/// constant mass matrix declared (as the macro would prove it), which the
/// explicit paths need.
#[derive(Clone, Copy, Debug)]
struct Chain<const N: usize, const FORCED: bool = false, const SEPARABLE: bool = false>;

impl<const N: usize, const FORCED: bool, const SEPARABLE: bool> Lagrangian<N> for Chain<N, FORCED, SEPARABLE> {
    const AUTONOMOUS: bool = true;
    const CYCLIC: [bool; N] = [false; N];
    const SEPARABILITY: Separability = if SEPARABLE { Separability::ConstantMass } else { Separability::NotProven };
    const HAS_FORCE: bool = FORCED;

    fn lagrangian<D: Scalar>(&self, _t: D, q: [D; N], v: [D; N]) -> D {
        let mut l = D::zero();
        for i in 0..N {
            l += v[i] * v[i] * 0.5;
        }
        for i in 0..=N {
            let left = if i == 0 { D::zero() } else { q[i - 1] };
            let right = if i == N { D::zero() } else { q[i] };
            let d = right - left;
            let d2 = d * d;
            l -= d2 * 0.5 + d2 * d2 * 0.25;
        }
        l
    }

    fn force<D: Scalar>(&self, _t: D, _q: [D; N], v: [D; N]) -> [D; N] {
        v.map(|v| v * -0.01)
    }
}

/// The lowest mode of the chain, from rest.
fn initial<const N: usize>() -> ([f64; N], [f64; N]) {
    let q = core::array::from_fn(|i| 0.3 * (core::f64::consts::PI * (i + 1) as f64 / (N + 1) as f64).sin());
    (q, [0.0; N])
}

/// What a case did: took its steps, or was refused at `start` with
/// [`Error::Unsupported`] (and why).
#[derive(Debug, PartialEq)]
enum Outcome {
    Ran,
    Unsupported(&'static str),
}

/// Takes three steps of `start`'s integrator, or records its refusal, which
/// must be [`Error::Unsupported`]: any other error at `start`, or any failed
/// step after a successful one, fails the test.
fn run<I, T: Real, F: Debug>(start: Result<I, Error<T>>, mut step: impl FnMut(&mut I) -> Result<(), F>) -> Outcome {
    match start {
        Ok(mut sim) => {
            for k in 0..3 {
                if let Err(e) = step(&mut sim) {
                    panic!("step {k} failed after a successful start: {e:?}");
                }
            }
            Outcome::Ran
        }
        Err(Error::Unsupported { what }) => Outcome::Unsupported(what),
        Err(e) => panic!("start failed with an error other than `Unsupported`: {e:?}"),
    }
}

/// Runs `case` in a thread of its own with the default 2 MiB stack, named
/// after the case so that an overflow names it.
fn in_small_thread(name: String, case: impl FnOnce() -> Outcome + Send + 'static) -> (String, Outcome) {
    let outcome = std::thread::Builder::new().name(name.clone()).stack_size(STACK).spawn(case).unwrap().join();
    (name.clone(), outcome.unwrap_or_else(|_| panic!("{name}: panicked")))
}

/// A case, run in a thread of its own.
type Case = Box<dyn FnOnce() -> Outcome + Send>;

/// Whether a case needs forward-mode derivatives (forces, energy-preserving
/// steps, Galerkin rules, `DoubleDouble`, `Derivatives::Forward`): those
/// run up to `Derivatives::FORWARD_MAX_N` and are refused above it.
#[derive(Clone, Copy, PartialEq)]
enum Needs {
    AnyMode,
    ForwardMode,
}

/// Every capability at size `N`; `M = N + 1` for the time-transformed system.
fn capabilities<const N: usize, const M: usize>() -> Vec<(String, Outcome)>
where
    Dim<N>: ExtendedSize<M>,
{
    let h = 0.05;
    let bounds = StepBounds::around(h);
    let mut cases: Vec<(String, Needs, Case)> = Vec::new();
    let mut add = |name: &str, needs: Needs, case: Case| {
        cases.push((format!("{name}, N = {N}"), needs, case));
    };
    add(
        "midpoint",
        Needs::AnyMode,
        Box::new(move || {
            let (q, v) = initial::<N>();
            run(Integrator::new(Chain::<N>, Midpoint, h).start(0.0, q, v), |s| s.step().map(drop))
        }),
    );
    add(
        "midpoint, forward mode",
        Needs::ForwardMode,
        Box::new(move || {
            let (q, v) = initial::<N>();
            let sim = Integrator::new(Chain::<N>, Midpoint, h).derivatives(Derivatives::Forward).start(0.0, q, v);
            run(sim, |s| s.step().map(drop))
        }),
    );
    add(
        "trapezoid",
        Needs::AnyMode,
        Box::new(move || {
            let (q, v) = initial::<N>();
            run(Integrator::new(Chain::<N>, Trapezoid, h).start(0.0, q, v), |s| s.step().map(drop))
        }),
    );
    add(
        "trapezoid, explicit",
        Needs::AnyMode,
        Box::new(move || {
            let (q, v) = initial::<N>();
            run(Integrator::new(Chain::<N, false, true>, Trapezoid, h).start(0.0, q, v), |s| s.step().map(drop))
        }),
    );
    add(
        "α-β",
        Needs::AnyMode,
        Box::new(move || {
            let (q, v) = initial::<N>();
            let rule = AlphaBeta::new(0.3).unwrap();
            run(Integrator::new(Chain::<N>, rule, h).start(0.0, q, v), |s| s.step().map(drop))
        }),
    );
    add(
        "midpoint, forced",
        Needs::ForwardMode,
        Box::new(move || {
            let (q, v) = initial::<N>();
            run(Integrator::new(Chain::<N, true>, Midpoint, h).start(0.0, q, v), |s| s.step().map(drop))
        }),
    );
    add(
        "trapezoid, forced",
        Needs::ForwardMode,
        Box::new(move || {
            let (q, v) = initial::<N>();
            run(Integrator::new(Chain::<N, true>, Trapezoid, h).start(0.0, q, v), |s| s.step().map(drop))
        }),
    );
    add(
        "α-β, forced",
        Needs::ForwardMode,
        Box::new(move || {
            let (q, v) = initial::<N>();
            let rule = AlphaBeta::new(0.3).unwrap();
            run(Integrator::new(Chain::<N, true>, rule, h).start(0.0, q, v), |s| s.step().map(drop))
        }),
    );
    add(
        "energy-preserving midpoint",
        Needs::ForwardMode,
        Box::new(move || {
            let (q, v) = initial::<N>();
            let sim = Integrator::new(Chain::<N>, Midpoint, h).energy_preserving(bounds).start(0.0, q, v);
            run(sim, |s| s.step().map(drop))
        }),
    );
    add(
        "energy-preserving trapezoid",
        Needs::ForwardMode,
        Box::new(move || {
            let (q, v) = initial::<N>();
            let sim = Integrator::new(Chain::<N>, Trapezoid, h).energy_preserving(bounds).start(0.0, q, v);
            run(sim, |s| s.step().map(drop))
        }),
    );
    add(
        "energy-balance midpoint, forced",
        Needs::ForwardMode,
        Box::new(move || {
            let (q, v) = initial::<N>();
            let sim = Integrator::new(Chain::<N, true>, Midpoint, h).energy_preserving(bounds).start(0.0, q, v);
            run(sim, |s| s.step().map(drop))
        }),
    );
    add(
        "Galerkin s = 2",
        Needs::ForwardMode,
        Box::new(move || {
            let (q, v) = initial::<N>();
            run(Integrator::new(Chain::<N>, Galerkin::<2, 2>::gauss(), h).start(0.0, q, v), |s| s.step().map(drop))
        }),
    );
    add(
        "Galerkin s = 2, forced",
        Needs::ForwardMode,
        Box::new(move || {
            let (q, v) = initial::<N>();
            let sim = Integrator::new(Chain::<N, true>, Galerkin::<2, 2>::gauss(), h).start(0.0, q, v);
            run(sim, |s| s.step().map(drop))
        }),
    );
    add(
        "Galerkin s = 5 (sN = 80 at N = 16)",
        Needs::ForwardMode,
        Box::new(move || {
            let (q, v) = initial::<N>();
            run(Integrator::new(Chain::<N>, Galerkin::<5, 5>::gauss(), h).start(0.0, q, v), |s| s.step().map(drop))
        }),
    );
    add(
        "Galerkin s = 6 (sN = 96 at N = 16)",
        Needs::ForwardMode,
        Box::new(move || {
            let (q, v) = initial::<N>();
            run(Integrator::new(Chain::<N>, Galerkin::<6, 6>::gauss(), h).start(0.0, q, v), |s| s.step().map(drop))
        }),
    );
    add(
        "Galerkin s = 2 in DoubleDouble",
        Needs::ForwardMode,
        Box::new(move || {
            let (q, v) = initial::<N>();
            let dd = DoubleDouble::from;
            let sim = Integrator::new(Chain::<N>, Galerkin::<2, 2, DoubleDouble>::gauss(), dd(h)).start(
                dd(0.0),
                q.map(dd),
                v.map(dd),
            );
            run(sim, |s| s.step().map(drop))
        }),
    );
    add(
        "energy-preserving Galerkin s = 2",
        Needs::ForwardMode,
        Box::new(move || {
            let (q, v) = initial::<N>();
            let sim = Integrator::new(Chain::<N>, Galerkin::<2, 2>::gauss(), h).energy_preserving(bounds);
            run(sim.start(0.0, q, v), |s| s.step().map(drop))
        }),
    );
    add(
        "Yoshida 4",
        Needs::AnyMode,
        Box::new(move || {
            let (q, v) = initial::<N>();
            run(Integrator::new(Chain::<N>, Composition::YOSHIDA4, h).start(0.0, q, v), |s| s.step().map(drop))
        }),
    );
    add(
        "midpoint, solve",
        Needs::AnyMode,
        Box::new(move || {
            let (q, v) = initial::<N>();
            let sim = Integrator::new(Chain::<N>, Midpoint, h).start(0.0, q, v);
            run(sim, |s| s.solve(Plan::until(s.state().t + 2.0 * h).every(1)).map(drop))
        }),
    );
    add(
        "Galerkin s = 2, solve",
        Needs::ForwardMode,
        Box::new(move || {
            let (q, v) = initial::<N>();
            let sim = Integrator::new(Chain::<N>, Galerkin::<2, 2>::gauss(), h).start(0.0, q, v);
            run(sim, |s| s.solve(Plan::until(s.state().t + 2.0 * h).every(1)).map(drop))
        }),
    );
    add(
        "midpoint in DoubleDouble",
        Needs::ForwardMode,
        Box::new(move || {
            let (q, v) = initial::<N>();
            let sim = Integrator::new(Chain::<N>, Midpoint, DoubleDouble::from(h)).start(
                DoubleDouble::from(0.0),
                q.map(DoubleDouble::from),
                v.map(DoubleDouble::from),
            );
            run(sim, |s| s.step().map(drop))
        }),
    );
    add(
        "time-transformed midpoint",
        Needs::AnyMode,
        Box::new(move || {
            let (q, v) = initial::<N>();
            let density = RadiusPower::new([0], 0.0).unwrap();
            let sim = TimeTransformed::new(Chain::<N>, density).rule(Midpoint, h).start::<M>(0.0, q, v);
            run(sim, |s| s.step().map(drop))
        }),
    );
    add(
        "explicit time-transformed",
        Needs::AnyMode,
        Box::new(move || {
            let (q, v) = initial::<N>();
            let sim =
                ExplicitTimeTransformed::new(Chain::<N, false, true>, TimeFunction::Logarithmic, h).start(0.0, q, v);
            run(sim, |s| s.step().map(drop))
        }),
    );
    add(
        "explicit time-transformed, solve",
        Needs::AnyMode,
        Box::new(move || {
            let (q, v) = initial::<N>();
            let sim =
                ExplicitTimeTransformed::new(Chain::<N, false, true>, TimeFunction::Logarithmic, h).start(0.0, q, v);
            run(sim, |s| solve_with_events(s, h, DenseKind::Native))
        }),
    );
    add(
        "time-transformed midpoint, solve",
        Needs::AnyMode,
        Box::new(move || {
            let (q, v) = initial::<N>();
            let density = RadiusPower::new([0], 0.0).unwrap();
            let sim = TimeTransformed::new(Chain::<N>, density).rule(Midpoint, h).start::<M>(0.0, q, v);
            run(sim, |s| solve_with_events(s, h, DenseKind::Native))
        }),
    );
    add(
        "midpoint, solve with quintic dense output and events",
        Needs::AnyMode,
        Box::new(move || {
            let (q, v) = initial::<N>();
            let sim = Integrator::new(Chain::<N>, Midpoint, h).start(0.0, q, v);
            run(sim, |s| solve_with_events(s, h, DenseKind::Quintic))
        }),
    );
    add(
        "Yoshida 4, solve with events",
        Needs::AnyMode,
        Box::new(move || {
            let (q, v) = initial::<N>();
            let sim = Integrator::new(Chain::<N>, Composition::YOSHIDA4, h).start(0.0, q, v);
            run(sim, |s| solve_with_events(s, h, DenseKind::Native))
        }),
    );
    add(
        "Galerkin s = 2, solve with events",
        Needs::ForwardMode,
        Box::new(move || {
            let (q, v) = initial::<N>();
            let sim = Integrator::new(Chain::<N>, Galerkin::<2, 2>::gauss(), h).start(0.0, q, v);
            run(sim, |s| solve_with_events(s, h, DenseKind::Native))
        }),
    );
    add(
        "midpoint, forward mode, tangent map",
        Needs::ForwardMode,
        Box::new(move || {
            let (q, v) = initial::<N>();
            let sim = Integrator::new(Chain::<N>, Midpoint, h).derivatives(Derivatives::Forward).start(0.0, q, v);
            run(sim, |s| {
                s.step()?;
                let map = s.last_tangent_map().expect("a tangent map after a step");
                assert!(map.symplecticity_defect() < 1e-10, "{}", map.symplecticity_defect());
                Ok::<_, Error>(())
            })
        }),
    );
    add(
        "Galerkin s = 2, tangent map",
        Needs::ForwardMode,
        Box::new(move || {
            let (q, v) = initial::<N>();
            let sim = Integrator::new(Chain::<N>, Galerkin::<2, 2>::gauss(), h).start(0.0, q, v);
            run(sim, |s| {
                s.step()?;
                let map = s.last_tangent_map().expect("a tangent map after a step");
                assert!(map.symplecticity_defect() < 1e-10, "{}", map.symplecticity_defect());
                Ok::<_, Error>(())
            })
        }),
    );
    cases
        .into_iter()
        .map(|(name, needs, case)| {
            let (name, outcome) = in_small_thread(name, case);
            let forward_only_above_limit = needs == Needs::ForwardMode && N > Derivatives::FORWARD_MAX_N;
            match &outcome {
                Outcome::Ran => assert!(!forward_only_above_limit, "{name}: ran above `FORWARD_MAX_N`"),
                Outcome::Unsupported(why) => {
                    assert!(forward_only_above_limit, "{name}: refused where it has a path: {why}");
                }
            }
            (name, outcome)
        })
        .collect()
}

/// Solves two steps' worth of time from the integrator's state, every node
/// kept, with an event recorded and one landed on by dense output of the
/// kind asked for; both must be found.
fn solve_with_events<I: Stepping<N> + Clone, const N: usize>(
    sim: &mut I,
    h: f64,
    dense: DenseKind,
) -> Result<(), SolveError> {
    let t0 = sim.state().t;
    let plan = Plan::until(t0 + 2.0 * h)
        .every(1)
        .dense(dense)
        .event(Event::new(move |t, q: &[f64], _| t - (t0 + 0.3 * h) + 0.0 * q[0]).action(Action::Record))
        .event(Event::new(move |t, _, v: &[f64]| t - (t0 + 1.4 * h) + 0.0 * v[0]).action(Action::Land));
    let solution = sim.solve(plan)?;
    assert_eq!(solution.status, Status::Finished);
    assert_eq!(solution.events.len(), 2, "{:?}", solution.events.iter().map(|e| e.t).collect::<Vec<_>>());
    Ok(())
}

/// Prints the table of outcomes (the assertions are in `capabilities`).
fn report(outcomes: Vec<(String, Outcome)>) {
    for (name, outcome) in outcomes {
        match outcome {
            Outcome::Ran => println!("{name}: runs"),
            Outcome::Unsupported(why) => println!("{name}: unsupported: {why}"),
        }
    }
}

#[test]
fn every_capability_at_32_fits_a_2_mib_thread() {
    report(capabilities::<32, 33>());
}

#[test]
fn every_capability_at_256_fits_a_2_mib_thread() {
    report(capabilities::<256, 257>());
}
