//! Verification: Newton steps and readouts of run-time-sized systems from
//! the generated gradient code on vector dual numbers (all `2b + 1` colour
//! classes of a band up to bandwidth 2 in one evaluation per point, wider
//! bands and general patterns in chunks of five classes) against the tape
//! path of the same body.
//!
//! - Bandwidths 0, 2 and 3 (pendula coupled to their second and third
//!   neighbours, one of them driven in time) and a dense, position-dependent
//!   mass matrix (pendula coupled all to all): the same trajectories to round-off
//!   and the same Newton iterations (midpoint, trapezoid with Newton, α-β).
//! - The readouts, which record no tape for these systems: the
//!   Legendre map at `start` (`p0`), the inverse Legendre map
//!   (`velocity()`), `energy()`, and the discrete energy of explicit
//!   trapezoid steps, against the tape's to round-off.
//! - A failed step on this path changes nothing, and a retry succeeds.
use super::dynamic_systems::TapeOnly;
use lagrangian::Separability;
use lagrangian::prelude::*;
// The run-time-sized driver named directly: its derivative paths (lanes
// against the tape) are compared on one rule at a time.
use lagrangian_runtime::DynIntegrator;

/// Oscillators with a position-dependent mass and no coupling: bandwidth 0
/// (one colour class, the plain `Dual64` evaluation).
struct Onsite {
    n: usize,
}

#[lagrangian]
impl Onsite {
    fn dimension(&self) -> usize {
        self.n
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        let mut l = 0.0;
        for i in 0..q.len() {
            l += 0.5 * (1.0 + 0.3 * q[i].cos()) * v[i] * v[i] + q[i].cos() - 0.05 * q[i].powi(4);
        }
        l
    }
}

/// Pendula coupled to their second neighbours through the kinetic energy
/// and a torsion spring, the first one driven in time: bandwidth 2 (five
/// classes, one `DualSVec64<5>` evaluation; the step energy's `∂L/∂t` on
/// `Dual64`).
struct Reach2 {
    n: usize,
    drive: f64,
}

#[lagrangian]
impl Reach2 {
    fn dimension(&self) -> usize {
        self.n
    }

    fn lagrangian(&self, t: f64, q: &[f64], v: &[f64]) -> f64 {
        let n = q.len();
        let mut l = self.drive * (0.7 * t).sin() * q[0];
        for i in 0..n {
            l += 0.5 * v[i] * v[i] + q[i].cos();
        }
        for i in 2..n {
            l += 0.2 * v[i - 2] * v[i] * (q[i - 2] - q[i]).cos() - 0.25 * (q[i] - q[i - 2]).powi(2);
        }
        l
    }
}

/// Pendula coupled to their first and third neighbours: bandwidth 3 (seven
/// classes, two chunks).
struct Reach3 {
    n: usize,
}

#[lagrangian]
impl Reach3 {
    fn dimension(&self) -> usize {
        self.n
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        let n = q.len();
        let mut l = 0.0;
        for i in 0..n {
            l += 0.5 * v[i] * v[i] + q[i].cos();
        }
        for i in 1..n {
            l += 0.15 * v[i - 1] * v[i] * (q[i - 1] - q[i]).cos() - 0.5 * (q[i] - q[i - 1]).powi(2);
        }
        for i in 3..n {
            l += 0.1 * v[i - 3] * v[i] - 0.2 * (q[i] - q[i - 3]).powi(2);
        }
        l
    }
}

/// Pendula coupled all to all through the kinetic energy
/// `½ Σ v_i² + ½ c (Σ_i cos q_i v_i)²`: a dense, position-dependent mass
/// matrix `I + c·u uᵀ` (`u_i = cos q_i`; `n` classes in chunks of five).
struct MeanField {
    n: usize,
}

#[lagrangian]
impl MeanField {
    fn dimension(&self) -> usize {
        self.n
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        let n = q.len();
        let mut l = 0.0;
        let mut s = 0.0;
        for i in 0..n {
            l += 0.5 * v[i] * v[i] + q[i].cos();
            s += q[i].cos() * v[i];
        }
        l + 0.15 * s * s
    }
}

