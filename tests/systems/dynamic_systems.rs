//! Verification: systems whose size is known only at run time
//! (`DynLagrangian`), written here by hand, and the run-time-sized
//! integrator behind `Problem<S, Dyn>`, named directly where its own steps
//! are compared with the const-size integrator's (a hidden item of the
//! runtime crate); landing and bad input go through `Problem`.
//!
//! - The run-time-sized integrator and the const-size integrator's reverse
//!   mode take the same steps (to 1e-14) on the same system: an FPU-β chain
//!   (midpoint, and trapezoid on its explicit path) and coupled pendula
//!   (non-separable, banded; midpoint).
//! - Compositions (Yoshida 4, Kahan–Li 8) take the const-size integrator's
//!   steps: fused explicit sub-steps, or Newton sub-steps one by one.
//! - An FPU-β chain of 100 000 masses runs in a thread with a 2 MiB stack.
//! - The energy error of a chain of 1 000 is bounded without drift.
//! - Bad input is a typed error; a failed step changes nothing and a retry
//!   with a good step succeeds.
//! - Newton steps from the generated gradient code on dual numbers (forward
//!   over reverse, `#[lagrangian]` over slices) against the tape path of
//!   the same body: same trajectories to round-off and the same Newton
//!   iterations (FPU-β chain and coupled pendula, N = 16 and 300; midpoint,
//!   trapezoid with Newton, α-β); a chain of 1 000 without energy drift and
//!   one of 100 000 in a 2 MiB thread on that path.
use lagrangian::prelude::*;
use lagrangian::{Composition, Coupling, Derivatives, Pattern, Separability};
use lagrangian_runtime::{DynIntegrator, DynMethod};

/// An FPU-β chain with fixed ends, unit masses and springs, of run-time length.
#[derive(Clone)]
struct DynFpu {
    n: usize,
    beta: f64,
}

/// A tridiagonal `q–q` block, nothing else coupled.
const CHAIN: Coupling =
    Coupling { q_q: Pattern::Banded { bandwidth: 1 }, q_v: Pattern::Diagonal, v_v: Pattern::Diagonal };

impl DynLagrangian for DynFpu {
    const AUTONOMOUS: bool = true;
    const SEPARABILITY: Separability = Separability::ConstantMass;
    const COUPLING: Coupling = CHAIN;

    fn dimension(&self) -> usize {
        self.n
    }

    fn lagrangian<D: Scalar>(&self, _t: D, q: &[D], v: &[D]) -> D {
        let n = q.len();
        let spring = |d: D| d * d * 0.5 + d.powi(4) * (0.25 * self.beta);
        let mut kinetic = D::zero();
        for x in v {
            kinetic += *x * *x * 0.5;
        }
        let mut potential = spring(q[0]) + spring(q[n - 1]);
        for i in 0..n - 1 {
            potential += spring(q[i + 1] - q[i]);
        }
        kinetic - potential
    }
}

/// Pendula coupled to their neighbours through the kinetic energy and a
/// torsion spring: not separable, banded, mass matrix depending on `q`.
#[derive(Clone)]
struct DynPendula {
    n: usize,
    /// Kinetic coupling (below ½ keeps the mass matrix positive definite).
    c: f64,
    /// Torsion spring.
    k: f64,
}

impl DynLagrangian for DynPendula {
    const AUTONOMOUS: bool = true;
    const SEPARABILITY: Separability = Separability::QuadraticKinetic;
    const COUPLING: Coupling = Coupling {
        q_q: Pattern::Banded { bandwidth: 1 },
        q_v: Pattern::Banded { bandwidth: 1 },
        v_v: Pattern::Banded { bandwidth: 1 },
    };

    fn dimension(&self) -> usize {
        self.n
    }

    fn lagrangian<D: Scalar>(&self, _t: D, q: &[D], v: &[D]) -> D {
        let mut l = D::zero();
        for i in 0..q.len() {
            l += v[i] * v[i] * 0.5 + q[i].cos();
        }
        for i in 1..q.len() {
            let (a, b) = (i - 1, i);
            l += v[a] * v[b] * (q[a] - q[b]).cos() * self.c - (q[b] - q[a]).powi(2) * (0.5 * self.k);
        }
        l
    }
}

/// A run-time-sized system as a const-size one, with the same body and the
/// same proven structure: what the const-size integrator steps when both
/// are compared.
struct Fixed<S, const N: usize>(S);

