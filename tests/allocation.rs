//! No heap allocation in the stepping loop for small systems whose size is
//! known at compile time (the project's standard).
//!
//! A counting global allocator wraps the system allocator; after a warm-up
//! step (which may allocate what a method keeps for the whole run, such as
//! the inverse of a constant mass matrix), 500 more steps of every method and
//! policy on the pendulum and the double pendulum must allocate nothing.
//! Counting is per thread, so the test harness's own threads do not
//! interfere.
// A counting `GlobalAlloc` cannot be written without `unsafe`; it forwards
// every call to the system allocator unchanged.
#![allow(unsafe_code)]

mod common;

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use common::{DOUBLE_PENDULUM, PENDULUM};
use lagrangian::prelude::*;
use lagrangian::{
    AlphaBeta, Composition, Derivatives, DoubleDouble, Event, GalerkinIntegrator, Method, Plan, Problem, Scheme,
    Summation,
};

struct Counting;

thread_local! {
    static ALLOCATIONS: Cell<u64> = const { Cell::new(0) };
}

// SAFETY: forwards every call to `System` unchanged; only counts.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // `try_with`: the thread-local may already be gone while a thread exits.
        let _ = ALLOCATIONS.try_with(|n| n.set(n.get() + 1));
        // SAFETY: the caller upholds `GlobalAlloc::alloc`'s contract.
        unsafe { System.alloc(layout) }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: the caller upholds `GlobalAlloc::dealloc`'s contract.
        unsafe { System.dealloc(ptr, layout) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let _ = ALLOCATIONS.try_with(|n| n.set(n.get() + 1));
        // SAFETY: the caller upholds `GlobalAlloc::realloc`'s contract.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

fn allocations() -> u64 {
    ALLOCATIONS.with(Cell::get)
}

/// Allocations made by 500 steps after one warm-up step.
fn allocations_while_stepping<S, M, const N: usize, T>(sim: Integrator<S, M, N, T>) -> u64
where
    S: Lagrangian<N>,
    M: Method<T>,
    T: lagrangian::Real,
{
    allocations_after_warm_up(sim, 1)
}

/// Allocations made by 500 steps after `warm_up` steps.
fn allocations_after_warm_up<S, M, const N: usize, T>(mut sim: Integrator<S, M, N, T>, warm_up: usize) -> u64
where
    S: Lagrangian<N>,
    M: Method<T>,
    T: lagrangian::Real,
{
    sim.run(warm_up, |_| {}).expect("warm-up steps");
    let before = allocations();
    sim.run(500, |_| {}).expect("steps");
    allocations() - before
}

#[test]
fn one_point_rules_do_not_allocate() {
    let h = 0.01;
    let cases: [(&str, u64); 6] = [
        (
            "pendulum midpoint",
            allocations_while_stepping(Integrator::new(PENDULUM, Midpoint, h).start(0.0, [1.0], [0.0]).unwrap()),
        ),
        (
            "pendulum trapezoid (explicit)",
            allocations_while_stepping(Integrator::new(PENDULUM, Trapezoid, h).start(0.0, [1.0], [0.0]).unwrap()),
        ),
        (
            "pendulum α-β",
            allocations_while_stepping(
                Integrator::new(PENDULUM, AlphaBeta::new(0.3).unwrap(), h).start(0.0, [1.0], [0.0]).unwrap(),
            ),
        ),
        (
            "double pendulum midpoint",
            allocations_while_stepping(
                Integrator::new(DOUBLE_PENDULUM, Midpoint, h).start(0.0, [1.0, 0.5], [0.0, 0.0]).unwrap(),
            ),
        ),
        (
            "double pendulum trapezoid (Newton)",
            allocations_while_stepping(
                Integrator::new(DOUBLE_PENDULUM, Trapezoid, h).start(0.0, [1.0, 0.5], [0.0, 0.0]).unwrap(),
            ),
        ),
        (
            "pendulum energy-preserving midpoint",
            allocations_while_stepping(
                Integrator::new(PENDULUM, Midpoint, h)
                    .energy_preserving(StepBounds::around(h))
                    .start(0.0, [1.0], [0.0])
                    .unwrap(),
            ),
        ),
    ];
    for (name, n) in cases {
        assert_eq!(n, 0, "{name}: {n} allocations in 500 steps");
    }
}

/// Reverse mode keeps its buffers on the heap in a pool and reuses them,
/// with compensated or plain sums (each commits its buffers differently).
/// The pool fills over the first steps (the last step's segment from the
/// second, the step before it from the third), and grows once more, by two
/// buffers, the first time the growth check cannot decide from its cheap
/// bound and writes out the predictor: so a few allocations in 500 steps
/// after three warm-up steps, where a step that lost a buffer would
/// allocate at every step (the bug this caught: 1000).
#[test]
fn reverse_mode_and_plain_sums_do_not_allocate() {
    let h = 0.01;
    fn allocations_while_stepping<S: Lagrangian<N>, M: Method<f64>, const N: usize>(
        sim: Integrator<S, M, N, f64>,
    ) -> u64 {
        allocations_after_warm_up(sim, 3)
    }
    let reverse = |method: Composition, summation| {
        allocations_while_stepping(
            Integrator::new(DOUBLE_PENDULUM, method, h)
                .derivatives(Derivatives::Reverse)
                .summation(summation)
                .start(0.0, [1.0, 0.5], [0.0, 0.0])
                .unwrap(),
        )
    };
    let forward = |summation| {
        allocations_while_stepping(
            Integrator::new(PENDULUM, Composition::YOSHIDA4, h).summation(summation).start(0.0, [1.0], [0.0]).unwrap(),
        )
    };
    let midpoint = |summation| {
        allocations_while_stepping(
            Integrator::new(PENDULUM, Midpoint, h)
                .derivatives(Derivatives::Reverse)
                .summation(summation)
                .start(0.0, [1.0], [0.0])
                .unwrap(),
        )
    };
    let cases: [(&str, u64); 8] = [
        (
            "double pendulum Yoshida 4, reverse mode (Newton sub-steps)",
            reverse(Composition::YOSHIDA4, Summation::Compensated),
        ),
        ("the same, plain sums", reverse(Composition::YOSHIDA4, Summation::Plain)),
        ("pendulum Yoshida 4, forward mode (fused)", forward(Summation::Compensated)),
        ("the same, plain sums", forward(Summation::Plain)),
        ("pendulum midpoint, reverse mode", midpoint(Summation::Compensated)),
        ("the same, plain sums", midpoint(Summation::Plain)),
        (
            "pendulum trapezoid, reverse mode (explicit)",
            allocations_while_stepping(
                Integrator::new(PENDULUM, Trapezoid, h)
                    .derivatives(Derivatives::Reverse)
                    .start(0.0, [1.0], [0.0])
                    .unwrap(),
            ),
        ),
        (
            "pendulum Kahan–Li 8, reverse mode (fused), plain sums",
            allocations_while_stepping(
                Integrator::new(PENDULUM, Composition::KAHAN_LI8, h)
                    .derivatives(Derivatives::Reverse)
                    .summation(Summation::Plain)
                    .start(0.0, [1.0], [0.0])
                    .unwrap(),
            ),
        ),
    ];
    let allocating: Vec<String> = cases.iter().filter(|c| c.1 > 2).map(|(name, n)| format!("{name}: {n}")).collect();
    assert!(allocating.is_empty(), "allocations in 500 steps: {allocating:?}");
}

#[test]
fn galerkin_compositions_and_double_double_do_not_allocate() {
    let h = 0.05;
    let cases: [(&str, u64); 5] = [
        (
            "pendulum Galerkin s = 2",
            allocations_while_stepping(
                GalerkinIntegrator::new(PENDULUM, Galerkin::<2, 2>::gauss(), h).start(0.0, [1.0], [0.0]).unwrap(),
            ),
        ),
        (
            "double pendulum Galerkin s = 4",
            allocations_while_stepping(
                GalerkinIntegrator::new(DOUBLE_PENDULUM, Galerkin::<4, 4>::gauss(), h)
                    .start(0.0, [1.0, 0.5], [0.0, 0.0])
                    .unwrap(),
            ),
        ),
        (
            "pendulum Yoshida 6",
            allocations_while_stepping(
                Integrator::new(PENDULUM, Composition::YOSHIDA6, h).start(0.0, [1.0], [0.0]).unwrap(),
            ),
        ),
        (
            "double pendulum Yoshida 4 (Newton sub-steps)",
            allocations_while_stepping(
                Integrator::new(DOUBLE_PENDULUM, Composition::YOSHIDA4, h).start(0.0, [1.0, 0.5], [0.0, 0.0]).unwrap(),
            ),
        ),
        (
            "pendulum midpoint in double-double",
            allocations_while_stepping(
                Integrator::new(PENDULUM, Midpoint, DoubleDouble::from(h))
                    .start(DoubleDouble::from(0.0), [DoubleDouble::from(1.0)], [DoubleDouble::from(0.0)])
                    .unwrap(),
            ),
        ),
    ];
    for (name, n) in cases {
        assert_eq!(n, 0, "{name}: {n} allocations in 500 steps");
    }
}

/// Steppers of a `Problem` step without allocating, and `solve` allocates
/// nothing per step: its copy of the stepper from before each step (kept
/// for events and failed steps) is made once and refreshed in place. Two
/// solves of 500 and 1000 steps that keep the same rows (the first and last
/// nodes, two save times, an event that is never met) allocate the same.
#[test]
fn problem_steppers_and_solve_do_not_allocate_per_step() {
    let h = 0.01;
    let schemes = [
        Scheme::MIDPOINT,
        Scheme::galerkin(2),
        Scheme::composition(Composition::YOSHIDA4, OnePoint::Trapezoid),
        Scheme::MIDPOINT.composed(Composition::YOSHIDA4),
    ];
    for scheme in schemes {
        let problem = Problem::new(DOUBLE_PENDULUM, 0.0, [1.0, 0.5], [0.0, 0.0]);
        let mut sim = problem.stepper(&scheme, h).unwrap();
        sim.step().unwrap();
        let before = allocations();
        sim.run(500, |_| {}).unwrap();
        assert_eq!(allocations() - before, 0, "{scheme:?}: stepping");

        let solve = |steps: u32| {
            let plan = Plan::until(f64::from(steps) * h)
                .every(1 << 20)
                .save_at(vec![0.5, 1.0])
                .event(Event::new(|_t, q: &[f64], _v: &[f64]| q[0] + 10.0));
            let before = allocations();
            let sol = problem.solve(&scheme, h, plan).unwrap().into_result().unwrap();
            let n = allocations() - before;
            assert_eq!((sol.len(), sol.events.len(), sol.stats.steps), (4, 0, u64::from(steps)), "{scheme:?}");
            n
        };
        let (short, long) = (solve(500), solve(1000));
        assert!(short > 0 && long == short, "{scheme:?}: {short} allocations in 500 steps, {long} in 1000");
    }
}

/// The counter sees this thread's allocations (so the zeros above mean something).
#[test]
fn the_counter_counts() {
    let before = allocations();
    let v: Vec<u64> = std::hint::black_box((0..100).collect());
    assert_eq!(v.len(), 100);
    assert!(allocations() > before);
}

/// A pendulum as a point on the unit circle.
#[derive(Clone, Debug)]
struct CartesianPendulum;

#[lagrangian]
impl CartesianPendulum {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) - q[1]
    }
    fn constraints(&self, q: [f64; 2]) -> [f64; 1] {
        [q[0] * q[0] + q[1] * q[1] - 1.0]
    }
}

#[test]
fn constrained_galerkin_and_compositions_do_not_allocate() {
    let (h, q0) = (0.05, [1f64.sin(), -1f64.cos()]);
    let galerkin = Constrained::<_, 1>::galerkin(Galerkin::<3, 3>::gauss());
    let composition = Constrained::<_, 1>::composition(Composition::YOSHIDA6);
    let cases = [
        (
            "Cartesian pendulum, constrained Galerkin s = 3",
            allocations_while_stepping(
                Integrator::new(CartesianPendulum, galerkin, h).start(0.0, q0, [0.0; 2]).unwrap(),
            ),
        ),
        (
            "Cartesian pendulum, Yoshida 6 over RATTLE",
            allocations_while_stepping(
                Integrator::new(CartesianPendulum, composition, h).start(0.0, q0, [0.0; 2]).unwrap(),
            ),
        ),
    ];
    for (name, n) in cases {
        assert_eq!(n, 0, "{name}: {n} allocations in 500 steps");
    }
}
