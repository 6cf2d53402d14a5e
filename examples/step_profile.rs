//! A fixed number of steps of one benchmark case, for instruction counts that
//! do not depend on the load of the machine:
//!
//! ```text
//! cargo build --release --example step_profile
//! valgrind --tool=callgrind target/release/examples/step_profile "double pendulum" midpoint 20000
//! ```
//!
//! Cases: `pendulum` or `double pendulum`; methods: `midpoint`, `trapezoid`,
//! `problem-midpoint` (`pendulum` only: midpoint chosen as a `Scheme` value through `Problem`),
//! `boxed-midpoint` (`pendulum` only: midpoint named directly, on the heap, stepped by a call not inlined),
//! `ideal` (`pendulum` only: the generated midpoint step's algorithm written out by hand),
//! `variable` (energy-preserving midpoint, from the start of the bench's
//! variable-step group), `damped` (double pendulum with joint friction, a
//! forced step), `energy` (a midpoint step and `Integrator::energy` after it), `hand` (the hand-written midpoint of the bench) or
//! `derivatives` (one `step_derivatives` evaluation per "step", nothing else); `verlet` (a hand-written Störmer–Verlet).
//! Further cases: `kepler`, `henon-heiles` and `fpu` (the bench's FPU-β chain, N = 16) with `trapezoid`
//! (explicit Störmer–Verlet) or `verlet`; `fpu trapezoid-powi` (the same chain with the quartic
//! written `d.powi(4)`, as in `chain1000`, instead of `d * d * d * d`); `pendulum kahan-li8` and `pendulum hand-kahan-li8`
//! (the same composition of hand-written Verlet steps); `verlet-compensated` (`kepler`, `henon-heiles`, `fpu`,
//! `chain1000`) and `pendulum hand-kahan-li8-compensated`: the bench's hand-written compositions with the
//! compensated sums the generated steps keep (`Stepper::step_compensated`); `pendulum galerkin6` and
//! `kepler galerkin6` (Galerkin s = 6, 6 Gauss points, h = 0.1), `pendulum galerkin8`, `kepler galerkin4`,
//! `double pendulum galerkin4` (s = 4, h = 2/95: the report's step for 1e-8 over t ≤ 2; `galerkin4-newton`: solved by Newton only);
//! `galerkin6-tight` (s = 6 with Newton's `rtol` at 1e-17, a reference for the round-off of the others);
//! `chain1000` with `trapezoid` or `verlet` (the FPU-β chain of `chain_scaling.rs`, N = 1000, reverse mode),
//! `dyn-trapezoid` and `dyn-yoshida4` (the same chain sized at run time, `Stepper<S, Dyn>`), `midpoint` (reverse-mode Newton steps), `yoshida4` (Yoshida 4 of explicit sub-steps, fused), and
//! `verlet-compensated-inplace` (a hand-written compensated Verlet on slices in place: the fair baseline
//! of the generated explicit step); `digest-trapezoid`, `digest-midpoint`, `digest-yoshida4` print the bits
//! of the state and of every readout after `n` steps, to compare two builds.
//! `gradient` (`fpu`, `chain1000`, `kepler`, `henon-heiles`; `fpu gradient-powi`): the macro's `gradient_q`
//! alone, one evaluation per "step"; `force`: the hand-written force of the `verlet` case instead.
//! `trace-midpoint`, `trace-trapezoid`, `trace-alpha-beta` (α = 0.3; `pendulum` or `double pendulum`)
//! print the positions of every node as bit patterns, to compare the trajectories of two builds;
//! `trace-midpoint-nudged` starts midpoint from `q0[0]` one ulp up (what round-off alone does),
//! `trace-midpoint-tight` runs it with Newton's `rtol` at 1e-16.
//! It prints the wall-clock ns per step; `/usr/bin/time -f %U` gives CPU time,
//! which is steadier on a shared machine.
#![allow(missing_docs)]

#[path = "../tests/common/mod.rs"]
mod common;
#[path = "../bench/src/compositions.rs"]
#[allow(dead_code, unreachable_pub)]
mod compositions;
#[path = "../bench/src/handwritten.rs"]
mod handwritten;

use common::{DOUBLE_PENDULUM as DP, DoublePendulum, PENDULUM as P, Pendulum};
use compositions::{Composition as Hand, Stepper};
use handwritten::*;
use lagrangian::derivatives::step_derivatives;
use lagrangian::{
    Composition, Galerkin, GalerkinIntegrator, Integrator, Lagrangian, Midpoint, Problem, Scheme, Segment, StepBounds,
    Summation, Trapezoid,
};
use std::hint::black_box;

/// The tests' pendulum as a type of its own: `boxed-midpoint` steps it out
/// of line, and a further caller of the same instantiation as `midpoint`'s
/// would change the inliner's choices for `midpoint` (641 against 700
/// instructions per step).
#[derive(Clone)]
struct HeapPendulum {
    m: f64,
    l: f64,
    g: f64,
}

#[lagrangian::lagrangian]
impl HeapPendulum {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * self.m * self.l * self.l * v[0] * v[0] + self.m * self.g * self.l * q[0].cos()
    }
}

const H: f64 = 0.01;

/// The double pendulum of the tests with joint friction: a forced (Lagrange–d'Alembert) step.
struct DampedDoublePendulum {
    p: DoublePendulum,
    c: f64,
}

#[lagrangian::lagrangian]
impl DampedDoublePendulum {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let (m1, m2, l1, l2, g) = (self.p.m1, self.p.m2, self.p.l1, self.p.l2, self.p.g);
        let kinetic = 0.5 * (m1 + m2) * l1 * l1 * v[0] * v[0]
            + 0.5 * m2 * l2 * l2 * v[1] * v[1]
            + m2 * l1 * l2 * v[0] * v[1] * (q[0] - q[1]).cos();
        kinetic + (m1 + m2) * g * l1 * q[0].cos() + m2 * g * l2 * q[1].cos()
    }

    fn dissipation(&self, _q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * self.c * (v[0] * v[0] + (v[1] - v[0]) * (v[1] - v[0]))
    }
}