impl<S: DynLagrangian, const N: usize> Lagrangian<N> for Fixed<S, N> {
    const AUTONOMOUS: bool = S::AUTONOMOUS;
    const CYCLIC: [bool; N] = [false; N];
    const SEPARABILITY: Separability = S::SEPARABILITY;
    const COUPLING: Coupling = S::COUPLING;

    fn lagrangian<D: Scalar>(&self, t: D, q: [D; N], v: [D; N]) -> D {
        self.0.lagrangian(t, &q, &v)
    }
}

/// Normal mode `k` of a chain of `n` with fixed ends, scaled so that the
/// largest spring strain is `strain` (0.3: well into the quartic regime).
fn chain_mode(n: usize, k: usize, strain: f64) -> Vec<f64> {
    let a = strain * (n + 1) as f64 / (k as f64 * core::f64::consts::PI);
    (0..n).map(|i| a * ((i + 1) as f64 * k as f64 * core::f64::consts::PI / (n + 1) as f64).sin()).collect()
}

/// Largest difference of `q` and `p` between the run-time-sized integrator
/// and the const-size one in reverse mode over `steps` steps, relative to the
/// largest `|q|`, `|p|`; and the Newton iterations of each.
fn path_difference<S, M, const N: usize>(system: impl Fn() -> S, method: M, h: f64, steps: usize) -> (f64, u64, u64)
where
    S: DynLagrangian,
    M: F64Readouts + DynMethod + Copy,
{
    let q0 = chain_mode(N, 2, 0.3);
    let v0: Vec<f64> = (0..N).map(|i| 0.1 * (i as f64).sin()).collect();
    let mut fixed = Integrator::new(Fixed::<S, N>(system()), method, h)
        .derivatives(Derivatives::Reverse)
        .start(0.0, core::array::from_fn(|i| q0[i]), core::array::from_fn(|i| v0[i]))
        .unwrap();
    let mut dynamic = DynIntegrator::new(system(), method, h).start(0.0, &q0, &v0).unwrap();
    let mut worst: f64 = 0.0;
    for _ in 0..steps {
        fixed.step().unwrap();
        dynamic.step().unwrap();
        let (a, b) = (fixed.state(), dynamic.state());
        let scale = a.q.iter().chain(a.p.iter()).fold(1e-300f64, |m, x| m.max(x.abs()));
        for i in 0..N {
            worst = worst.max((a.q[i] - b.q[i]).abs() / scale).max((a.p[i] - b.p[i]).abs() / scale);
        }
        assert_eq!(a.t, b.t);
    }
    let rel = (fixed.discrete_energy() - dynamic.discrete_energy()).abs() / fixed.discrete_energy().abs();
    assert!(rel <= 1e-14, "discrete energy: {rel:e}");
    (worst, fixed.stats().newton_iterations, dynamic.stats().newton_iterations)
}

#[test]
fn run_time_sized_and_const_size_reverse_paths_agree() {
    let fpu = || DynFpu { n: 16, beta: 1.0 };
    let pendula = || DynPendula { n: 16, c: 0.3, k: 0.5 };
    let (d, f, r) = path_difference::<_, _, 16>(fpu, Midpoint, 0.05, 100);
    println!("FPU-β N = 16, midpoint: difference {d:.2e}, Newton iterations {f} / {r}");
    assert!(d <= 1e-14 && f == r && r >= 100, "{d:e} {f} {r}");
    let (d, f, r) = path_difference::<_, _, 16>(fpu, Trapezoid, 0.05, 100);
    println!("FPU-β N = 16, trapezoid (explicit): difference {d:.2e}, Newton iterations {f} / {r}");
    assert!(d <= 1e-14 && f == 0 && r == 0, "{d:e} {f} {r}");
    let (d, f, r) = path_difference::<_, _, 16>(pendula, Midpoint, 0.05, 100);
    println!("coupled pendula N = 16, midpoint: difference {d:.2e}, Newton iterations {f} / {r}");
    assert!(d <= 1e-14 && f == r && r >= 100, "{d:e} {f} {r}");
    // The α-β rule's action comes from its quadrature point too.
    let euler = lagrangian::AlphaBeta::new(0.3).unwrap();
    let (d, _, _) = path_difference::<_, _, 16>(pendula, euler, 0.05, 100);
    assert!(d <= 1e-14, "α-β: {d:e}");
    // Trapezoid on a non-separable system: Newton with both quadrature points.
    let (d, _, r) = path_difference::<_, _, 16>(pendula, Trapezoid, 0.05, 100);
    assert!(d <= 1e-14 && r >= 100, "trapezoid, Newton: {d:e}");
}

