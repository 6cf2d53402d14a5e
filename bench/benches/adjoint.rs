//! The cost of the discrete adjoint: the time of `Problem::gradient`
//! against the time of the forward run it differentiates (the same steps
//! with no derivatives), and the peak heap memory of a gradient over 10⁶
//! steps with `⌈√n⌉` checkpoints, counted by this binary's global allocator.
//!
//! `cargo bench -p lagrangian-bench --bench adjoint [-- CASE [forward|gradient]]`
//!
//! Prints a markdown table, of the cases whose name contains `CASE` when
//! one is given (`pendulum-midpoint`, `pendulum-galerkin3`,
//! `pendulum-kahan-li8`, `kepler-splitting-kahan-li8`, `chain8` … `chain64`,
//! `chain1000`, `memory`). With `forward` or
//! `gradient` after it, runs that half of each chosen case once and prints
//! nothing: what `valgrind --tool=callgrind` counts the instructions of. Timings are the minimum of several runs of CPU
//! wall time (`Instant`) on an otherwise shared machine; the memory is the
//! largest number of live heap bytes during the call above the bytes live
//! before it.
#![allow(missing_docs)]
// A counting `GlobalAlloc` cannot be written without `unsafe`; it forwards
// every call to the system allocator unchanged.
#![allow(unsafe_code)]

use std::alloc::{GlobalAlloc, Layout, System};
use std::hint::black_box;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use lagrangian::prelude::*;

#[path = "../../tests/common/parametric_chain.rs"]
mod parametric_chain;
use parametric_chain::Chain;

/// The system allocator, counting live and peak bytes.
struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller upholds `GlobalAlloc::alloc`'s contract.
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            let live = LIVE.fetch_add(layout.size(), Ordering::Relaxed) + layout.size();
            PEAK.fetch_max(live, Ordering::Relaxed);
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: the caller upholds `GlobalAlloc::dealloc`'s contract.
        unsafe { System.dealloc(ptr, layout) };
        LIVE.fetch_sub(layout.size(), Ordering::Relaxed);
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// A double pendulum with `m1`, `l1` and `g` as parameters.
#[derive(Clone)]
struct DoublePendulum {
    m1: f64,
    m2: f64,
    l1: f64,
    l2: f64,
    g: f64,
}

#[lagrangian(parameters(m1, l1, g))]
impl DoublePendulum {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let kinetic = 0.5 * (self.m1 + self.m2) * self.l1 * self.l1 * v[0] * v[0]
            + 0.5 * self.m2 * self.l2 * self.l2 * v[1] * v[1]
            + self.m2 * self.l1 * self.l2 * v[0] * v[1] * (q[0] - q[1]).cos();
        kinetic + (self.m1 + self.m2) * self.g * self.l1 * q[0].cos() + self.m2 * self.g * self.l2 * q[1].cos()
    }
}

/// Planar Kepler with the gravitational parameter `μ` as a parameter.
#[derive(Clone)]
struct Kepler {
    mu: f64,
}

#[lagrangian(parameters(mu))]
impl Kepler {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) + self.mu / (q[0] * q[0] + q[1] * q[1]).sqrt()
    }
}

/// `Σ_k 10⁻³ |q_k|² + |q_n|²`.
struct Squares;

impl<const N: usize, const P: usize> Loss<N, P> for Squares {
    fn running<D: Scalar>(&self, _k: u64, _t: D, q: [D; N], _p: [D; N], _theta: &[D; P]) -> D {
        q.iter().fold(D::zero(), |s, &x| s + x * x) * 1e-3
    }
    fn terminal<D: Scalar>(&self, _t: D, q: [D; N], _p: [D; N], _theta: &[D; P]) -> D {
        q.iter().fold(D::zero(), |s, &x| s + x * x)
    }
}