/// The pendulum of the tests (`tests/common`, the same expression, so the
/// same numbers) as a type of its own: the trace cases then do not share,
/// and so do not change the inlining of, the profiled pendulum step.
struct TracePendulum {
    m: f64,
    l: f64,
    g: f64,
}

#[lagrangian::lagrangian]
impl TracePendulum {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * self.m * self.l * self.l * v[0] * v[0] + self.m * self.g * self.l * q[0].cos()
    }
}

/// The double pendulum of the tests, as a type of its own (see [`TracePendulum`]).
struct TraceDoublePendulum {
    m1: f64,
    m2: f64,
    l1: f64,
    l2: f64,
    g: f64,
}

#[lagrangian::lagrangian]
impl TraceDoublePendulum {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let kinetic = 0.5 * (self.m1 + self.m2) * self.l1 * self.l1 * v[0] * v[0]
            + 0.5 * self.m2 * self.l2 * self.l2 * v[1] * v[1]
            + self.m2 * self.l1 * self.l2 * v[0] * v[1] * (q[0] - q[1]).cos();
        let potential = -(self.m1 + self.m2) * self.g * self.l1 * q[0].cos() - self.m2 * self.g * self.l2 * q[1].cos();
        kinetic - potential
    }
}

/// `L = ½|q̇|² + 1/|q|` (the bench's Kepler problem).
struct Kepler;

#[lagrangian::lagrangian]
impl Kepler {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) + 1.0 / (q[0] * q[0] + q[1] * q[1]).sqrt()
    }
}

/// `L = ½|q̇|² − ½(x² + y²) − x²y + y³/3` (the bench's Hénon–Heiles).
struct HenonHeiles;

#[lagrangian::lagrangian]
impl HenonHeiles {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let (x, y) = (q[0], q[1]);
        0.5 * (v[0] * v[0] + v[1] * v[1]) - 0.5 * (x * x + y * y) - x * x * y + y * y * y / 3.0
    }
}

const FPU_N: usize = 16;

/// The bench's FPU-β chain between fixed walls (β = 1).
struct Fpu;

#[lagrangian::lagrangian]
impl Fpu {
    fn lagrangian(&self, q: [f64; FPU_N], v: [f64; FPU_N]) -> f64 {
        let mut kinetic = 0.0;
        for i in 0..FPU_N {
            kinetic += 0.5 * v[i] * v[i];
        }
        let (a, b) = (q[0], q[FPU_N - 1]);
        let mut potential = 0.5 * (a * a + b * b) + 0.25 * (a * a * a * a + b * b * b * b);
        for i in 0..FPU_N - 1 {
            let d = q[i + 1] - q[i];
            potential += 0.5 * d * d + 0.25 * d * d * d * d;
        }
        kinetic - potential
    }
}

const CHAIN_N: usize = 1000;

/// The chain of `bench/benches/chain_scaling.rs` (β = 1, fixed ends), generic
/// in its size: at `N = 1000` it steps in reverse mode.
struct Chain<const N: usize>;

#[lagrangian::lagrangian]
impl<const N: usize> Chain<N> {
    fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
        let mut kinetic = 0.0;
        for i in 0..N {
            kinetic += 0.5 * v[i] * v[i];
        }
        let mut d = q[0];
        let mut potential = 0.5 * d * d + 0.25 * d.powi(4);
        for i in 0..N - 1 {
            d = q[i + 1] - q[i];
            potential += 0.5 * d * d + 0.25 * d.powi(4);
        }
        d = q[N - 1];
        potential += 0.5 * d * d + 0.25 * d.powi(4);
        kinetic - potential
    }
}

/// The same chain sized at run time (`Problem<S, Dyn>`, as in `chain_scaling.rs`).
#[derive(Clone)]
struct DynChain(usize);

#[lagrangian::lagrangian]
impl DynChain {
    fn dimension(&self) -> usize {
        self.0
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        let n = q.len();
        let mut kinetic = 0.0;
        for i in 0..n {
            kinetic += 0.5 * v[i] * v[i];
        }
        let mut d = q[0];
        let mut potential = 0.5 * d * d + 0.25 * d.powi(4);
        for i in 0..n - 1 {
            d = q[i + 1] - q[i];
            potential += 0.5 * d * d + 0.25 * d.powi(4);
        }
        d = q[n - 1];
        potential += 0.5 * d * d + 0.25 * d.powi(4);
        kinetic - potential
    }
}

/// The chain's start of `chain_scaling.rs`: mode `N/10`, spring strains 0.3.
/// A planar pendulum of `N` equal links (as in the tests' large systems):
/// a dense, position-dependent mass matrix.
struct NLink<const N: usize>;

#[lagrangian::lagrangian]
impl<const N: usize> NLink<N> {
    fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
        let (mut vx, mut vy, mut y) = (0.0, 0.0, 0.0);
        let mut l = 0.0;
        for i in 0..N {
            vx += q[i].cos() * v[i];
            vy += q[i].sin() * v[i];
            y -= q[i].cos();
            l += 0.5 * (vx * vx + vy * vy) - y;
        }
        l
    }
}

/// `n` midpoint steps of the `N`-link pendulum with the given derivatives.
fn nlink_mode<const N: usize>(mode: lagrangian::Derivatives, n: usize) -> Vec<f64> {
    let q0: [f64; N] = core::array::from_fn(|i| 0.5 * (1.0 + i as f64 / N as f64));
    run(Integrator::new(NLink::<N>, Midpoint, 0.01).derivatives(mode).start(0.0, q0, [0.0; N]), n)
}