#[test]
fn a_chain_of_100_000_masses_runs_in_a_2_mib_thread() {
    std::thread::Builder::new()
        .stack_size(2 << 20)
        .spawn(|| {
            let n = 100_000;
            let h = 0.05;
            let q0 = chain_mode(n, n / 10, 0.3);
            let system = || DynFpu { n, beta: 1.0 };
            let mut midpoint = DynIntegrator::new(system(), Midpoint, h).start(0.0, &q0, &vec![0.0; n]).unwrap();
            let e0 = midpoint.energy().unwrap();
            midpoint.run(3, |_| {}).unwrap();
            let mut trapezoid = DynIntegrator::new(system(), Trapezoid, h).start(0.0, &q0, &vec![0.0; n]).unwrap();
            trapezoid.run(10, |_| {}).unwrap();
            assert_eq!(trapezoid.stats().newton_iterations, 0);
            let start = |method| DynIntegrator::new(system(), method, h).start(0.0, &q0, &vec![0.0; n]).unwrap();
            let mut yoshida = start(Composition::YOSHIDA4);
            yoshida.run(3, |_| {}).unwrap();
            for (name, state, e) in [
                ("midpoint, 3 steps", midpoint.state(), midpoint.energy().unwrap()),
                ("trapezoid, 10 steps", trapezoid.state(), trapezoid.energy().unwrap()),
                ("Yoshida 4, 3 steps", yoshida.state(), yoshida.energy().unwrap()),
            ] {
                assert!(state.q.iter().chain(&state.p).all(|x| x.is_finite()), "{name}");
                let error = (e - e0).abs() / e0;
                println!("FPU-β N = 100 000, {name}: relative energy error {error:.2e}");
                // O((ωh)²) with ω ≤ 2, h = 0.05; and the state moved.
                assert!(error < 2e-3 && error > 1e-12, "{name}: {error:e}");
            }
        })
        .unwrap()
        .join()
        .expect("no stack overflow, no panic");
}

#[test]
fn the_energy_error_of_a_chain_of_1000_does_not_drift() {
    // Mode 100 with strains of 0.3, 4 000 midpoint steps (t = 200, about
    // 10 periods): the error oscillates; a drift would make the second
    // half's largest error grow beyond the first half's.
    let n = 1000;
    let mut sim = DynIntegrator::new(DynFpu { n, beta: 1.0 }, Midpoint, 0.05)
        .start(0.0, &chain_mode(n, 100, 0.3), &vec![0.0; n])
        .unwrap();
    let e0 = sim.energy().unwrap();
    let mut errors = Vec::new();
    for _ in 0..200 {
        sim.run(20, |_| {}).unwrap();
        errors.push((sim.energy().unwrap() - e0).abs() / e0);
    }
    let (first, second) = errors.split_at(errors.len() / 2);
    let max = |s: &[f64]| s.iter().copied().fold(0.0f64, f64::max);
    let (a, b) = (max(first), max(second));
    println!("FPU-β N = 1000 (run-time sized), midpoint: largest energy error {a:.3e} (t ≤ 100), {b:.3e} (t > 100)");
    assert!(a > 0.0 && a < 2e-3 && b < 1.5 * a, "{a:e} {b:e}");
}

#[test]
fn run_until_lands_exactly() {
    let n = 50;
    let problem = Problem::new(DynFpu { n, beta: 1.0 }, 0.0, chain_mode(n, 3, 0.2), vec![0.0; n]);
    let mut sim = problem.stepper(&Scheme::TRAPEZOID, 0.03).unwrap();
    sim.run_until(1.0).unwrap();
    assert_eq!(sim.state().t, 1.0);
    assert_eq!(sim.stats().steps, 34);
    assert_eq!(sim.step_size(), 0.03);
    assert!((sim.last_step_size().unwrap() - 0.01).abs() < 1e-12);
    // A no-op: no step taken.
    sim.run_until(1.0).unwrap();
    assert_eq!(sim.stats().steps, 34);
    let before = sim.state().clone();
    assert!(matches!(sim.run_until(0.5), Err(Error::InvalidTarget { target: 0.5, .. })));
    assert!(matches!(sim.run_until(f64::NAN), Err(Error::InvalidTarget { .. })));
    assert_eq!(sim.state(), &before);
}

