//! Verification: large systems in reverse mode (`Derivatives::Reverse`, the
//! default above `Derivatives::FORWARD_MAX_N` coordinates): derivatives from
//! a tape, banded Newton solves when the macro proved a band, dense ones on
//! the heap otherwise.
//!
//! - Where both modes run, reverse mode gives forward mode's steps to
//!   round-off: an FPU-β chain (separable, banded; explicit and Newton
//!   steps), coupled pendula (non-separable, banded), an N-link pendulum
//!   (dense, position-dependent mass).
//! - The energy error of a chain of 1 000 oscillates without drift.
//! - A 256-link pendulum (dense) runs.
//! - What reverse mode does not do yet is refused with a typed error.
//! - A failed reverse-mode step (explicit, or a composition failing on a
//!   later sub-step) leaves every readout as it was, and the steps after it
//!   are those of a twin that never failed.
//! - Newton steps from the generated gradient code on dual numbers (forward
//!   over reverse) give the tape path's steps to round-off with the same
//!   Newton iterations (FPU-β chain, coupled pendula; N = 16 and 64).
use lagrangian::prelude::*;
use lagrangian::structure::{Coupling, Separability};
use lagrangian::{Derivatives, Error};

use super::chains::{Fpu, chain_energy_error};

/// An FPU-β chain of masses 3 (a diagonal constant mass matrix that is not
/// the identity, whose inverse is inexact).
pub struct HeavyFpu<const N: usize>;