fn chain_q0<const N: usize>() -> [f64; N] {
    let k = N.div_ceil(10);
    let a = 0.3 * (N + 1) as f64 / (k as f64 * std::f64::consts::PI);
    core::array::from_fn(|i| a * ((i + 1) as f64 * k as f64 * std::f64::consts::PI / (N + 1) as f64).sin())
}

/// The chain's force `−∇V` by hand (fixed ends), as in `chain_scaling.rs`.
fn chain_force<const N: usize>(q: &[f64; N]) -> [f64; N] {
    let spring = |d: f64| d + d * d * d;
    let mut f = [0.0; N];
    let mut left = spring(q[0]);
    for i in 0..N {
        let right = spring(if i + 1 < N { q[i + 1] - q[i] } else { -q[i] });
        f[i] = right - left;
        left = right;
    }
    f
}

/// Velocity Verlet with unit mass and force `f`, `n` steps of size `h`.
fn hand_verlet<const N: usize>(
    f: impl Fn(&[f64; N]) -> [f64; N],
    weights: &[f64],
    h: f64,
    mut q: [f64; N],
    mut p: [f64; N],
    n: usize,
) -> Vec<f64> {
    let mut force = f(&q);
    for _ in 0..n {
        for w in weights {
            let hh = w * h;
            for i in 0..N {
                p[i] += 0.5 * hh * force[i];
                q[i] += hh * p[i];
            }
            force = f(&q);
            for i in 0..N {
                p[i] += 0.5 * hh * force[i];
            }
        }
        black_box(&q);
    }
    q.to_vec()
}

/// `n` steps of the bench's hand-written composition `method` (unit masses)
/// with compensated sums ([`Stepper::step_compensated`]).
fn compensated<const N: usize>(
    method: Hand,
    f: impl Fn(&[f64; N]) -> [f64; N],
    h: f64,
    q0: [f64; N],
    v0: [f64; N],
    n: usize,
) -> Vec<f64> {
    let mut s = Stepper::new(method, [1.0; N], &f, h, q0, v0);
    for _ in 0..n {
        s.step_compensated(&f);
        black_box(&s.q);
    }
    s.q.to_vec()
}

fn kepler_force(q: &[f64; 2]) -> [f64; 2] {
    let r2 = q[0] * q[0] + q[1] * q[1];
    let k = -1.0 / (r2 * r2.sqrt());
    [k * q[0], k * q[1]]
}

fn henon_heiles_force(q: &[f64; 2]) -> [f64; 2] {
    let (x, y) = (q[0], q[1]);
    [-x - 2.0 * x * y, -y - x * x + y * y]
}

fn fpu_force(q: &[f64; FPU_N]) -> [f64; FPU_N] {
    let tension = |d: f64| d + d * d * d;
    let at = |i: isize| if i < 0 || i >= FPU_N as isize { 0.0 } else { q[i as usize] };
    core::array::from_fn(|i| {
        let i = i as isize;
        tension(at(i + 1) - at(i)) - tension(at(i) - at(i - 1))
    })
}

/// Kepler e = 0.5 from pericentre (a = 1).
const KEPLER_Q0: [f64; 2] = [0.5, 0.0];
const KEPLER_V0: [f64; 2] = [0.0, 1.7320508075688772];
const HH_Q0: [f64; 2] = [0.0, 0.1];
const HH_V0: [f64; 2] = [0.4, 0.0];

fn fpu_q0() -> [f64; FPU_N] {
    core::array::from_fn(|i| 2.0 * (std::f64::consts::PI * (i + 1) as f64 / (FPU_N + 1) as f64).sin())
}