/// A rule without quadrature points.
#[derive(Clone, Copy, Debug)]
struct Opaque;

impl DiscreteLagrangian for Opaque {
    fn order(&self) -> u32 {
        2
    }

    fn action<S, D, const N: usize>(&self, system: &S, t0: D, h: D, q0: [D; N], dq: [D; N]) -> D
    where
        S: Lagrangian<N> + ?Sized,
        D: Scalar,
    {
        Midpoint.action(system, t0, h, q0, dq)
    }
}

/// A chain whose last coordinate has no mass: `∂²L/∂v²` is singular.
#[derive(Clone)]
struct MasslessEnd(usize);

impl DynLagrangian for MasslessEnd {
    const AUTONOMOUS: bool = true;

    fn dimension(&self) -> usize {
        self.0
    }

    fn lagrangian<D: Scalar>(&self, _t: D, q: &[D], v: &[D]) -> D {
        let mut l = D::zero();
        for i in 0..q.len() {
            l -= q[i] * q[i] * 0.5;
            if i + 1 < q.len() {
                l += v[i] * v[i] * 0.5;
            }
        }
        l
    }
}

#[test]
fn bad_input_is_a_typed_error() {
    let n = 20;
    let fpu = || DynFpu { n, beta: 1.0 };
    let q0 = chain_mode(n, 2, 0.3);
    let zero = vec![0.0; n];
    let start = |h: f64, q: &[f64], v: &[f64]| Problem::new(fpu(), 0.0, q, v).stepper(&Scheme::MIDPOINT, h).map(|_| ());
    assert_eq!(start(0.05, &q0[1..], &zero), Err(Error::WrongLength { what: "q0", expected: n, found: n - 1 }));
    assert_eq!(start(0.05, &q0, &[0.0; 3]), Err(Error::WrongLength { what: "v0", expected: n, found: 3 }));
    let mut nan = q0.clone();
    nan[7] = f64::NAN;
    assert!(matches!(start(0.05, &nan, &zero), Err(Error::InvalidInitialData { .. })));
    for h in [0.0, -0.05, f64::NAN, f64::INFINITY] {
        assert!(matches!(start(h, &q0, &zero), Err(Error::InvalidStepSize { .. })), "h = {h}");
    }
    // A rule of one's own is the driver's business (`Scheme` names none).
    assert!(matches!(DynIntegrator::new(fpu(), Opaque, 0.05).start(0.0, &q0, &zero), Err(Error::Unsupported { .. })));
    assert!(matches!(
        Problem::new(MasslessEnd(8), 0.0, vec![0.1; 8], vec![0.0; 8]).stepper(&Scheme::MIDPOINT, 0.05),
        Err(Error::InvalidInitialData { .. })
    ));
    assert!(matches!(
        Problem::new(DynFpu { n: 0, beta: 1.0 }, 0.0, vec![], vec![]).stepper(&Scheme::MIDPOINT, 0.05),
        Err(Error::InvalidInitialData { .. })
    ));
    let bad_newton = NewtonOptions { rtol: -1.0, ..NewtonOptions::default() };
    assert!(matches!(
        Problem::new(fpu(), 0.0, q0.clone(), zero.clone()).newton(bad_newton).stepper(&Scheme::MIDPOINT, 0.05),
        Err(Error::InvalidNewtonOptions { .. })
    ));
}

/// An absurd step fails with a typed error carrying the state, changes
/// nothing, and a retry with the old step continues as if it never failed.
fn fail_and_retry(scheme: Scheme, absurd: f64, expected: fn(&Error) -> bool) {
    fail_and_retry_with(|| DynFpu { n: 64, beta: 1.0 }, scheme, absurd, expected);
}

