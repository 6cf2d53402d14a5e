//! Cost of one step at a fixed step size: the generated midpoint and
//! trapezoid steps against the hand-written ones of [`crate::handwritten`]
//! (analytic derivatives), on the report's pendulum and double pendulum.
//! The ns/step table of `docs/measurements.md` is generated from these numbers.

use std::hint::black_box;

use lagrangian::GalerkinIntegrator;
use lagrangian::prelude::*;

use crate::handwritten::{DoubleMethod, DoubleParams, DoubleStepper, PendulumMidpoint, PendulumParams, PendulumVerlet};
use crate::problems::{DoublePendulum, Model, Pendulum, PendulumSys};
use crate::report::StepCost;

/// The step size of every measurement.
pub const H: f64 = 0.01;

/// Times `run` (which takes `steps` steps and returns Newton iterations per
/// step, if any) `repeats` times; the best run.
fn time(
    system: &str,
    method: &str,
    (steps, repeats): (usize, u32),
    mut run: impl FnMut() -> Option<Option<f64>>,
) -> Option<StepCost> {
    let mut best = f64::INFINITY;
    let mut newton = None;
    for _ in 0..repeats {
        let start = crate::clock::Clock::start();
        newton = run()?;
        best = best.min(start.seconds());
    }
    Some(StepCost {
        system: system.into(),
        method: method.into(),
        h: H,
        steps: steps as u64,
        repeats,
        ns_per_step: best / steps as f64 * 1e9,
        newton_per_step: newton,
    })
}

/// Runs `steps` steps of `sim`; the Newton iterations per step.
fn newton_per_step<S: Lagrangian<N>, M: F64Readouts + Clone, const N: usize>(
    mut sim: Integrator<S, M, N>,
    steps: usize,
) -> Option<Option<f64>> {
    sim.run(steps, |s| {
        black_box(&s.state().q);
    })
    .ok()?;
    let s = sim.stats();
    Some(Some(s.newton_iterations as f64 / s.steps.max(1) as f64))
}

fn generated<S: Lagrangian<N> + Clone, M: F64Readouts + Clone, const N: usize>(
    system: &S,
    method: M,
    (q0, v0): ([f64; N], [f64; N]),
    steps: usize,
) -> Option<Option<f64>> {
    newton_per_step(Integrator::new(system.clone(), method, H).start(0.0, q0, v0).ok()?, steps)
}

/// The generated energy-preserving midpoint step (`StepBounds::around(H)`).
fn energy_preserving<S: Lagrangian<N> + Clone, const N: usize>(
    system: &S,
    (q0, v0): ([f64; N], [f64; N]),
    steps: usize,
) -> Option<Option<f64>> {
    let sim = Integrator::new(system.clone(), Midpoint, H)
        .energy_preserving(StepBounds::around(H))
        .start(0.0, q0, v0)
        .ok()?;
    newton_per_step(sim, steps)
}

/// The step size of the Galerkin measurements (the pendulum, as in the
/// Galerkin benchmark).
pub const H_GALERKIN: f64 = 0.1;

fn galerkin<const S: usize>(system: &PendulumSys, steps: usize) -> Option<Option<f64>> {
    let mut sim =
        GalerkinIntegrator::new(*system, Galerkin::<S, S>::gauss(), H_GALERKIN).start(0.0, [1.0], [0.0]).ok()?;
    sim.run(steps, |s| {
        black_box(&s.state().q);
    })
    .ok()?;
    let s = sim.stats();
    Some(Some(s.newton_iterations as f64 / s.steps.max(1) as f64))
}

/// Measures every pair, each the best of `runs` runs of `steps` steps; a
/// method that fails (it should not) is left out.
pub fn measure(steps: usize, runs: u32) -> Vec<StepCost> {
    let size = (steps, runs);
    let mut out = Vec::new();

    let pendulum = Pendulum { scale: 1.0 }.system();
    let start = ([1.0], [0.0]);
    let params = PendulumParams { a: 1.0, d: pendulum.w2 };
    let name = "pendulum";
    out.extend(time(name, "generated midpoint", size, || generated(&pendulum, Midpoint, start, steps)));
    out.extend(time(name, "generated trapezoid", size, || generated(&pendulum, Trapezoid, start, steps)));
    out.extend(time(name, "generated energy-preserving midpoint", size, || energy_preserving(&pendulum, start, steps)));
    out.extend(time(name, "hand-written midpoint", size, || {
        let mut s = PendulumMidpoint::new(params, H, 1.0, 0.0);
        for _ in 0..steps {
            s.step()?;
            black_box(s.q);
        }
        Some(None)
    }));
    out.extend(time(name, "hand-written verlet", size, || {
        let mut s = PendulumVerlet { s: params, h: H, q: 1.0, p: 0.0 };
        for _ in 0..steps {
            s.step();
            black_box(s.q);
        }
        Some(None)
    }));

    let dp = DoublePendulum { scale: 1.0 }.system();
    let (q0, v0) = ([1.0, -0.5], [0.0, 0.5]);
    let params = DoubleParams {
        a: (dp.m1 + dp.m2) * dp.l1 * dp.l1,
        b: dp.m2 * dp.l2 * dp.l2,
        c: dp.m2 * dp.l1 * dp.l2,
        d: (dp.m1 + dp.m2) * dp.g * dp.l1,
        e: dp.m2 * dp.g * dp.l2,
    };
    let name = "double pendulum";
    out.extend(time(name, "generated midpoint", size, || generated(&dp, Midpoint, (q0, v0), steps)));
    out.extend(time(name, "generated trapezoid", size, || generated(&dp, Trapezoid, (q0, v0), steps)));
    for (label, method) in
        [("hand-written midpoint", DoubleMethod::Midpoint), ("hand-written verlet", DoubleMethod::Verlet)]
    {
        out.extend(time(name, label, size, || {
            let mut s = DoubleStepper::new(params, method, H, q0, v0);
            for _ in 0..steps {
                s.step()?;
                black_box(s.q);
            }
            Some(None)
        }));
    }
    // From (1, −0.5) the energy equation loses its root within 40 steps; from
    // rest at (0.5, 0.3) it keeps it.
    let name = "double pendulum from rest at (0.5, 0.3)";
    let rest = ([0.5, 0.3], [0.0, 0.0]);
    out.extend(time(name, "generated midpoint", size, || generated(&dp, Midpoint, rest, steps)));
    out.extend(time(name, "generated energy-preserving midpoint", size, || energy_preserving(&dp, rest, steps)));
    // Galerkin s = 1…8 on the pendulum at h = 0.1, a tenth of the steps (they cost up to 20 times more).
    let size = (steps / 10, size.1);
    macro_rules! degrees {
        ($($s:literal)*) => {$(
            out.extend(time("pendulum, h = 0.1", concat!("galerkin-", $s), size, || galerkin::<$s>(&pendulum, size.0))
                .map(|c| StepCost { h: H_GALERKIN, ..c }));
        )*};
    }
    degrees!(1 2 3 4 5 6 7 8);
    out
}