/// The run-time-sized chain of `CHAIN_N` masses stepped by `scheme`, `h = 0.05`.
fn dyn_chain(scheme: Scheme) -> lagrangian::Stepper<DynChain, lagrangian::Dyn> {
    let q0 = chain_q0::<CHAIN_N>().to_vec();
    Problem::new(DynChain(CHAIN_N), 0.0, q0, vec![0.0; CHAIN_N]).stepper(&scheme, 0.05).unwrap()
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let (case, method, n) = (args[1].as_str(), args[2].as_str(), args[3].parse::<usize>().unwrap());
    let start = std::time::Instant::now();
    let q = match (case, method) {
        ("pendulum", "hand") => {
            let mut s = PendulumMidpoint::new(PendulumParams { a: P.m * P.l * P.l, d: P.m * P.g * P.l }, H, 1.0, 0.0);
            (0..n).for_each(|_| s.step().unwrap());
            vec![s.q]
        }
        ("pendulum", "ideal") => {
            let mut s = IdealMidpoint::new(P.m * P.l * P.l, P.m * P.g * P.l, H, 1.0);
            (0..n).for_each(|_| s.step());
            vec![s.q]
        }
        ("pendulum", "verlet") => {
            let params = PendulumParams { a: P.m * P.l * P.l, d: P.m * P.g * P.l };
            let mut s = PendulumVerlet { s: params, h: H, q: 1.0, p: 0.0 };
            (0..n).for_each(|_| s.step());
            vec![s.q]
        }
        ("pendulum", "midpoint") => run(Integrator::new(Pendulum { ..P }, Midpoint, H).start(0.0, [1.0], [0.0]), n),
        ("pendulum", "problem-midpoint") => {
            let mut sim = Problem::new(Pendulum { ..P }, 0.0, [1.0], [0.0]).stepper(&Scheme::MIDPOINT, H).unwrap();
            for _ in 0..n {
                black_box(sim.step().unwrap());
            }
            sim.state().q.to_vec()
        }
        // The midpoint named directly but on the heap and stepped by a call
        // that is not inlined, as `Problem`'s dispatch steps it: the
        // dispatch's own cost is `problem-midpoint` minus this.
        ("pendulum", "boxed-midpoint") => {
            #[inline(never)]
            fn step_boxed<S: lagrangian::Lagrangian<1>>(sim: &mut lagrangian::Integrator<S, Midpoint, 1>) {
                black_box(sim.step().unwrap());
            }
            let system = HeapPendulum { m: P.m, l: P.l, g: P.g };
            let mut sim = Box::new(Integrator::new(system, Midpoint, H).start(0.0, [1.0], [0.0]).unwrap());
            for _ in 0..n {
                step_boxed(&mut sim);
            }
            sim.state().q.to_vec()
        }
        ("pendulum", "trapezoid") => run(Integrator::new(Pendulum { ..P }, Trapezoid, H).start(0.0, [1.0], [0.0]), n),
        ("pendulum", "variable") => run(
            Integrator::new(Pendulum { ..P }, Midpoint, H).energy_preserving(StepBounds::around(H)).start(
                0.0,
                [1.0],
                [0.0],
            ),
            n,
        ),
        ("double pendulum", "hand") => {
            let p = DoubleParams {
                a: (DP.m1 + DP.m2) * DP.l1 * DP.l1,
                b: DP.m2 * DP.l2 * DP.l2,
                c: DP.m2 * DP.l1 * DP.l2,
                d: (DP.m1 + DP.m2) * DP.g * DP.l1,
                e: DP.m2 * DP.g * DP.l2,
            };
            let mut s = DoubleStepper::new(p, DoubleMethod::Midpoint, H, [1.0, -0.5], [0.0, 0.5]);
            (0..n).for_each(|_| s.step().unwrap());
            s.q.to_vec()
        }
        ("double pendulum", "midpoint") => {
            run(Integrator::new(DoublePendulum { ..DP }, Midpoint, H).start(0.0, [1.0, -0.5], [0.0, 0.5]), n)
        }
        // Galerkin s = 4 at the report's step for 1e-8 over t ≤ 2 (95 steps).
        ("double pendulum", "galerkin4") => run(
            GalerkinIntegrator::new(DoublePendulum { ..DP }, Galerkin::<4, 4>::gauss(), 2.0 / 95.0).start(
                0.0,
                [1.0, -0.5],
                [0.0, 0.5],
            ),
            n,
        ),
        // The same steps solved by Newton only (no fixed-point iteration).
        ("double pendulum", "galerkin4-newton") => run(
            GalerkinIntegrator::new(
                DoublePendulum { ..DP },
                Galerkin::<4, 4>::gauss().with_iteration(lagrangian::galerkin::StageIteration::Newton),
                2.0 / 95.0,
            )
            .start(0.0, [1.0, -0.5], [0.0, 0.5]),
            n,
        ),
        ("double pendulum", "trapezoid") => {
            run(Integrator::new(DoublePendulum { ..DP }, Trapezoid, H).start(0.0, [1.0, -0.5], [0.0, 0.5]), n)
        }
        ("double pendulum", "variable") => run(
            Integrator::new(DoublePendulum { ..DP }, Midpoint, H).energy_preserving(StepBounds::around(H)).start(
                0.0,
                [0.5, 0.3],
                [0.0, 0.0],
            ),
            n,
        ),
        // `Summation::Plain`: the state's sums rounded once, as the
        // hand-written steps do.
        ("pendulum", "midpoint-plain") => {
            run(Integrator::new(Pendulum { ..P }, Midpoint, H).summation(Summation::Plain).start(0.0, [1.0], [0.0]), n)
        }
        ("pendulum", "kahan-li8-plain") => run(
            Integrator::new(Pendulum { ..P }, Composition::KAHAN_LI8, H).summation(Summation::Plain).start(
                0.0,
                [1.0],
                [0.0],
            ),
            n,
        ),
        ("double pendulum", "midpoint-plain") => run(
            Integrator::new(DoublePendulum { ..DP }, Midpoint, H).summation(Summation::Plain).start(
                0.0,
                [1.0, -0.5],
                [0.0, 0.5],
            ),
            n,
        ),
        ("kepler", "trapezoid-plain") => {
            run(Integrator::new(Kepler, Trapezoid, H).summation(Summation::Plain).start(0.0, KEPLER_Q0, KEPLER_V0), n)
        }
        ("henon-heiles", "trapezoid-plain") => {
            run(Integrator::new(HenonHeiles, Trapezoid, H).summation(Summation::Plain).start(0.0, HH_Q0, HH_V0), n)
        }
        ("fpu", "trapezoid-plain") => {
            run(Integrator::new(Fpu, Trapezoid, H).summation(Summation::Plain).start(0.0, fpu_q0(), [0.0; FPU_N]), n)
        }
        ("pendulum", "kahan-li8") => {
            run(Integrator::new(Pendulum { ..P }, Composition::KAHAN_LI8, H).start(0.0, [1.0], [0.0]), n)
        }
        ("pendulum", "hand-kahan-li8") => {
            let (a, d) = (P.m * P.l * P.l, P.m * P.g * P.l);
            // Unit mass in the coordinate `√a θ`.
            let f = |q: &[f64; 1]| [-(d / a.sqrt()) * (q[0] / a.sqrt()).sin()];
            hand_verlet(f, Composition::KAHAN_LI8.weights(), H, [a.sqrt()], [0.0], n)
        }
        ("pendulum", "hand-kahan-li8-compensated") => {
            let (a, d) = (P.m * P.l * P.l, P.m * P.g * P.l);
            // Unit mass in the coordinate `√a θ`.
            let f = |q: &[f64; 1]| [-(d / a.sqrt()) * (q[0] / a.sqrt()).sin()];
            compensated(Hand::KahanLi8, f, H, [a.sqrt()], [0.0], n)
        }
        ("pendulum", "galerkin6") => {
            run(GalerkinIntegrator::new(Pendulum { ..P }, Galerkin::<6, 6>::gauss(), 0.1).start(0.0, [1.0], [0.0]), n)
        }
        ("pendulum", "galerkin8") => {
            run(GalerkinIntegrator::new(Pendulum { ..P }, Galerkin::<8, 8>::gauss(), 0.1).start(0.0, [1.0], [0.0]), n)
        }
        ("kepler", "galerkin4") => {
            run(GalerkinIntegrator::new(Kepler, Galerkin::<4, 4>::gauss(), 0.1).start(0.0, KEPLER_Q0, KEPLER_V0), n)
        }
        ("pendulum", "galerkin6-tight") => run(
            GalerkinIntegrator::new(Pendulum { ..P }, Galerkin::<6, 6>::gauss(), 0.1)
                .newton(lagrangian::NewtonOptions { rtol: 1e-17, ..Default::default() })
                .start(0.0, [1.0], [0.0]),
            n,
        ),
        ("kepler", "galerkin6-tight") => run(
            GalerkinIntegrator::new(Kepler, Galerkin::<6, 6>::gauss(), 0.1)
                .newton(lagrangian::NewtonOptions { rtol: 1e-17, ..Default::default() })
                .start(0.0, KEPLER_Q0, KEPLER_V0),
            n,
        ),
        ("kepler", "galerkin6") => {
            run(GalerkinIntegrator::new(Kepler, Galerkin::<6, 6>::gauss(), 0.1).start(0.0, KEPLER_Q0, KEPLER_V0), n)
        }
        ("kepler", "trapezoid") => run(Integrator::new(Kepler, Trapezoid, H).start(0.0, KEPLER_Q0, KEPLER_V0), n),
        ("kepler", "verlet") => hand_verlet(kepler_force, &[1.0], H, KEPLER_Q0, KEPLER_V0, n),
        ("kepler", "verlet-compensated") => compensated(Hand::Verlet, kepler_force, H, KEPLER_Q0, KEPLER_V0, n),
        ("henon-heiles", "verlet-compensated") => compensated(Hand::Verlet, henon_heiles_force, H, HH_Q0, HH_V0, n),
        ("fpu", "verlet-compensated") => compensated(Hand::Verlet, fpu_force, H, fpu_q0(), [0.0; FPU_N], n),
        ("chain1000", "verlet-compensated") => {
            compensated(Hand::Verlet, chain_force, 0.05, chain_q0(), [0.0; CHAIN_N], n)
        }
        ("henon-heiles", "trapezoid") => run(Integrator::new(HenonHeiles, Trapezoid, H).start(0.0, HH_Q0, HH_V0), n),
        ("henon-heiles", "verlet") => hand_verlet(henon_heiles_force, &[1.0], H, HH_Q0, HH_V0, n),
        ("fpu", "trapezoid") => run(Integrator::new(Fpu, Trapezoid, H).start(0.0, fpu_q0(), [0.0; FPU_N]), n),
        ("fpu", "trapezoid-reverse") => run(
            Integrator::new(Fpu, Trapezoid, H).derivatives(lagrangian::Derivatives::Reverse).start(
                0.0,
                fpu_q0(),
                [0.0; FPU_N],
            ),
            n,
        ),
        ("fpu", "verlet") => hand_verlet(fpu_force, &[1.0], H, fpu_q0(), [0.0; FPU_N], n),
        // The same chain written with `powi(4)` (the `chain1000` form): what the
        // spelling of the quartic term costs in the generated gradient.
        ("fpu", "trapezoid-powi") => {
            run(Integrator::new(Chain::<FPU_N>, Trapezoid, H).start(0.0, fpu_q0(), [0.0; FPU_N]), n)
        }
        ("chain1000", "trapezoid") => {
            run(Integrator::new(Chain::<CHAIN_N>, Trapezoid, 0.05).start(0.0, chain_q0(), [0.0; CHAIN_N]), n)
        }
        ("chain1000", "verlet") => hand_verlet(chain_force, &[1.0], 0.05, chain_q0(), [0.0; CHAIN_N], n),
        ("chain1000", "dyn-trapezoid") => {
            let mut sim = dyn_chain(Scheme::TRAPEZOID);
            for _ in 0..n {
                black_box(sim.step().unwrap());
            }
            sim.state().q.clone()
        }
        // Newton steps of small chains in forward and in reverse mode: where
        // `Derivatives::REVERSE_MIN_N` should lie.
        ("chain8", "midpoint-forward") => newton_mode::<8>(lagrangian::Derivatives::Forward, n),
        ("chain8", "midpoint-reverse") => newton_mode::<8>(lagrangian::Derivatives::Reverse, n),
        ("chain10", "midpoint-forward") => newton_mode::<10>(lagrangian::Derivatives::Forward, n),
        ("chain10", "midpoint-reverse") => newton_mode::<10>(lagrangian::Derivatives::Reverse, n),
        ("chain12", "midpoint-forward") => newton_mode::<12>(lagrangian::Derivatives::Forward, n),
        ("chain12", "midpoint-reverse") => newton_mode::<12>(lagrangian::Derivatives::Reverse, n),
        ("nlink4", "midpoint-forward") => nlink_mode::<4>(lagrangian::Derivatives::Forward, n),
        ("nlink4", "midpoint-reverse") => nlink_mode::<4>(lagrangian::Derivatives::Reverse, n),
        ("nlink8", "midpoint-forward") => nlink_mode::<8>(lagrangian::Derivatives::Forward, n),
        ("nlink8", "midpoint-reverse") => nlink_mode::<8>(lagrangian::Derivatives::Reverse, n),
        ("nlink12", "midpoint-forward") => nlink_mode::<12>(lagrangian::Derivatives::Forward, n),
        ("nlink12", "midpoint-reverse") => nlink_mode::<12>(lagrangian::Derivatives::Reverse, n),
        ("nlink16", "midpoint-forward") => nlink_mode::<16>(lagrangian::Derivatives::Forward, n),
        ("nlink16", "midpoint-reverse") => nlink_mode::<16>(lagrangian::Derivatives::Reverse, n),
        ("chain16", "midpoint-forward") => newton_mode::<16>(lagrangian::Derivatives::Forward, n),
        ("chain16", "midpoint-reverse") => newton_mode::<16>(lagrangian::Derivatives::Reverse, n),
        ("chain24", "midpoint-forward") => newton_mode::<24>(lagrangian::Derivatives::Forward, n),
        ("chain24", "midpoint-reverse") => newton_mode::<24>(lagrangian::Derivatives::Reverse, n),
        ("chain32", "midpoint-forward") => newton_mode::<32>(lagrangian::Derivatives::Forward, n),
        ("chain32", "midpoint-reverse") => newton_mode::<32>(lagrangian::Derivatives::Reverse, n),
        ("chain1000", "trapezoid-plain") => run(
            Integrator::new(Chain::<CHAIN_N>, Trapezoid, 0.05).summation(Summation::Plain).start(
                0.0,
                chain_q0(),
                [0.0; CHAIN_N],
            ),
            n,
        ),
        ("chain1000", "dyn-yoshida4") => {
            let mut sim =
                dyn_chain(Scheme::composition(Composition::YOSHIDA4, lagrangian::problem::OnePoint::Trapezoid));
            for _ in 0..n {
                black_box(sim.step().unwrap());
            }
            sim.state().q.clone()
        }
        ("chain1000", "verlet-compensated-inplace") => compensated_in_place(0.05, &chain_q0::<CHAIN_N>(), n),
        // Reverse-mode Newton steps (midpoint) and sub-stepped explicit
        // compositions (Yoshida 4) of the same chain.
        ("chain1000", "midpoint") => {
            run(Integrator::new(Chain::<CHAIN_N>, Midpoint, 0.05).start(0.0, chain_q0(), [0.0; CHAIN_N]), n)
        }
        ("chain1000", "yoshida4") => big_stack(move || {
            run(
                Integrator::new(Chain::<CHAIN_N>, Composition::YOSHIDA4, 0.05).start(0.0, chain_q0(), [0.0; CHAIN_N]),
                n,
            )
        }),
        // The bits of every readout after `n` steps, to compare two builds.
        ("chain1000", "digest-trapezoid") => {
            digest(Integrator::new(Chain::<CHAIN_N>, Trapezoid, 0.05).start(0.0, chain_q0(), [0.0; CHAIN_N]), n)
        }
        ("chain1000", "digest-midpoint") => {
            digest(Integrator::new(Chain::<CHAIN_N>, Midpoint, 0.05).start(0.0, chain_q0(), [0.0; CHAIN_N]), n)
        }
        ("chain1000", "digest-yoshida4") => big_stack(move || {
            digest(
                Integrator::new(Chain::<CHAIN_N>, Composition::YOSHIDA4, 0.05).start(0.0, chain_q0(), [0.0; CHAIN_N]),
                n,
            )
        }),
        // The generated gradient `∂L/∂q` alone against the hand-written
        // force it replaces in the explicit step (`gradient-powi`: the FPU
        // chain written with `d.powi(4)`).
        ("fpu", "gradient") => repeat(|q, out| Fpu.gradient_q(0.0, q, &[0.0; FPU_N], out), fpu_q0(), n),
        ("fpu", "gradient-powi") => repeat(|q, out| Chain::<FPU_N>.gradient_q(0.0, q, &[0.0; FPU_N], out), fpu_q0(), n),
        ("fpu", "force") => repeat(|q, out| *out = fpu_force(q), fpu_q0(), n),
        ("chain1000", "gradient") => {
            repeat(|q, out| Chain::<CHAIN_N>.gradient_q(0.0, q, &[0.0; CHAIN_N], out), chain_q0(), n)
        }
        ("chain1000", "force") => repeat(|q, out| *out = chain_force(q), chain_q0::<CHAIN_N>(), n),
        ("kepler", "gradient") => repeat(|q, out| Kepler.gradient_q(0.0, q, &[0.0; 2], out), KEPLER_Q0, n),
        ("kepler", "force") => repeat(|q, out| *out = kepler_force(q), KEPLER_Q0, n),
        ("henon-heiles", "gradient") => repeat(|q, out| HenonHeiles.gradient_q(0.0, q, &[0.0; 2], out), HH_Q0, n),
        ("henon-heiles", "force") => repeat(|q, out| *out = henon_heiles_force(q), HH_Q0, n),
        (_, "derivatives") => {
            // The derivative evaluation alone: one `step_derivatives` (residual
            // part, momentum, Jacobian) per "step", at nearby segments (every input
            // varies, so that nothing is hoisted out of the loop).
            let mut acc = 0.0;
            for k in 0..n {
                let x = black_box(1e-9 * k as f64);
                acc += if case == "pendulum" {
                    let seg = Segment { t0: 0.0, h: H, q0: [1.0 + x], dq: [0.001 + x] };
                    step_derivatives(&Pendulum { ..P }, &Midpoint, &seg).d2_q0_q1[0]
                } else {
                    let seg = Segment { t0: 0.0, h: H, q0: [1.0 + x, -0.5 - x], dq: [0.001 + x, 0.002 - x] };
                    step_derivatives(&DoublePendulum { ..DP }, &Midpoint, &seg).d2_q0_q1[(0, 1)]
                };
            }
            vec![acc]
        }
        ("double pendulum", "energy") => {
            // A step and the energy readout `E_L(q_k, v(p_k))` (inverse Legendre transform) after each.
            let mut sim =
                Integrator::new(DoublePendulum { ..DP }, Midpoint, H).start(0.0, [1.0, -0.5], [0.0, 0.5]).unwrap();
            let mut e = 0.0;
            for _ in 0..n {
                sim.step().unwrap();
                e += sim.energy().unwrap();
            }
            vec![e]
        }
        ("double pendulum", "damped") => run(
            Integrator::new(DampedDoublePendulum { p: DoublePendulum { ..DP }, c: 0.05 }, Midpoint, H).start(
                0.0,
                [1.0, -0.5],
                [0.0, 0.5],
            ),
            n,
        ),
        (_, m) if m.starts_with("trace-") => {
            // Every node's positions, one line each as the bits of the f64s,
            // to compare the trajectories of two builds exactly.
            let rule = &m["trace-".len()..];
            let lines = if case == "pendulum" {
                trace(TracePendulum { m: P.m, l: P.l, g: P.g }, rule, [1.0], [0.0], n)
            } else {
                let system = TraceDoublePendulum { m1: DP.m1, m2: DP.m2, l1: DP.l1, l2: DP.l2, g: DP.g };
                trace(system, rule, [1.0, -0.5], [0.0, 0.5], n)
            };
            println!("{lines}");
            vec![]
        }
        _ => panic!("unknown case {case:?} {method:?}"),
    };
    let ns = start.elapsed().as_nanos() as f64 / n.max(1) as f64;
    println!("{ns:.1} ns/step, q = {:?}", black_box(q));
}