/// [`fail_and_retry`] on the system `system()` of 64 coordinates.
fn fail_and_retry_with<S: DynLagrangian + Clone>(
    system: impl Fn() -> S,
    scheme: Scheme,
    absurd: f64,
    expected: fn(&Error) -> bool,
) {
    let n = 64;
    let q0 = chain_mode(n, 5, 0.3);
    let start = || Problem::new(system(), 0.0, q0.clone(), vec![0.0; n]).stepper(&scheme, 0.05).unwrap();
    let mut sim = start();
    sim.run(5, |_| {}).unwrap();
    let (before, stats, energy) = (sim.state().clone(), sim.stats(), sim.discrete_energy());
    assert!(matches!(sim.set_step_size(0.0), Err(Error::InvalidStepSize { .. })));
    assert!(matches!(sim.set_step_size(f64::NAN), Err(Error::InvalidStepSize { .. })));
    sim.set_step_size(absurd).unwrap();
    let failure = sim.step().map(|_| ()).unwrap_err();
    println!("{}: {failure}", scheme.name());
    assert!(expected(&failure), "{failure:?}");
    match &failure {
        Error::NewtonDidNotConverge { state, .. }
        | Error::SingularJacobian { state, .. }
        | Error::NonFinite { state, .. }
        | Error::StepRejected { state, .. } => assert_eq!(state, &before),
        other => panic!("unexpected error {other:?}"),
    }
    assert_eq!(sim.state(), &before);
    assert_eq!(sim.discrete_energy(), energy);
    assert_eq!((sim.stats().steps, sim.stats().failed_steps), (stats.steps, stats.failed_steps + 1));
    sim.set_step_size(0.05).unwrap();
    sim.run(5, |_| {}).unwrap();
    let mut clean = start();
    clean.run(10, |_| {}).unwrap();
    let (a, b) = (sim.state(), clean.state());
    assert_eq!((a.step, &a.q, &a.p), (b.step, &b.q, &b.p), "{}", scheme.name());
    assert!((a.t - b.t).abs() <= 1e-15);
}

#[test]
fn a_failed_step_changes_nothing_and_a_retry_succeeds() {
    // The quartic springs at h = 1000: Newton's corrections stop shrinking.
    let yoshida4 = Scheme::composition(Composition::YOSHIDA4, lagrangian::problem::OnePoint::Trapezoid);
    fail_and_retry(
        Scheme::MIDPOINT,
        1e3,
        |e| matches!(e, Error::NewtonDidNotConverge { iterations, .. } if *iterations > 1),
    );
    // The explicit step at h = 1e100: the forces overflow. (At h = 1e12 it
    // still returns a finite state: the quadratic predictor extrapolates as
    // far as the step goes, so the plausibility check does not fire.)
    fail_and_retry(Scheme::TRAPEZOID, 1e100, |e| matches!(e, Error::NonFinite { quantity: "momentum", .. }));
    // A fused composition: the positions overflow.
    fail_and_retry(yoshida4.clone(), 1e100, |e| matches!(e, Error::NonFinite { .. }));
    // Newton sub-steps (coupled pendula, not separable): a sub-step fails
    // after others were taken.
    fail_and_retry_with(
        || DynPendula { n: 64, c: 0.3, k: 0.5 },
        yoshida4,
        1e3,
        |e| matches!(e, Error::NewtonDidNotConverge { .. } | Error::StepRejected { .. }),
    );
}

#[test]
fn run_time_sized_compositions_take_the_const_size_steps() {
    let fpu = || DynFpu { n: 16, beta: 1.0 };
    for (name, method) in [("Yoshida 4", Composition::YOSHIDA4), ("Kahan–Li 8", Composition::KAHAN_LI8)] {
        let (d, f, r) = path_difference::<_, _, 16>(fpu, method, 0.05, 100);
        println!("FPU-β N = 16, {name} (fused explicit sub-steps): difference {d:.2e}, Newton iterations {f} / {r}");
        assert!(d <= 1e-14 && f == 0 && r == 0, "{name}: {d:e} {f} {r}");
    }
    // Not separable: Newton sub-steps, one by one, as the const-size
    // integrator's reverse mode takes them.
    let pendula = || DynPendula { n: 16, c: 0.3, k: 0.5 };
    let (d, f, r) = path_difference::<_, _, 16>(pendula, Composition::YOSHIDA4, 0.05, 100);
    println!("coupled pendula N = 16, Yoshida 4 (Newton sub-steps): difference {d:.2e}, Newton iterations {f} / {r}");
    assert!(d <= 1e-14 && f == r && r >= 300, "{d:e} {f} {r}");
}

/// The FPU-β chain through `#[lagrangian]` over slices: the macro writes
/// its gradient code, so Newton steps take the forward-over-reverse path.
struct GenFpu {
    n: usize,
    beta: f64,
}

