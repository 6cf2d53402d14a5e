//! Every capability on a chain of `N` masses in a thread with the default
//! 2 MiB stack: it takes a few steps or refuses with a typed error at
//! `start`, never overflows the stack (which aborts the whole test process,
//! naming the thread of the case that overflowed).
//!
//! The sizes are 256 and those where a stack use growing with `N²` or with
//! the integrator's size would show first: 16 (the largest forward-mode
//! system, `Derivatives::FORWARD_MAX_N`), 32 (which overflowed when it was
//! the largest), 64 and 128. The chain is written by hand, without the macro's
//! gradient code, so that every path takes its derivatives from dual
//! numbers, the largest values any path carries.

use std::fmt::Debug;

use lagrangian_runtime::galerkin::Galerkin;
use lagrangian_runtime::{
    AlphaBeta, Composition, Derivatives, DoubleDouble, ExplicitTimeTransformed, Integrator, Lagrangian, Midpoint, Plan,
    RadiusPower, Scalar, Separability, StepBounds, Stepping, TimeFunction, TimeTransformed, Trapezoid,
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

/// What a case did: took its steps, or was refused at `start` (with why).
enum Outcome {
    Ran,
    Refused(String),
}

/// Takes `steps` steps of `start()`'s integrator, or records the refusal.
fn run<I, E: Debug, F: Debug>(start: Result<I, E>, mut step: impl FnMut(&mut I) -> Result<(), F>) -> Outcome {
    match start {
        Ok(mut sim) => {
            for k in 0..3 {
                if let Err(e) = step(&mut sim) {
                    panic!("step {k} failed after a successful start: {e:?}");
                }
            }
            Outcome::Ran
        }
        Err(e) => Outcome::Refused(format!("{e:?}")),
    }
}

/// Runs `case` in a thread of its own with the default 2 MiB stack, named
/// after the case so that an overflow names it.
fn in_small_thread(name: String, case: impl FnOnce() -> Outcome + Send + 'static) -> (String, Outcome) {
    let outcome = std::thread::Builder::new().name(name.clone()).stack_size(STACK).spawn(case).unwrap().join();
    (name, outcome.unwrap_or_else(|_| panic!("case panicked")))
}

/// Every capability at size `N`; `M = N + 1` for the time-transformed system.
fn capabilities<const N: usize, const M: usize>() -> Vec<(String, Outcome)> {
    let h = 0.05;
    let bounds = StepBounds::around(h);
    let mut cases: Vec<(String, Box<dyn FnOnce() -> Outcome + Send>)> = Vec::new();
    let mut add =
        |name: &str, case: Box<dyn FnOnce() -> Outcome + Send>| cases.push((format!("{name}, N = {N}"), case));
    add(
        "midpoint",
        Box::new(move || {
            let (q, v) = initial::<N>();
            run(Integrator::new(Chain::<N>, Midpoint, h).start(0.0, q, v), |s| s.step().map(drop))
        }),
    );
    add(
        "midpoint, forward mode",
        Box::new(move || {
            let (q, v) = initial::<N>();
            let sim = Integrator::new(Chain::<N>, Midpoint, h).derivatives(Derivatives::Forward).start(0.0, q, v);
            run(sim, |s| s.step().map(drop))
        }),
    );
    add(
        "trapezoid",
        Box::new(move || {
            let (q, v) = initial::<N>();
            run(Integrator::new(Chain::<N>, Trapezoid, h).start(0.0, q, v), |s| s.step().map(drop))
        }),
    );
    add(
        "trapezoid, explicit",
        Box::new(move || {
            let (q, v) = initial::<N>();
            run(Integrator::new(Chain::<N, false, true>, Trapezoid, h).start(0.0, q, v), |s| s.step().map(drop))
        }),
    );
    add(
        "α-β",
        Box::new(move || {
            let (q, v) = initial::<N>();
            let rule = AlphaBeta::new(0.3).unwrap();
            run(Integrator::new(Chain::<N>, rule, h).start(0.0, q, v), |s| s.step().map(drop))
        }),
    );
    add(
        "midpoint, forced",
        Box::new(move || {
            let (q, v) = initial::<N>();
            run(Integrator::new(Chain::<N, true>, Midpoint, h).start(0.0, q, v), |s| s.step().map(drop))
        }),
    );
    add(
        "trapezoid, forced",
        Box::new(move || {
            let (q, v) = initial::<N>();
            run(Integrator::new(Chain::<N, true>, Trapezoid, h).start(0.0, q, v), |s| s.step().map(drop))
        }),
    );
    add(
        "α-β, forced",
        Box::new(move || {
            let (q, v) = initial::<N>();
            let rule = AlphaBeta::new(0.3).unwrap();
            run(Integrator::new(Chain::<N, true>, rule, h).start(0.0, q, v), |s| s.step().map(drop))
        }),
    );
    add(
        "energy-preserving midpoint",
        Box::new(move || {
            let (q, v) = initial::<N>();
            let sim = Integrator::new(Chain::<N>, Midpoint, h).energy_preserving(bounds).start(0.0, q, v);
            run(sim, |s| s.step().map(drop))
        }),
    );
    add(
        "energy-preserving trapezoid",
        Box::new(move || {
            let (q, v) = initial::<N>();
            let sim = Integrator::new(Chain::<N>, Trapezoid, h).energy_preserving(bounds).start(0.0, q, v);
            run(sim, |s| s.step().map(drop))
        }),
    );
    add(
        "energy-balance midpoint, forced",
        Box::new(move || {
            let (q, v) = initial::<N>();
            let sim = Integrator::new(Chain::<N, true>, Midpoint, h).energy_preserving(bounds).start(0.0, q, v);
            run(sim, |s| s.step().map(drop))
        }),
    );
    add(
        "Galerkin s = 2",
        Box::new(move || {
            let (q, v) = initial::<N>();
            run(Integrator::new(Chain::<N>, Galerkin::<2, 2>::gauss(), h).start(0.0, q, v), |s| s.step().map(drop))
        }),
    );
    add(
        "Galerkin s = 2, forced",
        Box::new(move || {
            let (q, v) = initial::<N>();
            let sim = Integrator::new(Chain::<N, true>, Galerkin::<2, 2>::gauss(), h).start(0.0, q, v);
            run(sim, |s| s.step().map(drop))
        }),
    );
    add(
        "Galerkin s = 5 (sN = 80 at N = 16)",
        Box::new(move || {
            let (q, v) = initial::<N>();
            run(Integrator::new(Chain::<N>, Galerkin::<5, 5>::gauss(), h).start(0.0, q, v), |s| s.step().map(drop))
        }),
    );
    add(
        "Galerkin s = 6 (sN = 96 at N = 16)",
        Box::new(move || {
            let (q, v) = initial::<N>();
            run(Integrator::new(Chain::<N>, Galerkin::<6, 6>::gauss(), h).start(0.0, q, v), |s| s.step().map(drop))
        }),
    );
    add(
        "Galerkin s = 2 in DoubleDouble",
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
        Box::new(move || {
            let (q, v) = initial::<N>();
            let sim = Integrator::new(Chain::<N>, Galerkin::<2, 2>::gauss(), h).energy_preserving(bounds);
            run(sim.start(0.0, q, v), |s| s.step().map(drop))
        }),
    );
    add(
        "Yoshida 4",
        Box::new(move || {
            let (q, v) = initial::<N>();
            run(Integrator::new(Chain::<N>, Composition::YOSHIDA4, h).start(0.0, q, v), |s| s.step().map(drop))
        }),
    );
    add(
        "midpoint, solve",
        Box::new(move || {
            let (q, v) = initial::<N>();
            let sim = Integrator::new(Chain::<N>, Midpoint, h).start(0.0, q, v);
            run(sim, |s| s.solve(Plan::until(s.state().t + 2.0 * h).every(1)).map(drop))
        }),
    );
    add(
        "Galerkin s = 2, solve",
        Box::new(move || {
            let (q, v) = initial::<N>();
            let sim = Integrator::new(Chain::<N>, Galerkin::<2, 2>::gauss(), h).start(0.0, q, v);
            run(sim, |s| s.solve(Plan::until(s.state().t + 2.0 * h).every(1)).map(drop))
        }),
    );
    add(
        "midpoint in DoubleDouble",
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
        Box::new(move || {
            let (q, v) = initial::<N>();
            let density = RadiusPower::new([0], 0.0).unwrap();
            let sim = TimeTransformed::new(Chain::<N>, density).rule(Midpoint, h).start::<M>(0.0, q, v);
            run(sim, |s| s.step().map(drop))
        }),
    );
    // Not yet at larger sizes: `ExplicitTimeTransformed::start` holds the
    // `N × N` inverse mass matrix (and the Hessian that makes it) on the
    // stack, and overflows at N = 256.
    if N <= 64 {
        add(
            "explicit time-transformed",
            Box::new(move || {
                let (q, v) = initial::<N>();
                let sim = ExplicitTimeTransformed::new(Chain::<N, false, true>, TimeFunction::Logarithmic, h)
                    .start(0.0, q, v);
                run(sim, |s| s.step().map(drop))
            }),
        );
    }
    cases.into_iter().map(|(name, case)| in_small_thread(name, case)).collect()
}

/// Prints the table of outcomes; a refusal must be typed, which its
/// `Debug` form shows (an `Unsupported` or another variant of the errors).
fn report(outcomes: Vec<(String, Outcome)>) {
    for (name, outcome) in outcomes {
        match outcome {
            Outcome::Ran => println!("{name}: runs"),
            Outcome::Refused(why) => println!("{name}: refused at start: {why}"),
        }
    }
}

#[test]
fn every_capability_at_16_and_32_fits_a_2_mib_thread() {
    report(capabilities::<16, 17>());
    report(capabilities::<32, 33>());
}

#[test]
fn every_capability_at_64_and_128_fits_a_2_mib_thread() {
    report(capabilities::<64, 65>());
    report(capabilities::<128, 129>());
}

#[test]
fn every_capability_at_256_fits_a_2_mib_thread() {
    report(capabilities::<256, 257>());
}