#[lagrangian]
impl<const N: usize> HeavyFpu<N> {
    fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
        let mut kinetic = 0.0;
        for i in 0..N {
            kinetic += 1.5 * v[i] * v[i];
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

/// Pendula coupled to their neighbours through the kinetic energy and a
/// torsion spring: not separable, banded, mass matrix depending on `q`.
pub struct CoupledPendula<const N: usize> {
    /// Kinetic coupling (below ½ keeps the mass matrix positive definite).
    pub c: f64,
    /// Torsion spring.
    pub k: f64,
}

#[lagrangian]
impl<const N: usize> CoupledPendula<N> {
    fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
        let mut l = 0.0;
        for i in 0..N {
            l += 0.5 * v[i] * v[i] + q[i].cos();
        }
        for i in 1..N {
            let (a, b) = (i - 1, i);
            l += self.c * v[a] * v[b] * (q[a] - q[b]).cos() - 0.5 * self.k * (q[b] - q[a]).powi(2);
        }
        l
    }
}

/// A planar pendulum of `N` equal links (unit masses at the joints, unit
/// lengths, `g = 1`), angles from the downward vertical: the joint
/// velocities are prefix sums, so every coordinate couples with every other
/// (a dense, position-dependent mass matrix) with `O(N)` operations.
pub struct NLinkPendulum<const N: usize>;

#[lagrangian]
impl<const N: usize> NLinkPendulum<N> {
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

/// A chain with one massless coordinate: its mass matrix is singular.
pub struct MasslessEnd<const N: usize>;

#[lagrangian]
impl<const N: usize> MasslessEnd<N> {
    fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
        let mut l = 0.0;
        for i in 0..N - 1 {
            l += 0.5 * v[i] * v[i];
        }
        for i in 0..N {
            l -= 0.5 * q[i] * q[i];
        }
        l
    }
}

/// A smooth initial displacement of a chain: the lowest two normal modes.
fn chain_start<const N: usize>(amplitude: f64) -> [f64; N] {
    core::array::from_fn(|i| {
        let x = core::f64::consts::PI * (i + 1) as f64 / (N + 1) as f64;
        amplitude * (x.sin() + 0.3 * (2.0 * x).sin())
    })
}

/// Largest difference of `q` and `p` between forward and reverse mode over
/// `n` steps, relative to the largest `|q|`, `|p|`.
fn mode_difference<S: Lagrangian<N>, M: Method<f64> + Copy, const N: usize>(
    system: impl Fn() -> S,
    method: M,
    h: f64,
    q0: [f64; N],
    n: usize,
) -> (f64, u64, u64) {
    let start = |mode| Integrator::new(system(), method, h).derivatives(mode).start(0.0, q0, [0.0; N]).unwrap();
    let (mut forward, mut reverse) = (start(Derivatives::Forward), start(Derivatives::Reverse));
    let mut worst: f64 = 0.0;
    for _ in 0..n {
        forward.step().unwrap();
        reverse.step().unwrap();
        let (a, b) = (forward.state(), reverse.state());
        let scale = a.q.iter().chain(a.p.iter()).fold(1e-300f64, |m, x| m.max(x.abs()));
        for i in 0..N {
            worst = worst.max((a.q[i] - b.q[i]).abs() / scale).max((a.p[i] - b.p[i]).abs() / scale);
        }
    }
    (worst, forward.stats().newton_iterations, reverse.stats().newton_iterations)
}

#[test]
fn reverse_mode_gives_forward_modes_steps() {
    let fpu = || Fpu::<16> { beta: 1.0 };
    let (d, f, r) = mode_difference(fpu, Trapezoid, 0.05, chain_start(0.5), 1000);
    println!("FPU-β N = 16, trapezoid (explicit): {d:.2e} ({f} / {r} Newton iterations)");
    assert!(d <= 1e-13 && f == 0 && r == 0, "{d:e} {f} {r}");
    // Masses 3: forward mode multiplies by `M⁻¹`, reverse mode by the
    // reciprocals of the diagonal.
    let (d, f, r) = mode_difference(|| HeavyFpu::<16>, Trapezoid, 0.05, chain_start(0.5), 1000);
    println!("FPU-β N = 16, masses 3, trapezoid (explicit): {d:.2e} ({f} / {r} Newton iterations)");
    assert!(d <= 1e-13 && f == 0 && r == 0, "{d:e} {f} {r}");
    let (d, f, r) = mode_difference(fpu, Midpoint, 0.05, chain_start(0.5), 1000);
    println!("FPU-β N = 16, midpoint: {d:.2e} ({f} / {r} Newton iterations)");
    assert!(d <= 1e-13, "{d:e}");
    assert!(r.abs_diff(f) <= f / 20, "{f} {r}");

    let pendula = || CoupledPendula::<16> { c: 0.3, k: 0.5 };
    let (d, f, r) = mode_difference(pendula, Midpoint, 0.02, chain_start(0.8), 500);
    println!("coupled pendula N = 16, midpoint: {d:.2e} ({f} / {r} Newton iterations)");
    assert!(d <= 1e-13, "{d:e}");

    let (d, f, r) = mode_difference(|| NLinkPendulum::<8>, Midpoint, 0.01, chain_start(0.5), 300);
    println!("8-link pendulum, midpoint (dense): {d:.2e} ({f} / {r} Newton iterations)");
    assert!(d <= 1e-12, "{d:e}");
}

#[test]
fn the_energy_error_of_a_long_chain_does_not_drift() {
    // 1 000 masses, mode 100 excited with strains of 0.3, 4 000 midpoint
    // steps (t = 200, about 10 periods): the error oscillates; a drift would
    // make the second half's largest error grow beyond the first half's.
    let e = chain_energy_error::<Midpoint, 1000>(Midpoint, 0.05, 4000, 20);
    let (first, second) = e.split_at(e.len() / 2);
    let max = |s: &[f64]| s.iter().copied().fold(0.0f64, f64::max);
    let (a, b) = (max(first), max(second));
    println!("FPU-β N = 1000, midpoint: largest energy error {a:.3e} (t ≤ 100), {b:.3e} (t > 100)");
    assert!(a > 0.0 && b < 1.5 * a, "{a:e} {b:e}");
}

#[test]
fn a_256_link_pendulum_runs() {
    std::thread::spawn(|| {
        let h = 2e-3;
        let mut sim = Integrator::new(NLinkPendulum::<256>, Midpoint, h).start(0.0, chain_start(0.2), [0.0; 256]).unwrap();
        let e0 = sim.energy().unwrap();
        sim.run(50, |_| {}).unwrap();
        let e = sim.energy().unwrap();
        let iterations = sim.stats().newton_iterations as f64 / 50.0;
        println!("256-link pendulum: 50 midpoint steps, relative energy change {:.2e}, {iterations} Newton iterations per step", (e - e0).abs() / e0.abs());
        assert!((e - e0).abs() <= 1e-6 * e0.abs(), "{e0} → {e}");
        assert!(iterations <= 6.0);
    })
    .join()
    .expect("no stack overflow, no panic");
}

#[test]
fn what_reverse_mode_does_not_do_is_refused() {
    let q0 = chain_start(0.1);
    let unsupported = |r: Result<(), String>| assert!(r.as_ref().is_err_and(|e| e.contains("not supported")), "{r:?}");
    unsupported(
        Integrator::new(Fpu::<64> { beta: 1.0 }, Midpoint, 0.05)
            .energy_preserving(StepBounds::around(0.05))
            .start(0.0, q0, [0.0; 64])
            .map(|_| ())
            .map_err(|e| e.to_string()),
    );
    unsupported(
        Integrator::new(Fpu::<64> { beta: 1.0 }, Midpoint, 0.05)
            .derivatives(Derivatives::Forward)
            .start(0.0, q0, [0.0; 64])
            .map(|_| ())
            .map_err(|e| e.to_string()),
    );
    unsupported(
        GalerkinIntegrator::new(Fpu::<64> { beta: 1.0 }, Galerkin::<2, 2>::gauss(), 0.05)
            .start(0.0, q0, [0.0; 64])
            .map(|_| ())
            .map_err(|e| e.to_string()),
    );
    match Integrator::new(MasslessEnd::<64>, Midpoint, 0.05).start(0.0, q0, [0.0; 64]) {
        Err(Error::InvalidInitialData { reason }) => assert!(reason.contains("singular"), "{reason}"),
        other => panic!("{:?}", other.map(|_| ())),
    }
}

/// A system with its generated gradient code hidden: reverse mode records
/// its `L` on the tape, with the same structure constants.
struct TapeOnly<S>(S);

impl<S: Lagrangian<N>, const N: usize> Lagrangian<N> for TapeOnly<S> {
    const AUTONOMOUS: bool = S::AUTONOMOUS;
    const CYCLIC: [bool; N] = S::CYCLIC;
    const SEPARABILITY: Separability = S::SEPARABILITY;
    const COUPLING: Coupling = S::COUPLING;