/// An FPU-β chain with second-neighbour springs: separable with constant
/// mass, so the trapezoid rule takes explicit steps and their discrete
/// energy is a readout.
struct Fpu2 {
    n: usize,
}

#[lagrangian]
impl Fpu2 {
    fn dimension(&self) -> usize {
        self.n
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        let n = q.len();
        let mut l = 0.0;
        for i in 0..n {
            l += 0.5 * v[i] * v[i] - 0.5 * q[i] * q[i];
        }
        for i in 2..n {
            let d = q[i] - q[i - 2];
            l -= 0.5 * d * d + 0.25 * d.powi(4);
        }
        l
    }
}

/// A smooth start: positions of amplitude 0.4, velocities of 0.1.
fn start_data(n: usize) -> (Vec<f64>, Vec<f64>) {
    let q = (0..n).map(|i| 0.4 * (0.7 * i as f64 + 0.3).sin()).collect();
    let v = (0..n).map(|i| 0.1 * (1.3 * i as f64).cos()).collect();
    (q, v)
}

/// The largest relative difference of two vectors (against the larger's
/// largest entry).
fn relative(a: &[f64], b: &[f64]) -> f64 {
    let scale = a.iter().chain(b).fold(1e-300f64, |m, x| m.max(x.abs()));
    a.iter().zip(b).fold(0.0f64, |m, (x, y)| m.max((x - y).abs() / scale))
}

/// What [`against_tape`] measured, each relative to the tape's values.
#[derive(Debug)]
struct Agreement {
    /// `p0` from the Legendre map at `start`.
    p0: f64,
    /// `q` and `p` over all steps.
    state: f64,
    /// The discrete energy over all steps.
    discrete_energy: f64,
    /// `velocity()` and `energy()` at the end.
    velocity: f64,
    energy: f64,
    /// The largest difference of Newton iterations in one step, and the new
    /// path's total.
    iterations: u64,
    total: u64,
}

/// Steps `system` and its tape-only twin side by side.
fn against_tape<S, M>(system: impl Fn() -> S, method: M, h: f64, steps: usize) -> Agreement
where
    S: DynLagrangian,
    M: DiscreteLagrangian,
{
    assert!(S::HAS_GRADIENT_QV);
    let n = system().dimension();
    let (q0, v0) = start_data(n);
    let mut new = DynIntegrator::new(system(), method, h).start(0.0, &q0, &v0).unwrap();
    let mut tape = DynIntegrator::new(TapeOnly(system()), method, h).start(0.0, &q0, &v0).unwrap();
    let p0 = relative(&new.state().p, &tape.state().p);
    let (mut state, mut discrete_energy, mut iterations) = (0.0f64, 0.0f64, 0u64);
    for _ in 0..steps {
        let before = (new.stats().newton_iterations, tape.stats().newton_iterations);
        new.step().unwrap();
        tape.step().unwrap();
        let (a, b) = (new.state(), tape.state());
        state = state.max(relative(&a.q, &b.q)).max(relative(&a.p, &b.p));
        let (e_new, e_tape) = (new.discrete_energy(), tape.discrete_energy());
        discrete_energy = discrete_energy.max((e_new - e_tape).abs() / e_tape.abs());
        let taken = (new.stats().newton_iterations - before.0, tape.stats().newton_iterations - before.1);
        iterations = iterations.max(taken.0.abs_diff(taken.1));
    }
    let velocity = relative(&new.velocity().unwrap(), &tape.velocity().unwrap());
    let (e_new, e_tape) = (new.energy().unwrap(), tape.energy().unwrap());
    let energy = (e_new - e_tape).abs() / e_tape.abs();
    Agreement { p0, state, discrete_energy, velocity, energy, iterations, total: new.stats().newton_iterations }
}