#[lagrangian]
impl GenFpu {
    fn dimension(&self) -> usize {
        self.n
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        let n = q.len();
        let mut kinetic = 0.0;
        for i in 0..n {
            kinetic += 0.5 * v[i] * v[i];
        }
        let mut d = q[0];
        let mut potential = 0.5 * d * d + 0.25 * self.beta * d.powi(4);
        for i in 0..n - 1 {
            d = q[i + 1] - q[i];
            potential += 0.5 * d * d + 0.25 * self.beta * d.powi(4);
        }
        d = q[n - 1];
        potential += 0.5 * d * d + 0.25 * self.beta * d.powi(4);
        kinetic - potential
    }
}

/// The coupled pendula through `#[lagrangian]` over slices (not separable,
/// banded; a time-dependent drive of the first pendulum so that the step
/// energy's `∂L/∂t` term is exercised).
struct GenPendula {
    n: usize,
    c: f64,
    k: f64,
    drive: f64,
}

#[lagrangian]
impl GenPendula {
    fn dimension(&self) -> usize {
        self.n
    }

    fn lagrangian(&self, t: f64, q: &[f64], v: &[f64]) -> f64 {
        let n = q.len();
        let mut l = self.drive * (0.7 * t).sin() * q[0];
        for i in 0..n {
            l += 0.5 * v[i] * v[i] + q[i].cos();
        }
        for i in 1..n {
            l += self.c * v[i - 1] * v[i] * (q[i - 1] - q[i]).cos() - 0.5 * self.k * (q[i] - q[i - 1]).powi(2);
        }
        l
    }
}

/// A run-time-sized system with its generated gradient code hidden: the
/// integrator records its `L` on the tape (the path before the generic
/// gradient code), with the same structure constants. Also used by
/// `lane_duals`.
pub(crate) struct TapeOnly<S>(pub(crate) S);

impl<S: DynLagrangian> DynLagrangian for TapeOnly<S> {
    const AUTONOMOUS: bool = S::AUTONOMOUS;
    const SEPARABILITY: Separability = S::SEPARABILITY;
    const COUPLING: Coupling = S::COUPLING;

    fn dimension(&self) -> usize {
        self.0.dimension()
    }

    fn lagrangian<D: Scalar>(&self, t: D, q: &[D], v: &[D]) -> D {
        self.0.lagrangian(t, q, v)
    }
}

/// Largest difference of `q` and `p` (relative to the largest `|q|`, `|p|`)
/// and of the discrete energy (relative) between the forward-over-reverse
/// and the tape Newton path over `steps` steps, the largest difference of
/// Newton iterations in one step, and the iterations of the new path.
fn fwdrev_against_tape<S, M>(system: impl Fn() -> S, method: M, h: f64, steps: usize) -> (f64, f64, u64, u64)
where
    S: DynLagrangian,
    M: DiscreteLagrangian,
{
    assert!(S::HAS_GRADIENT_QV);
    let n = system().dimension();
    let q0 = chain_mode(n, 2, 0.3);
    let v0: Vec<f64> = (0..n).map(|i| 0.1 * (i as f64).sin()).collect();
    let mut new = DynIntegrator::new(system(), method, h).start(0.0, &q0, &v0).unwrap();
    let mut tape = DynIntegrator::new(TapeOnly(system()), method, h).start(0.0, &q0, &v0).unwrap();
    let (mut worst, mut energy, mut iterations) = (0.0f64, 0.0f64, 0u64);
    for _ in 0..steps {
        let before = (new.stats().newton_iterations, tape.stats().newton_iterations);
        new.step().unwrap();
        tape.step().unwrap();
        let (a, b) = (new.state(), tape.state());
        let scale = b.q.iter().chain(&b.p).fold(1e-300f64, |m, x| m.max(x.abs()));
        for i in 0..n {
            worst = worst.max((a.q[i] - b.q[i]).abs() / scale).max((a.p[i] - b.p[i]).abs() / scale);
        }
        let (e_new, e_tape) = (new.discrete_energy(), tape.discrete_energy());
        energy = energy.max((e_new - e_tape).abs() / e_tape.abs());
        let steps_new = new.stats().newton_iterations - before.0;
        let steps_tape = tape.stats().newton_iterations - before.1;
        iterations = iterations.max(steps_new.abs_diff(steps_tape));
    }
    (worst, energy, iterations, new.stats().newton_iterations)
}