    fn lagrangian<D: Scalar>(&self, t: D, q: [D; N], v: [D; N]) -> D {
        self.0.lagrangian(t, q, v)
    }
}

/// Largest difference of `q` and `p` (relative to the largest `|q|`, `|p|`)
/// between the reverse-mode Newton steps from the gradient code and from
/// the tape over `n` steps, the largest difference of Newton iterations in
/// one step, and the iterations of the new path.
fn gradient_code_difference<S: Lagrangian<N>, M: Method<f64> + Copy, const N: usize>(
    system: impl Fn() -> S,
    method: M,
    h: f64,
    q0: [f64; N],
    n: usize,
) -> (f64, u64, u64) {
    assert!(S::HAS_GRADIENT_QV);
    let mut new =
        Integrator::new(system(), method, h).derivatives(Derivatives::Reverse).start(0.0, q0, [0.0; N]).unwrap();
    let mut tape = Integrator::new(TapeOnly(system()), method, h)
        .derivatives(Derivatives::Reverse)
        .start(0.0, q0, [0.0; N])
        .unwrap();
    let (mut worst, mut iterations) = (0.0f64, 0u64);
    for _ in 0..n {
        let before = (new.stats().newton_iterations, tape.stats().newton_iterations);
        new.step().unwrap();
        tape.step().unwrap();
        let (a, b) = (new.state(), tape.state());
        let scale = b.q.iter().chain(b.p.iter()).fold(1e-300f64, |m, x| m.max(x.abs()));
        for i in 0..N {
            worst = worst.max((a.q[i] - b.q[i]).abs() / scale).max((a.p[i] - b.p[i]).abs() / scale);
        }
        let steps = (new.stats().newton_iterations - before.0, tape.stats().newton_iterations - before.1);
        iterations = iterations.max(steps.0.abs_diff(steps.1));
    }
    (worst, iterations, new.stats().newton_iterations)
}

#[test]
fn newton_steps_from_the_gradient_code_give_the_tapes_steps() {
    let fpu16 = || Fpu::<16> { beta: 1.0 };
    let fpu64 = || Fpu::<64> { beta: 1.0 };
    let pendula16 = || CoupledPendula::<16> { c: 0.3, k: 0.5 };
    let pendula64 = || CoupledPendula::<64> { c: 0.3, k: 0.5 };
    let euler = lagrangian::AlphaBeta::new(0.3).unwrap();
    let cases = [
        ("FPU-β N = 16, midpoint", gradient_code_difference(fpu16, Midpoint, 0.05, chain_start(0.5), 200)),
        ("FPU-β N = 64, midpoint", gradient_code_difference(fpu64, Midpoint, 0.05, chain_start(0.5), 200)),
        ("FPU-β N = 16, α-β", gradient_code_difference(fpu16, euler, 0.05, chain_start(0.5), 200)),
        (
            "coupled pendula N = 16, midpoint",
            gradient_code_difference(pendula16, Midpoint, 0.02, chain_start(0.8), 200),
        ),
        (
            "coupled pendula N = 16, trapezoid",
            gradient_code_difference(pendula16, Trapezoid, 0.02, chain_start(0.8), 200),
        ),
        (
            "coupled pendula N = 64, midpoint",
            gradient_code_difference(pendula64, Midpoint, 0.02, chain_start(0.8), 200),
        ),
        ("coupled pendula N = 64, α-β", gradient_code_difference(pendula64, euler, 0.02, chain_start(0.8), 200)),
    ];
    for (name, (d, i, total)) in &cases {
        println!("{name}: {d:.1e}, Newton iterations ±{i} per step ({total} in all)");
    }
    for (name, (d, i, total)) in cases {
        assert!(d <= 1e-13, "{name}: {d:e}");
        assert!(i <= 1 && total >= 200, "{name}: iterations ±{i}, {total}");
    }
}

/// Oscillators coupled by quartic springs, the first held off `q_0 = 1` by
/// the potential `−0.01 √(1 − q_0)`, whose force is NaN beyond: a step that
/// carries `q_0` over fails (in a composition, on the sub-step that does).
pub struct Wall<const N: usize>;

#[lagrangian]
impl<const N: usize> Wall<N> {
    fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
        let mut l = 0.01 * (1.0 - q[0]).sqrt();
        for i in 0..N {
            l += 0.5 * v[i] * v[i] - 0.5 * q[i] * q[i];
        }
        for i in 0..N - 1 {
            let d = q[i + 1] - q[i];
            l -= 0.25 * d * d * d * d;
        }
        l
    }
}