/// The least of `reps` timings of `f`, in seconds.
fn best(reps: usize, mut f: impl FnMut()) -> f64 {
    (0..reps)
        .map(|_| {
            let start = Instant::now();
            f();
            start.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

/// Which halves of a case to run.
#[derive(Clone, Copy, PartialEq)]
enum Phase {
    /// Both, timed, with a row of the table.
    Timed,
    /// The forward run once, silently.
    Forward,
    /// The gradient once, silently.
    Gradient,
}

/// Forward run and gradient of `problem` with `scheme` over `steps` steps
/// of size `h`: (forward s, gradient s).
fn costs<S, const N: usize, const P: usize>(
    problem: &Problem<S, lagrangian::Dim<N>>,
    scheme: &Scheme,
    h: f64,
    steps: usize,
    phase: Phase,
) -> (f64, f64)
where
    S: Parametric<N, P>,
    lagrangian::problem::Dim<N>: lagrangian::problem::Extended<N>,
{
    let t_end = steps as f64 * h;
    let checkpoints = Checkpoints::Budget((steps as f64).sqrt().ceil() as usize);
    let reps = if phase == Phase::Timed { 5 } else { 1 };
    let forward = || {
        let mut sim = problem.stepper(scheme, h).unwrap();
        sim.run_until(t_end).unwrap();
        black_box(sim.state());
    };
    let gradient = || {
        black_box(problem.gradient(scheme, h, t_end, &Squares, checkpoints).unwrap());
    };
    match phase {
        Phase::Timed => (best(reps, forward), best(reps, gradient)),
        Phase::Forward => (best(reps, forward), 0.0),
        Phase::Gradient => (0.0, best(reps, gradient)),
    }
}

fn row(what: &str, steps: usize, (forward, gradient): (f64, f64), phase: Phase) {
    if phase == Phase::Timed {
        println!("| {what} | {steps} | {:.3} | {:.3} | {:.1} |", forward * 1e3, gradient * 1e3, gradient / forward);
    }
}

fn chain<const N: usize>(scheme: &Scheme, steps: usize, phase: Phase)
where
    lagrangian::problem::Dim<N>: lagrangian::problem::Extended<N>,
{
    let q0: [f64; N] = core::array::from_fn(|i| 0.1 * ((i as f64 + 1.0) * 0.7).sin());
    let problem = Problem::new(Chain::<N> { theta: [1.0, 0.5] }, 0.0, q0, [0.0; N]);
    let what = format!("FPU-β chain N = {N}, {}", scheme.name());
    row(&what, steps, costs::<_, N, 2>(&problem, scheme, 0.05, steps, phase), phase);
}

fn main() {
    // `cargo bench` passes `--bench`; the other arguments choose the cases.
    let args: Vec<String> = std::env::args().skip(1).filter(|a| !a.starts_with("--")).collect();
    let chosen = |name: &str| args.first().is_none_or(|case| name.contains(case.as_str()));
    let phase = match args.get(1).map(String::as_str) {
        Some("forward") => Phase::Forward,
        Some("gradient") => Phase::Gradient,
        _ => Phase::Timed,
    };
    let pendulum = DoublePendulum { m1: 1.0, m2: 0.8, l1: 1.2, l2: 0.9, g: 9.81 };
    let problem = Problem::new(pendulum, 0.0, [0.6, -0.3], [0.2, 0.5]);
    if phase == Phase::Timed {
        println!("| system, method | steps | forward run (ms) | gradient (ms) | gradient / forward |");
        println!("|---|---|---|---|---|");
    }
    let (h, steps) = (1e-3, 10_000);
    for (name, scheme) in [
        ("pendulum-midpoint", Scheme::MIDPOINT),
        ("pendulum-galerkin3", Scheme::galerkin(3)),
        ("pendulum-kahan-li8", Scheme::composition(Composition::KAHAN_LI8, OnePoint::Trapezoid)),
    ] {
        if chosen(name) {
            let what = format!("double pendulum, {}", scheme.name());
            row(&what, steps, costs::<_, 2, 3>(&problem, &scheme, h, steps, phase), phase);
        }
    }
    // The explicit time-transformed splitting (logarithmic, drift–kick–drift,
    // Kahan–Li 8) on Kepler e = 0.5 with μ: σ = 0.1 in `s`, to t = 100
    // (about 16 orbits, 1003 steps in `s`).
    if chosen("kepler-splitting-kahan-li8") {
        let scheme = Scheme::splitting(TimeFunction::Logarithmic, Some(Composition::KAHAN_LI8));
        let kepler = Problem::new(Kepler { mu: 1.0 }, 0.0, [0.5, 0.0], [0.0, 3f64.sqrt()]);
        let what = format!("Kepler e = 0.5, {}", scheme.name());
        row(&what, 1000, costs::<_, 2, 1>(&kepler, &scheme, 0.1, 1000, phase), phase);
    }
    if chosen("chain8") {
        chain::<8>(&Scheme::MIDPOINT, 1000, phase);
    }
    if chosen("chain16") {
        chain::<16>(&Scheme::MIDPOINT, 1000, phase);
    }
    if chosen("chain32") {
        chain::<32>(&Scheme::MIDPOINT, 1000, phase);
    }
    if chosen("chain64") {
        chain::<64>(&Scheme::MIDPOINT, 100, phase);
    }
    if chosen("chain1000") {
        chain::<1000>(&Scheme::MIDPOINT, 100, phase);
    }
    if !chosen("memory") || phase != Phase::Timed {
        return;
    }

    // Peak memory over 10⁶ steps with ⌈√n⌉ = 1000 checkpoints.
    let n = 1_000_000;
    let before = LIVE.load(Ordering::Relaxed);
    PEAK.store(before, Ordering::Relaxed);
    let start = Instant::now();
    let g = problem.gradient(&Scheme::MIDPOINT, h, n as f64 * h, &Squares, Checkpoints::Budget(1000)).unwrap();
    let seconds = start.elapsed().as_secs_f64();
    let peak = PEAK.load(Ordering::Relaxed) - before;
    let stepper = std::mem::size_of::<lagrangian::problem::Stepper<DoublePendulum, lagrangian::Dim<2>>>();
    println!(
        "\npeak heap of the double-pendulum midpoint gradient over {} steps, Checkpoints::Budget(1000): {:.2} MB \
         ({} checkpoint costates; a stepper is {stepper} bytes inline), {seconds:.1} s",
        g.last.step,
        peak as f64 / 1e6,
        g.costates.len()
    );
}