#[test]
fn newton_steps_from_the_gradient_code_agree_with_the_tape() {
    let fpu = |n| move || GenFpu { n, beta: 1.0 };
    let pendula = |n| move || GenPendula { n, c: 0.3, k: 0.5, drive: 0.2 };
    let euler = lagrangian::AlphaBeta::new(0.3).unwrap();
    let cases = [
        ("FPU-β N = 16, midpoint", fwdrev_against_tape(fpu(16), Midpoint, 0.05, 200)),
        ("FPU-β N = 300, midpoint", fwdrev_against_tape(fpu(300), Midpoint, 0.05, 100)),
        ("FPU-β N = 16, α-β (α = 0.3)", fwdrev_against_tape(fpu(16), euler, 0.05, 200)),
        ("coupled pendula N = 16, midpoint", fwdrev_against_tape(pendula(16), Midpoint, 0.05, 200)),
        ("coupled pendula N = 16, trapezoid (Newton)", fwdrev_against_tape(pendula(16), Trapezoid, 0.05, 200)),
        ("coupled pendula N = 16, α-β (α = 0.3)", fwdrev_against_tape(pendula(16), euler, 0.05, 200)),
        ("coupled pendula N = 300, midpoint", fwdrev_against_tape(pendula(300), Midpoint, 0.05, 100)),
        ("coupled pendula N = 300, trapezoid (Newton)", fwdrev_against_tape(pendula(300), Trapezoid, 0.05, 100)),
    ];
    for (name, (d, e, i, total)) in &cases {
        println!("{name}: state {d:.1e}, discrete energy {e:.1e}, Newton iterations ±{i} per step ({total} in all)");
    }
    for (name, (d, e, i, total)) in cases {
        // The two paths sum the same derivatives in different orders: each
        // step differs by round-off, and the chains are chaotic enough to
        // amplify it modestly over 100–200 steps.
        assert!(d <= 1e-13, "{name}: state differs by {d:e}");
        assert!(e <= 1e-13, "{name}: discrete energy differs by {e:e}");
        assert!(i <= 1 && total >= 100, "{name}: iterations ±{i}, {total}");
    }
}

#[test]
fn the_energy_error_of_a_chain_of_1000_does_not_drift_on_the_gradient_code_path() {
    let n = 1000;
    let mut sim = DynIntegrator::new(GenFpu { n, beta: 1.0 }, Midpoint, 0.05)
        .start(0.0, &chain_mode(n, 100, 0.3), &vec![0.0; n])
        .unwrap();
    let e0 = sim.energy().unwrap();
    let mut errors = Vec::new();
    for _ in 0..200 {
        sim.run(20, |_| {}).unwrap();
        errors.push((sim.energy().unwrap() - e0).abs() / e0);
    }
    let (first, second) = errors.split_at(errors.len() / 2);
    let max = |s: &[f64]| s.iter().copied().fold(0.0f64, f64::max);
    let (a, b) = (max(first), max(second));
    let iterations = sim.stats().newton_iterations as f64 / 4000.0;
    println!(
        "FPU-β N = 1000 (generated gradient), midpoint: largest energy error {a:.3e} (t ≤ 100), {b:.3e} (t > 100), {iterations:.2} Newton iterations per step"
    );
    assert!(a > 0.0 && a < 2e-3 && b < 1.5 * a, "{a:e} {b:e}");
}

#[test]
fn a_chain_of_100_000_masses_on_the_gradient_code_path_runs_in_a_2_mib_thread() {
    std::thread::Builder::new()
        .stack_size(2 << 20)
        .spawn(|| {
            let n = 100_000;
            let q0 = chain_mode(n, n / 10, 0.3);
            let mut sim =
                DynIntegrator::new(GenFpu { n, beta: 1.0 }, Midpoint, 0.05).start(0.0, &q0, &vec![0.0; n]).unwrap();
            let e0 = sim.energy().unwrap();
            sim.run(3, |_| {}).unwrap();
            let state = sim.state();
            assert!(state.q.iter().chain(&state.p).all(|x| x.is_finite()));
            let error = (sim.energy().unwrap() - e0).abs() / e0;
            println!("FPU-β N = 100 000 (generated gradient), 3 midpoint steps: relative energy error {error:.2e}");
            assert!(error < 2e-3 && error > 1e-12, "{error:e}");
        })
        .unwrap()
        .join()
        .expect("no stack overflow, no panic");
}