/// [`Wall`] declared discontinuous: its compositions take their sub-steps
/// one by one (and can fail after some of them were taken).
pub struct WallSubstepped<const N: usize>;

#[lagrangian(discontinuous)]
impl<const N: usize> WallSubstepped<N> {
    fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
        let mut l = 0.01 * (1.0 - q[0]).sqrt();
        for i in 0..N {
            l += 0.5 * v[i] * v[i] - 0.5 * q[i] * q[i];
        }
        for i in 0..N - 1 {
            let d = q[i + 1] - q[i];
            l -= 0.25 * d * d * d * d;
        }
        l
    }
}

/// Every readout of an integrator as bits, to compare two exactly.
fn readouts<S: Lagrangian<N>, M: lagrangian::F64Readouts, const N: usize>(it: &Integrator<S, M, N>) -> Vec<u64> {
    let s = it.state();
    let mut bits = vec![s.step, s.t.to_bits(), it.discrete_energy().to_bits(), it.stats().steps];
    bits.extend(s.q.iter().chain(&s.p).map(|x| x.to_bits()));
    bits.extend(it.velocity().unwrap().iter().map(|x| x.to_bits()));
    bits.push(it.last_step_size().map_or(0, f64::to_bits));
    bits
}

/// A failed reverse-mode step (explicit, a fused composition, and a
/// sub-stepped one failing on its second sub-step, after the first was
/// taken) leaves every readout as it was, and the steps after it are those
/// of a twin that never failed: the node, the last two segments, the Kahan
/// carries and the cached force are all put back.
#[test]
fn a_failed_reverse_step_changes_nothing() {
    fn check<S: Lagrangian<8>, M: lagrangian::F64Readouts + Copy>(system: fn() -> S, method: M, v: f64, name: &str) {
        let q0: [f64; 8] = core::array::from_fn(|i| if i == 0 { 0.8 } else { 0.1 * i as f64 });
        let mut v0 = [0.0; 8];
        v0[0] = v;
        let start =
            || Integrator::new(system(), method, 0.01).derivatives(Derivatives::Reverse).start(0.0, q0, v0).unwrap();
        // The smallest of these steps that fails (the larger ones fail too).
        for h_bad in [0.2, 0.3, 0.4, 0.5, 0.6, 0.8, 1.0] {
            let (mut it, mut twin) = (start(), start());
            it.run(5, |_| {}).unwrap();
            twin.run(5, |_| {}).unwrap();
            let before = readouts(&it);
            it.set_step_size(h_bad).unwrap();
            let Err(failure) = it.step() else { continue };
            assert!(matches!(failure, Error::NonFinite { .. }), "{name}: {failure}");
            assert_eq!(it.stats().failed_steps, 1, "{name}");
            assert_eq!(readouts(&it), before, "{name}");
            it.set_step_size(0.01).unwrap();
            it.run(5, |_| {}).unwrap();
            twin.run(5, |_| {}).unwrap();
            assert_eq!(readouts(&it), readouts(&twin), "{name}");
            println!("{name}: the step of {h_bad} failed and changed nothing");
            return;
        }
        panic!("{name}: no step failed");
    }
    // Trapezoid: q_0 near 0.85 moving up, over the wall.
    check(|| Wall::<8>, Trapezoid, 1.0, "trapezoid");
    // Yoshida 4, q_0 near 0.75 moving down: the first sub-step takes q_0
    // down, the second (weight −1.70) up past 1.
    check(|| Wall::<8>, Composition::YOSHIDA4, -1.0, "yoshida4 (fused)");
    check(|| WallSubstepped::<8>, Composition::YOSHIDA4, -1.0, "yoshida4 (sub-stepped)");
}