#[test]
fn the_macro_proves_the_bands_these_tests_rely_on() {
    // Otherwise the cases below would test another lane width than named.
    assert_eq!(Onsite::COUPLING.overall().bandwidth(), Some(0));
    assert_eq!(Reach2::COUPLING.overall().bandwidth(), Some(2));
    assert_eq!(Reach3::COUPLING.overall().bandwidth(), Some(3));
    assert_eq!(Fpu2::COUPLING.overall().bandwidth(), Some(2));
    assert_eq!(Fpu2::SEPARABILITY, Separability::ConstantMass);
    assert_eq!(MeanField::COUPLING.v_v.bandwidth(), None);
    const { assert!(!Reach2::AUTONOMOUS) };
    let generated = [
        ("Onsite", Onsite::HAS_GRADIENT_QV),
        ("Reach2", Reach2::HAS_GRADIENT_QV),
        ("Reach3", Reach3::HAS_GRADIENT_QV),
        ("MeanField", MeanField::HAS_GRADIENT_QV),
        ("Fpu2", Fpu2::HAS_GRADIENT_QV),
    ];
    for (name, has) in generated {
        assert!(has, "{name} has no generated gradient code");
    }
}

#[test]
fn every_lane_width_gives_the_tapes_steps_and_readouts() {
    let euler = lagrangian::AlphaBeta::new(0.3).unwrap();
    let cases = [
        ("bandwidth 0, N = 40, midpoint", against_tape(|| Onsite { n: 40 }, Midpoint, 0.05, 100)),
        ("bandwidth 0, N = 40, trapezoid", against_tape(|| Onsite { n: 40 }, Trapezoid, 0.05, 100)),
        ("bandwidth 2, N = 40, midpoint", against_tape(|| Reach2 { n: 40, drive: 0.2 }, Midpoint, 0.05, 100)),
        ("bandwidth 2, N = 40, α-β", against_tape(|| Reach2 { n: 40, drive: 0.2 }, euler, 0.05, 100)),
        ("bandwidth 2, N = 301, trapezoid", against_tape(|| Reach2 { n: 301, drive: 0.2 }, Trapezoid, 0.05, 50)),
        ("bandwidth 3, N = 40, midpoint", against_tape(|| Reach3 { n: 40 }, Midpoint, 0.05, 100)),
        ("bandwidth 3, N = 40, trapezoid", against_tape(|| Reach3 { n: 40 }, Trapezoid, 0.05, 100)),
        ("dense, N = 12, midpoint", against_tape(|| MeanField { n: 12 }, Midpoint, 0.02, 100)),
        ("dense, N = 12, α-β", against_tape(|| MeanField { n: 12 }, euler, 0.02, 100)),
        ("explicit, bandwidth 2, N = 40, trapezoid", against_tape(|| Fpu2 { n: 40 }, Trapezoid, 0.05, 100)),
    ];
    for (name, a) in &cases {
        println!(
            "{name}: p0 {:.1e}, state {:.1e}, discrete energy {:.1e}, velocity {:.1e}, energy {:.1e}, Newton iterations ±{} per step ({} in all)",
            a.p0, a.state, a.discrete_energy, a.velocity, a.energy, a.iterations, a.total
        );
    }
    for (name, a) in cases {
        // Both paths compute the same derivatives, summed in other orders:
        // each value differs by round-off, amplified modestly over the steps.
        for (what, d) in [
            ("p0", a.p0),
            ("state", a.state),
            ("discrete energy", a.discrete_energy),
            ("velocity", a.velocity),
            ("energy", a.energy),
        ] {
            assert!(d <= 1e-13, "{name}: {what} differs by {d:e}");
        }
        let explicit = name.starts_with("explicit");
        assert!(a.iterations <= 1 && (explicit || a.total >= 100), "{name}: {a:?}");
    }
}

#[test]
fn a_failed_step_on_vector_duals_changes_nothing() {
    let (q0, v0) = start_data(40);
    let start = || DynIntegrator::new(Reach2 { n: 40, drive: 0.2 }, Midpoint, 0.05).start(0.0, &q0, &v0).unwrap();
    let mut sim = start();
    sim.run(5, |_| {}).unwrap();
    let (before, energy) = (sim.state().clone(), sim.discrete_energy());
    sim.set_step_size(1e3).unwrap();
    let failure = sim.step().map(|_| ()).unwrap_err();
    assert_eq!(sim.state(), &before, "{failure}");
    assert_eq!(sim.discrete_energy(), energy);
    sim.set_step_size(0.05).unwrap();
    sim.run(5, |_| {}).unwrap();
    let mut clean = start();
    clean.run(10, |_| {}).unwrap();
    assert_eq!((&sim.state().q, &sim.state().p), (&clean.state().q, &clean.state().p));
}