/// `n` evaluations of a gradient or force `f` at positions that differ
/// from `q0` in the first coordinate (nothing is hoisted out of the loop);
/// every result is kept (`black_box`), so no component is skipped.
fn repeat<const N: usize>(f: impl Fn(&[f64; N], &mut [f64; N]), q0: [f64; N], n: usize) -> Vec<f64> {
    let (mut q, mut out, mut acc) = (q0, [0.0; N], 0.0);
    for k in 0..n {
        q[0] = q0[0] + black_box(1e-9 * k as f64);
        f(black_box(&q), &mut out);
        acc += black_box(&out)[N - 1];
    }
    vec![acc]
}

/// `n` steps of `rule` (`midpoint`, `trapezoid` or `alpha-beta`, α = 0.3),
/// the positions of every node as hexadecimal bit patterns.
fn trace<S: lagrangian::Lagrangian<N>, const N: usize>(
    system: S,
    rule: &str,
    q0: [f64; N],
    v0: [f64; N],
    n: usize,
) -> String {
    fn lines<S: lagrangian::Lagrangian<N>, M: lagrangian::Method<f64>, const N: usize>(
        mut sim: lagrangian::Integrator<S, M, N>,
        n: usize,
    ) -> String {
        let mut out = String::new();
        for _ in 0..n {
            sim.step().unwrap();
            let bits: Vec<String> = sim.state().q.iter().map(|x| format!("{:016x}", x.to_bits())).collect();
            out += &bits.join(" ");
            out.push('\n');
        }
        out
    }
    match rule {
        "midpoint" => lines(Integrator::new(system, Midpoint, H).start(0.0, q0, v0).unwrap(), n),
        // Newton's `rtol` at 1e-16: how far a change within the default tolerance carries it.
        "midpoint-tight" => lines(
            Integrator::new(system, Midpoint, H)
                .newton(lagrangian::NewtonOptions { rtol: 1e-16, ..Default::default() })
                .start(0.0, q0, v0)
                .unwrap(),
            n,
        ),
        // The first coordinate one ulp up: how far round-off alone carries the trajectory.
        "midpoint-nudged" => {
            let mut q0 = q0;
            q0[0] = f64::from_bits(q0[0].to_bits() + 1);
            lines(Integrator::new(system, Midpoint, H).start(0.0, q0, v0).unwrap(), n)
        }
        "trapezoid" => lines(Integrator::new(system, Trapezoid, H).start(0.0, q0, v0).unwrap(), n),
        "alpha-beta" => {
            let rule = lagrangian::AlphaBeta::new(0.3).unwrap();
            lines(Integrator::new(system, rule, H).start(0.0, q0, v0).unwrap(), n)
        }
        _ => panic!("unknown rule {rule:?}"),
    }
}

