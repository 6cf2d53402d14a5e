//! Galerkin rules on run-time-sized systems (`Scheme::Galerkin` through
//! [`Problem`] with vectors).
//!
//! - The same system at a compile-time and a run-time size takes the same
//!   steps to round-off, s = 1, 2, 4: an FPU-β chain (banded, separable) and
//!   coupled pendula (banded, non-separable, mass matrix depending on `q`).
//! - Degrees 1, 3, 5 … 8 take the compile-time steps too (coupled pendula).
//! - The fitted order is `2s` (s = 2, 3, 4) on the coupled pendula against
//!   a compile-time-size Galerkin s = 8 run at h = 0.02.
//! - A free FPU-β chain up to t = 2000 (s = 2, h = 0.1 and 0.05): the energy
//!   error stays bounded at O(h⁴), the total momentum is conserved to
//!   round-off.

use lagrangian::galerkin::StageIteration;
use lagrangian::prelude::*;
use lagrangian::{Coupling, Pattern, Separability};

/// An FPU-β chain of run-time length, unit masses and springs; with
/// `walls`, its ends are tied to fixed walls, else they are free.
#[derive(Clone)]
struct DynFpu {
    n: usize,
    beta: f64,
    walls: bool,
}

impl DynLagrangian for DynFpu {
    const AUTONOMOUS: bool = true;
    const SEPARABILITY: Separability = Separability::ConstantMass;
    const COUPLING: Coupling =
        Coupling { q_q: Pattern::Banded { bandwidth: 1 }, q_v: Pattern::Diagonal, v_v: Pattern::Diagonal };

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
        let mut potential = if self.walls { spring(q[0]) + spring(q[n - 1]) } else { D::zero() };
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
            l += v[a] * v[b] * (q[a] - q[b]).cos() * 0.3 - (q[b] - q[a]).powi(2) * 0.25;
        }
        l
    }
}

/// A run-time-sized system as a const-size one, with the same body and the
/// same proven structure.
#[derive(Clone)]
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

/// Initial data of `n` coordinates: a smooth, not symmetric displacement
/// and velocity.
fn initial(n: usize) -> (Vec<f64>, Vec<f64>) {
    let q = (0..n).map(|i| 0.4 * (0.7 * i as f64 + 0.3).sin()).collect();
    let v = (0..n).map(|i| 0.2 * (1.3 * i as f64).cos()).collect();
    (q, v)
}

/// The largest difference of `q` and `p` between `steps` steps of degree
/// `S` at the compile-time size (Newton, so that both solve the same
/// equations) and at the run-time size, relative to the largest `|q|`,
/// `|p|`.
fn path_difference<Sys: DynLagrangian + Clone, const N: usize, const S: usize>(
    system: Sys,
    h: f64,
    steps: usize,
) -> f64 {
    let (q0, v0) = initial(N);
    let rule = Galerkin::<S, S>::gauss().with_iteration(StageIteration::Newton);
    let mut fixed = GalerkinIntegrator::new(Fixed::<Sys, N>(system.clone()), rule, h)
        .start(0.0, core::array::from_fn(|i| q0[i]), core::array::from_fn(|i| v0[i]))
        .unwrap();
    let mut dynamic = Problem::new(system, 0.0, q0, v0).stepper(&Scheme::galerkin(S), h).unwrap();
    let mut worst: f64 = 0.0;
    for _ in 0..steps {
        fixed.step().unwrap();
        dynamic.step().unwrap();
        let (a, b) = (fixed.state(), dynamic.state());
        assert_eq!(a.t, b.t);
        let scale = a.q.iter().chain(a.p.iter()).fold(1e-300f64, |m, x| m.max(x.abs()));
        for i in 0..N {
            worst = worst.max((a.q[i] - b.q[i]).abs() / scale).max((a.p[i] - b.p[i]).abs() / scale);
        }
    }
    worst
}

#[test]
fn compile_time_and_run_time_sizes_take_the_same_galerkin_steps() {
    let fpu = DynFpu { n: 8, beta: 1.0, walls: true };
    let pendula = DynPendula { n: 8 };
    let runs = [
        ("FPU-β, s = 1", path_difference::<_, 8, 1>(fpu.clone(), 0.05, 400)),
        ("FPU-β, s = 2", path_difference::<_, 8, 2>(fpu.clone(), 0.1, 400)),
        ("FPU-β, s = 4", path_difference::<_, 8, 4>(fpu, 0.2, 200)),
        ("coupled pendula, s = 1", path_difference::<_, 8, 1>(pendula.clone(), 0.05, 400)),
        ("coupled pendula, s = 2", path_difference::<_, 8, 2>(pendula.clone(), 0.1, 400)),
        ("coupled pendula, s = 4", path_difference::<_, 8, 4>(pendula, 0.2, 200)),
    ];
    for (name, d) in runs {
        println!("{name}: largest relative difference {d:.2e}");
        // The same equations, derivatives rounded differently (the tape
        // against the chain rule on duals): measured 1e-15 to 3e-15.
        assert!(d <= 1e-13, "{name}: {d:e}");
    }
}

/// `q` at `t_end` of the coupled pendula at a run-time size, from the
/// initial data of [`initial`], under `scheme` with step `h`.
fn run_time_end(scheme: &Scheme, n: usize, h: f64, t_end: f64) -> Vec<f64> {
    let (q0, v0) = initial(n);
    let problem = Problem::new(DynPendula { n }, 0.0, q0, v0);
    let mut sim = problem.stepper(scheme, h).unwrap();
    sim.run_until(t_end).unwrap();
    sim.state().q.clone()
}

