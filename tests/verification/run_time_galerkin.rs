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