/// `f` in a thread with a 256 MiB stack: a composition's integrator at
/// `N = 1000` (its sub-steps and sub-integrator inline, 15 segments of 16 kB)
/// overflows the main thread's 8 MiB.
fn big_stack(f: impl FnOnce() -> Vec<f64> + Send + 'static) -> Vec<f64> {
    std::thread::Builder::new().stack_size(256 << 20).spawn(f).unwrap().join().unwrap()
}

/// FNV-1a over the bits of `values`.
fn fnv(values: &[f64]) -> u64 {
    values.iter().fold(0xcbf2_9ce4_8422_2325, |h, x| (h ^ x.to_bits()).wrapping_mul(0x100_0000_01b3))
}

/// `n` steps, then the bits of the state and of every readout (digests of
/// the arrays), to compare the trajectories of two builds exactly.
fn digest<S: lagrangian::Lagrangian<N>, M: lagrangian::F64Readouts, const N: usize>(
    sim: Result<lagrangian::Integrator<S, M, N>, lagrangian::Error>,
    n: usize,
) -> Vec<f64> {
    let mut sim = sim.unwrap();
    sim.run(n, |_| {}).unwrap();
    let s = sim.state();
    println!("step {} t {:016x}", s.step, s.t.to_bits());
    println!("q {:016x} p {:016x}", fnv(&s.q), fnv(&s.p));
    println!("discrete energy {:016x}", sim.discrete_energy().to_bits());
    println!("last step size {:?}", sim.last_step_size().map(f64::to_bits));
    println!("velocity {:016x}", fnv(&sim.velocity().unwrap()));
    println!("energy {:016x}", sim.energy().unwrap().to_bits());
    // One more step after the readouts (the predictor and the caches).
    sim.step().unwrap();
    println!("next q {:016x} p {:016x}", fnv(&sim.state().q), fnv(&sim.state().p));
    println!("stats {:?}", sim.stats());
    vec![]
}

