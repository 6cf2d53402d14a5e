//! Forces and Rayleigh dissipation on run-time-sized systems (the discrete
//! Lagrange–d'Alembert principle of docs/theory.md §6 on the reverse-mode
//! driver): the same states as at a compile-time size, the damped and the
//! driven chain against their analytic solutions with the order fitted,
//! momentum under internal forces, and a force that is not finite.

use lagrangian::prelude::*;
use lagrangian::{DynLagrangian, ForceCoupling, Pattern, Scalar};

/// Eight masses between walls, damped (`R = ½γ Σ v_i² + ½κ Σ (v_{i+1} −
/// v_i)²`) and driven (`Q_0 = a cos Ωt`, a cubic friction `−μ v_i³` on every
/// mass), with their size known at compile time.
#[derive(Clone)]
struct Forced;

const GAMMA: f64 = 0.05;
const KAPPA: f64 = 0.02;
const MU: f64 = 0.1;
const DRIVE: f64 = 0.3;
const OMEGA: f64 = 1.3;

#[lagrangian]
impl Forced {
    fn lagrangian(&self, q: [f64; 8], v: [f64; 8]) -> f64 {
        let mut kinetic = 0.0;
        for i in 0..8 {
            kinetic += 0.5 * v[i] * v[i];
        }
        let mut potential = 0.5 * (q[0] * q[0] + q[7] * q[7]);
        for i in 0..7 {
            let d = q[i + 1] - q[i];
            potential += 0.5 * d * d;
        }
        kinetic - potential
    }

    fn dissipation(&self, _q: [f64; 8], v: [f64; 8]) -> f64 {
        let mut r = 0.0;
        for i in 0..8 {
            r += 0.5 * GAMMA * v[i] * v[i];
        }
        for i in 0..7 {
            let d = v[i + 1] - v[i];
            r += 0.5 * KAPPA * d * d;
        }
        r
    }

    fn force(&self, t: f64, _q: [f64; 8], v: [f64; 8]) -> [f64; 8] {
        let mut f = [0.0; 8];
        for i in 0..8 {
            f[i] = -MU * v[i] * v[i] * v[i];
        }
        f[0] += DRIVE * (OMEGA * t).cos();
        f
    }
}

/// The same chain with its size known at run time, written by hand over
/// slices (force and dissipation banded: bandwidth 0 and 1).
#[derive(Clone, Debug)]
struct ForcedDyn {
    n: usize,
}

fn chain_lagrangian<D: Scalar>(q: &[D], v: &[D], walls: bool) -> D {
    let n = q.len();
    let mut l = D::from(0.0);
    for i in 0..n {
        l += v[i] * v[i] * 0.5;
    }
    if walls {
        l -= (q[0] * q[0] + q[n - 1] * q[n - 1]) * 0.5;
    }
    for i in 0..n - 1 {
        let d = q[i + 1] - q[i];
        l -= d * d * 0.5;
    }
    l
}

impl DynLagrangian for ForcedDyn {
    const AUTONOMOUS: bool = true;
    const FORCE_COUPLING: ForceCoupling = ForceCoupling { q: Pattern::Diagonal, v: Pattern::Banded { bandwidth: 1 } };
    const HAS_DISSIPATION: bool = true;
    const HAS_FORCE: bool = true;

    fn dimension(&self) -> usize {
        self.n
    }

    fn lagrangian<D: Scalar>(&self, _t: D, q: &[D], v: &[D]) -> D {
        chain_lagrangian(q, v, true)
    }

    fn dissipation<D: Scalar>(&self, _q: &[D], v: &[D]) -> D {
        let mut r = D::from(0.0);
        for x in v {
            r += *x * *x * (0.5 * GAMMA);
        }
        for i in 0..v.len() - 1 {
            let d = v[i + 1] - v[i];
            r += d * d * (0.5 * KAPPA);
        }
        r
    }

    fn force<D: Scalar>(&self, t: D, _q: &[D], v: &[D], f: &mut [D]) {
        for (f, v) in f.iter_mut().zip(v) {
            *f = -(*v * *v * *v * MU);
        }
        f[0] += (t * OMEGA).cos() * DRIVE;
    }
}

const H: f64 = 0.02;

/// The third normal mode's shape `sin(πi/3)`, `i = 1 … 8` (`ω₃ = 1`).
fn shape() -> [f64; 8] {
    core::array::from_fn(|i| (std::f64::consts::PI * (i + 1) as f64 / 3.0).sin())
}

fn schemes() -> [(&'static str, Scheme); 4] {
    [
        ("midpoint", Scheme::MIDPOINT),
        ("trapezoid", Scheme::TRAPEZOID),
        ("alpha-beta", Scheme::OnePoint(OnePoint::AlphaBeta(lagrangian::AlphaBeta::new(0.3).unwrap()))),
        ("yoshida 4", Scheme::composition(lagrangian::Composition::YOSHIDA4, OnePoint::Trapezoid)),
    ]
}

#[test]
fn a_forced_run_time_chain_steps_as_the_compile_time_one() {
    let q0 = shape();
    let v0: [f64; 8] = core::array::from_fn(|i| 0.1 * (i as f64 - 3.5));
    let dynamic = DynProblem::new(ForcedDyn { n: 8 }, 0.0, q0.to_vec(), v0.to_vec());
    let compiled = Problem::new(Forced, 0.0, q0, v0);
    for (name, scheme) in schemes() {
        let mut a = dynamic.stepper(&scheme, H).unwrap();
        let mut b = compiled.stepper(&scheme, H).unwrap();
        a.run(300).unwrap();
        b.run(300, |_| {}).unwrap();
        let (sa, sb) = (a.state(), b.state());
        assert_eq!(sa.t, sb.t, "{name}");
        let mut largest = 0.0f64;
        for i in 0..8 {
            largest = largest.max((sa.q[i] - sb.q[i]).abs()).max((sa.p[i] - sb.p[i]).abs());
        }
        // Round-off of 300 steps: the two sizes sum the same terms in
        // different orders.
        assert!(largest < 1e-12, "{name}: {largest:e}");
        // The motion is damped and driven: far from the start.
        assert!((sa.q[0] - q0[0]).abs() > 1e-2, "{name}");
    }
}