/// `N` free unit masses in the NaN band of `10⁻³ ln((q − 2)(q − 3))`: `L`
/// is NaN for `2 < q < 3`, where its derivatives stay finite, and the band's
/// terms are summed in a loop only the value of `L` reads (which the
/// explicit step's finiteness check sums reassociated).
pub struct BandedMasses<const N: usize>;

#[lagrangian]
impl<const N: usize> BandedMasses<N> {
    fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
        let mut l = 0.0;
        for i in 0..N {
            l += 0.5 * v[i] * v[i] + 1e-3 * ((q[i] - 2.0) * (q[i] - 3.0)).ln();
        }
        l
    }
}

/// The explicit reverse-mode step (Störmer–Verlet from the generated
/// gradient code, `N = 40`) that would carry the first mass into the NaN
/// band of [`BandedMasses`] is refused with the typed error, the state as
/// it was, and no published state lies in the band.
#[test]
fn an_explicit_reverse_step_into_a_nan_band_summed_in_a_loop_is_refused() {
    let (mut q0, mut v0) = ([0.0; 40], [0.0; 40]);
    (q0[0], v0[0]) = (1.5, 1.0);
    let mut it = Integrator::new(BandedMasses::<40>, Trapezoid, 0.01).start(0.0, q0, v0).unwrap();
    let failure = loop {
        let before = *it.state();
        match it.step() {
            Ok(state) => assert!(!(2.0..=3.0).contains(&state.q[0]), "stepped into the band: {}", state.q[0]),
            Err(failure) => {
                assert_eq!(*it.state(), before, "a failed step changed the state");
                break failure;
            }
        }
        assert!(it.state().step < 10_000, "never stopped (q = {})", it.state().q[0]);
    };
    println!("refused at q = {} after {} steps: {failure}", it.state().q[0], it.state().step);
    assert!(matches!(failure, Error::NonFinite { quantity: "lagrangian", .. }), "{failure}");
    // Explicit steps: no Newton iteration.
    assert_eq!(it.stats().newton_iterations, 0);
}