/// `n` compensated Störmer–Verlet steps of the chain (unit masses) on slices
/// in place: the fair large-N baseline of the generated explicit step, with
/// the same Kahan sums of `q` and `p` (`tape_step.rs`) and the force written
/// into a buffer, no arrays returned by value.
fn compensated_in_place(h: f64, q0: &[f64], n: usize) -> Vec<f64> {
    let len = q0.len();
    let (mut q, mut qc, mut p, mut pc) = (q0.to_vec(), vec![0.0; len], vec![0.0; len], vec![0.0; len]);
    // The forces at the node and at the next node, swapped after each step.
    let (mut f0, mut f1) = (vec![0.0; len], vec![0.0; len]);
    let kahan = |a: f64, c: f64, b: f64| {
        let u = c + b;
        let sum = a + u;
        (sum, u - (sum - a))
    };
    let force = |q: &[f64], f: &mut [f64]| {
        let spring = |d: f64| d + d * d * d;
        let mut left = spring(q[0]);
        for i in 0..q.len() {
            let right = spring(if i + 1 < q.len() { q[i + 1] - q[i] } else { -q[i] });
            f[i] = right - left;
            left = right;
        }
    };
    let half = 0.5 * h;
    force(&q, &mut f0);
    for _ in 0..n {
        // Half kick and drift in one pass (`p` itself changes at the end);
        // the slices cut to one length, so that the loops have no bounds checks.
        let (q, qc, p, pc) = (&mut q[..len], &mut qc[..len], &mut p[..len], &mut pc[..len]);
        let old = &f0[..len];
        for i in 0..len {
            let x = ((p[i] + half * old[i]) + pc[i]) * h;
            (q[i], qc[i]) = kahan(q[i], qc[i], x);
        }
        force(q, &mut f1);
        // Both half kicks as one compensated sum.
        let new = &f1[..len];
        for i in 0..len {
            (p[i], pc[i]) = kahan(p[i], pc[i], half * (old[i] + new[i]));
        }
        core::mem::swap(&mut f0, &mut f1);
        black_box(&q);
    }
    q
}