/// The reference of the order fits: the pendula at a compile-time size,
/// Galerkin s = 8 (order 16) at `h = 0.02`.
fn reference<const N: usize>(t_end: f64) -> [f64; N] {
    let (q0, v0) = initial(N);
    let mut sim = GalerkinIntegrator::new(Fixed::<_, N>(DynPendula { n: N }), Galerkin::<8, 8>::gauss(), 0.02)
        .start(0.0, core::array::from_fn(|i| q0[i]), core::array::from_fn(|i| v0[i]))
        .unwrap();
    sim.run_until(t_end, |_| {}).unwrap();
    sim.state().q
}

/// The least-squares slope of `log e` against `log h`.
fn fitted_order(points: &[(f64, f64)]) -> f64 {
    let xs: Vec<f64> = points.iter().map(|(h, _)| h.ln()).collect();
    let ys: Vec<f64> = points.iter().map(|(_, e)| e.ln()).collect();
    let (mx, my) = (xs.iter().sum::<f64>() / xs.len() as f64, ys.iter().sum::<f64>() / ys.len() as f64);
    let sxy: f64 = xs.iter().zip(&ys).map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = xs.iter().map(|x| (x - mx) * (x - mx)).sum();
    sxy / sxx
}

#[test]
fn the_fitted_order_at_a_run_time_size_is_2s() {
    const N: usize = 4;
    let t_end = 4.0;
    let reference = reference::<N>(t_end);
    for (s, steps) in [(2, [0.2, 0.1, 0.05]), (3, [0.4, 0.2, 0.1]), (4, [0.5, 0.25, 0.125])] {
        let points: Vec<(f64, f64)> = steps
            .iter()
            .map(|&h| {
                let q = run_time_end(&Scheme::galerkin(s), N, h, t_end);
                (h, q.iter().zip(&reference).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max))
            })
            .collect();
        let order = fitted_order(&points);
        let errors: Vec<String> = points.iter().map(|(h, e)| format!("{e:.2e} at h = {h}")).collect();
        println!("Galerkin s = {s} at a run-time size: errors {}, fitted order {order:.2}", errors.join(", "));
        assert!((order - 2.0 * s as f64).abs() <= 0.3, "s = {s}: order {order}");
    }
}

#[test]
fn degrees_up_to_eight_take_the_compile_time_steps() {
    // s = 2 and 4 are in `compile_time_and_run_time_sizes_take_the_same_galerkin_steps`.
    let pendula = DynPendula { n: 4 };
    let runs = [
        (1, path_difference::<_, 4, 1>(pendula.clone(), 0.05, 200)),
        (3, path_difference::<_, 4, 3>(pendula.clone(), 0.2, 100)),
        (5, path_difference::<_, 4, 5>(pendula.clone(), 0.3, 100)),
        (6, path_difference::<_, 4, 6>(pendula.clone(), 0.3, 100)),
        (7, path_difference::<_, 4, 7>(pendula.clone(), 0.4, 100)),
        (8, path_difference::<_, 4, 8>(pendula, 0.4, 100)),
    ];
    for (s, d) in runs {
        println!("coupled pendula N = 4, s = {s}: largest relative difference {d:.2e}");
        assert!(d <= 1e-13, "s = {s}: {d:e}");
    }
}

/// The largest relative energy error of the free FPU-β chain of `n`
/// masses under Galerkin s = 2 with step `h` up to `t_end`, sampled every
/// `sample` steps, over the first and the last tenth of the run; and the
/// largest drift of the total momentum, with the largest `|p_0|`.
fn free_chain(n: usize, h: f64, t_end: f64, sample: usize) -> (f64, f64, f64, f64) {
    let (q0, v0) = initial(n);
    let problem = Problem::new(DynFpu { n, beta: 1.0, walls: false }, 0.0, q0, v0);
    let mut sim = problem.stepper(&Scheme::galerkin(2), h).unwrap();
    let momentum = |p: &[f64]| p.iter().sum::<f64>();
    let (e0, p0) = (sim.energy().unwrap(), momentum(sim.momenta()));
    let scale = sim.momenta().iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let (mut first, mut last, mut drift) = (0.0f64, 0.0f64, 0.0f64);
    let steps = (t_end / h).round() as usize;
    for k in 1..=steps {
        sim.step().unwrap();
        drift = drift.max((momentum(sim.momenta()) - p0).abs());
        if k % sample == 0 {
            let e = (sim.energy().unwrap() - e0).abs() / e0.abs();
            if k <= steps / 10 {
                first = first.max(e);
            }
            if k > steps - steps / 10 {
                last = last.max(e);
            }
        }
    }
    (first, last, drift, scale)
}

#[test]
fn a_free_chain_keeps_its_energy_bounded_and_its_momentum() {
    let n = 32;
    let (first, last, drift, scale) = free_chain(n, 0.1, 2000.0, 50);
    let (half_first, half_last, half_drift, _) = free_chain(n, 0.05, 2000.0, 100);
    println!(
        "free FPU-β chain, N = {n}, Galerkin s = 2, t = 2000: energy error {first:.2e} (first tenth), {last:.2e} (last tenth) at h = 0.1 (20 000 steps), {half_first:.2e}, {half_last:.2e} at h = 0.05; momentum drift {drift:.2e}, {half_drift:.2e} (largest |p| {scale:.2})"
    );
    // Bounded at O(h⁴): small, and a sixteenth at half the step over the
    // same time (an error that grew with the number of steps, as round-off
    // or inexact Newton solves do, would not shrink so); momentum at round-off.
    let (worst, half_worst) = (first.max(last), half_first.max(half_last));
    assert!(worst < 1e-6, "energy {first:e} → {last:e}");
    assert!(half_worst < worst / 8.0, "energy at h/2: {half_worst:e} against {worst:e}");
    assert!(drift.max(half_drift) <= 1e-13 * scale.max(1.0), "momentum drift {drift:e}, {half_drift:e}");
}
