//! Galerkin rules on run-time-sized systems ([`Galerkin`] through
//! [`DynIntegrator`], and `Scheme::Galerkin` through [`DynProblem`]).
//!
//! - The same system at a compile-time and a run-time size takes the same
//!   steps to round-off, s = 1, 2, 4: an FPU-β chain (banded, separable) and
//!   coupled pendula (banded, non-separable, mass matrix depending on `q`).
//! - The fitted order is `2s` (s = 2, 3, 4) on the coupled pendula against
//!   a compile-time-size Galerkin s = 8 run at a quarter of the finest step.
//! - A free FPU-β chain over 20 000 steps (s = 2): the energy error stays
//!   bounded without drift, the total momentum is conserved to round-off.

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
    let mut dynamic = DynIntegrator::new(system, Galerkin::<S, S>::gauss(), h).start(0.0, &q0, &v0).unwrap();
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
    let problem = DynProblem::new(DynPendula { n }, 0.0, q0, v0);
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
fn every_degree_up_to_eight_halves_its_error_by_two_to_the_2s() {
    const N: usize = 4;
    let t_end = 4.0;
    let reference = reference::<N>(t_end);
    for s in 1..=8 {
        // A step where the error is well above round-off and in the asymptotic range.
        let h = [0.05, 0.2, 0.4, 0.5, 0.8, 1.0, 1.0, 1.0][s - 1];
        let error = |h: f64| {
            let q = run_time_end(&Scheme::galerkin(s), N, h, t_end);
            q.iter().zip(&reference).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max)
        };
        let (coarse, fine) = (error(h), error(h / 2.0));
        let order = (coarse / fine).log2();
        println!("Galerkin s = {s}: errors {coarse:.2e}, {fine:.2e} at h = {h}, {}: order {order:.2}", h / 2.0);
        assert!((order - 2.0 * s as f64).abs() <= 0.6 && fine > 1e-13, "s = {s}: order {order}, error {fine:e}");
    }
}

#[test]
fn a_free_chain_keeps_its_energy_bounded_and_its_momentum() {
    let n = 32;
    let (q0, v0) = initial(n);
    let problem = DynProblem::new(DynFpu { n, beta: 1.0, walls: false }, 0.0, q0, v0);
    let mut sim = problem.stepper(&Scheme::galerkin(2), 0.1).unwrap();
    let momentum = |p: &[f64]| p.iter().sum::<f64>();
    let (e0, p0) = (sim.energy().unwrap(), momentum(sim.momenta()));
    let scale = sim.momenta().iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let (mut first, mut last, mut drift) = (0.0f64, 0.0f64, 0.0f64);
    let steps = 20_000;
    for k in 1..=steps {
        sim.step().unwrap();
        drift = drift.max((momentum(sim.momenta()) - p0).abs());
        if k % 50 == 0 {
            let e = (sim.energy().unwrap() - e0).abs() / e0.abs();
            if k <= steps / 10 {
                first = first.max(e);
            }
            if k > steps - steps / 10 {
                last = last.max(e);
            }
        }
    }
    println!(
        "free FPU-β chain, N = {n}, Galerkin s = 2, h = 0.1, {steps} steps: energy error {first:.2e} (first tenth), {last:.2e} (last tenth); momentum drift {drift:.2e} (largest |p| {scale:.2})"
    );
    // Bounded: O(h⁴) for order 4 and not growing; momentum at round-off.
    assert!(first < 1e-4 && last < 2.0 * first, "energy {first:e} → {last:e}");
    assert!(drift <= 1e-12 * scale.max(1.0), "momentum drift {drift:e}");
}