/// `n` midpoint steps of the chain of `N` masses with the given derivatives.
fn newton_mode<const N: usize>(mode: lagrangian::Derivatives, n: usize) -> Vec<f64> {
    run(Integrator::new(Chain::<N>, Midpoint, 0.05).derivatives(mode).start(0.0, chain_q0(), [0.0; N]), n)
}

fn run<S: lagrangian::Lagrangian<N>, M: lagrangian::Method<f64>, const N: usize>(
    sim: Result<lagrangian::Integrator<S, M, N>, lagrangian::Error>,
    n: usize,
) -> Vec<f64> {
    let mut sim = sim.unwrap();
    for _ in 0..n {
        black_box(sim.step().unwrap());
    }
    let s = sim.stats();
    eprintln!("newton iterations per step: {:.3}", s.newton_iterations as f64 / s.steps as f64);
    sim.state().q.to_vec()
}

/// The generated pendulum midpoint step's algorithm written out by hand:
/// quadratic predictor, Newton on the increment with the runtime's
/// tolerance (`1e-14` relative), the inverse Jacobian kept once the
/// relative correction is below `1e-3`, the momentum from `p_k + h L_q`,
/// compensated sums; the momentum change from `L_q` evaluated at the
/// solution. What the generic machinery costs on top of the algorithm.
struct IdealMidpoint {
    a: f64,
    d: f64,
    h: f64,
    q: f64,
    qc: f64,
    p: f64,
    pc: f64,
    last: f64,
    earlier: f64,
}

impl IdealMidpoint {
    fn new(a: f64, d: f64, h: f64, q0: f64) -> Self {
        // Zero last increments: the first steps' predictor is not the
        // integrator's, the steps after are the same algorithm.
        Self { a, d, h, q: q0, qc: 0.0, p: 0.0, pc: 0.0, last: 0.0, earlier: 0.0 }
    }

    #[inline(never)]
    fn step(&mut self) {
        let (a, d, h) = (self.a, self.d, self.h);
        let (q, p, pc) = (self.q, self.p, self.pc);
        let mut x = 2.0 * self.last - self.earlier;
        let mut inv = 0.0;
        let mut keep = false;
        let mut prev = f64::INFINITY;
        let mut first = true;
        for _ in 0..25 {
            let qm = q + 0.5 * x;
            let r;
            if keep {
                let s = qm.sin();
                r = (p + (-0.5 * h * d * s - a * x / h)) + pc;
            } else {
                let (s, c) = qm.sin_cos();
                r = (p + (-0.5 * h * d * s - a * x / h)) + pc;
                let j = -0.25 * h * d * c - a / h;
                inv = 1.0 / j;
                assert!(inv.is_finite());
            }
            let dx = -inv * r;
            x += dx;
            let ratio = dx.abs() / (1e-14 * x.abs() + 1e-300);
            if ratio <= 1.0 {
                break;
            }
            let margin = if keep { 100.0 } else { 1.0 };
            if !first && ratio < prev && margin * ratio * ratio <= prev - ratio {
                break;
            }
            keep = (first || 4.0 * ratio <= prev) && ratio * 1e-14 <= 1e-3;
            first = false;
            prev = ratio;
        }
        let dp = -h * d * (q + 0.5 * x).sin();
        let (q1, qc1) = kahan(q, self.qc, x);
        let (p1, pc1) = kahan(p, pc, dp);
        assert!(q1.is_finite() && p1.is_finite());
        (self.q, self.qc, self.p, self.pc) = (q1, qc1, p1, pc1);
        (self.earlier, self.last) = (self.last, x);
    }
}

#[inline(always)]
fn kahan(s: f64, c: f64, x: f64) -> (f64, f64) {
    let y = x + c;
    let t = s + y;
    (t, y - (t - s))
}
