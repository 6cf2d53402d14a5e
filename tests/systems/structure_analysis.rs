//! The structure `#[lagrangian]` proves (`SEPARABILITY`, `COUPLING`,
//! `FORCE_COUPLING`) checked against derivatives evaluated at random points,
//! on the examples' systems, two chains written with `for` loops over
//! neighbours (also over slices, as run-time-sized systems), systems with a position-dependent mass matrix, and bodies
//! whose structure the analysis must not overstate.
//!
//! For every system, at several random points:
//! - every entry of the Hessian of `L` in `(q, v)` outside the claimed
//!   pattern is zero (second derivatives from hyper-dual numbers: exact up to
//!   round-off, so a non-zero entry shows up at its full size);
//! - every entry of the Jacobian of the generalised force outside the
//!   claimed pattern is zero;
//! - a constant mass matrix: the `q–v` block is zero, the `v–v` block is the
//!   same at two different points, and `L` has no term linear in `v`;
//! - a quadratic kinetic energy: `L(t, q, s v) − L(t, q, 0) = s² (L(t, q, v)
//!   − L(t, q, 0))`, and the `v–v` block does not change with `v` or `t`.
//!
//! Where the right answer is known by hand it is asserted too, so that an
//! analysis answering "general" everywhere would fail.
//!
//! `cargo test --test systems structure_analysis:: -- --nocapture` prints what the
//! analysis found for each system.
#![allow(missing_docs)]

use lagrangian::num_dual::{Dual64, HyperDual64};
use lagrangian::prelude::*;
use lagrangian::system::generalized_force;
use lagrangian::{Coupling, ForceCoupling, Pattern, Separability};

// ------------------------------------------------------ the examples' systems

pub struct Pendulum {
    pub m: f64,
    pub l: f64,
    pub g: f64,
}

#[lagrangian]
impl Pendulum {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * self.m * self.l * self.l * v[0] * v[0] + self.m * self.g * self.l * q[0].cos()
    }
}

pub struct DoublePendulum {
    pub m1: f64,
    pub m2: f64,
    pub l1: f64,
    pub l2: f64,
    pub g: f64,
}

#[lagrangian]
impl DoublePendulum {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let kinetic = 0.5 * (self.m1 + self.m2) * self.l1 * self.l1 * v[0] * v[0]
            + 0.5 * self.m2 * self.l2 * self.l2 * v[1] * v[1]
            + self.m2 * self.l1 * self.l2 * v[0] * v[1] * (q[0] - q[1]).cos();
        let potential = -(self.m1 + self.m2) * self.g * self.l1 * q[0].cos() - self.m2 * self.g * self.l2 * q[1].cos();
        kinetic - potential
    }
}

pub struct KeplerPolar {
    pub mu: f64,
}

#[lagrangian]
impl KeplerPolar {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let r = q[0];
        0.5 * (v[0] * v[0] + r * r * v[1] * v[1]) + self.mu / r
    }
}

pub struct KeplerCartesian {
    pub mu: f64,
    pub c: f64,
    pub s: f64,
}

#[lagrangian]
impl KeplerCartesian {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let r = (q[0] * q[0] + q[1] * q[1]).sqrt();
        0.5 * (v[0] * v[0] + v[1] * v[1]) + self.mu / r
    }

    fn dissipation(&self, _q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * self.c * (v[0] * v[0] + v[1] * v[1])
    }

    fn force(&self, q: [f64; 2], _v: [f64; 2]) -> [f64; 2] {
        let r = (q[0] * q[0] + q[1] * q[1]).sqrt();
        [-self.s * q[1] / r, self.s * q[0] / r]
    }
}

pub struct Oscillator {
    pub m: f64,
    pub k: f64,
}

#[lagrangian]
impl Oscillator {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * self.m * v[0] * v[0] - 0.5 * self.k * q[0] * q[0]
    }
}

pub struct Damped {
    pub m: f64,
    pub k: f64,
    pub c: f64,
}

#[lagrangian]
impl Damped {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * self.m * v[0] * v[0] - 0.5 * self.k * q[0] * q[0]
    }

    fn dissipation(&self, _q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * self.c * v[0] * v[0]
    }
}

pub struct Rlc {
    pub l: f64,
    pub c: f64,
    pub r: f64,
    pub e0: f64,
    pub omega: f64,
}

#[lagrangian]
impl Rlc {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * self.l * v[0] * v[0] - 0.5 * q[0] * q[0] / self.c
    }

    fn dissipation(&self, _q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * self.r * v[0] * v[0]
    }

    fn force(&self, t: f64, _q: [f64; 1], _v: [f64; 1]) -> [f64; 1] {
        [self.e0 * (self.omega * t).cos()]
    }
}

pub struct Sensor {
    pub m: f64,
    pub k: f64,
    pub g: f64,
    pub l0: f64,
    pub a: f64,
    pub r: f64,
    pub e: f64,
}

#[lagrangian]
impl Sensor {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let x = q[0];
        let l1 = self.l0 / (1.0 + x / self.a);
        0.5 * self.m * v[0] * v[0] + 0.5 * l1 * v[1] * v[1] - 0.5 * self.k * x * x + self.m * self.g * x
    }

    fn dissipation(&self, _q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * self.r * v[1] * v[1]
    }

    fn force(&self, _q: [f64; 2], _v: [f64; 2]) -> [f64; 2] {
        [0.0, self.e]
    }
}

pub struct PerturbedPendulum;

#[lagrangian]
impl PerturbedPendulum {
    fn lagrangian(&self, t: f64, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] - (1.0 - q[0].cos()) * (1.0 - 0.1 * (0.02 * t).sin())
    }
}

pub struct SlowOscillator {
    pub eps: f64,
}

#[lagrangian]
impl SlowOscillator {
    fn lagrangian(&self, t: f64, q: [f64; 1], v: [f64; 1]) -> f64 {
        let w = 1.0 + 0.5 * (self.eps * t).sin();
        0.5 * v[0] * v[0] - 0.5 * w * w * q[0] * q[0]
    }
}

// ------------------------------------------------------------------ chains

/// The FPU-β chain with fixed ends, as a `for` loop over neighbours.
pub struct Fpu<const N: usize> {
    pub beta: f64,
}

#[lagrangian]
impl<const N: usize> Fpu<N> {
    fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
        let mut kinetic = 0.0;
        for i in 0..N {
            kinetic += 0.5 * v[i] * v[i];
        }
        // `d` is declared outside the loop and reassigned in it.
        let mut d = q[0];
        let mut potential = 0.5 * d * d + 0.25 * self.beta * d.powi(4);
        for i in 0..N - 1 {
            d = q[i + 1] - q[i];
            potential += 0.5 * d * d + 0.25 * self.beta * d.powi(4);
        }
        d = q[N - 1];
        potential += 0.5 * d * d + 0.25 * self.beta * d.powi(4);
        kinetic - potential
    }
}

/// Pendula hanging from a line, each coupled to the next through its
/// kinetic energy (`vᵢ vᵢ₊₁ cos(qᵢ − qᵢ₊₁)`) and a torsion spring: not
/// separable, banded, a mass matrix depending on `q`.
pub struct CoupledPendula<const N: usize> {
    pub c: f64,
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

/// A damped chain: the force of each link on its neighbours, built element
/// by element in a loop.
pub struct DampedChain<const N: usize> {
    pub k: f64,
    pub c: f64,
}

#[lagrangian]
impl<const N: usize> DampedChain<N> {
    fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
        let mut l = 0.0;
        for i in 0..N {
            l += 0.5 * v[i] * v[i] - 0.5 * self.k * q[i] * q[i];
        }
        l
    }

    fn force(&self, q: [f64; N], v: [f64; N]) -> [f64; N] {
        let mut f = [0.0; N];
        for i in 1..N - 1 {
            f[i] = (q[i + 1] - 2.0 * q[i] + q[i - 1]).tanh();
            f[i] -= self.c * v[i] * (1.0 + q[i] * q[i]);
        }
        f
    }
}

// ------------------------------------------- position-dependent mass matrix

pub struct SphericalPendulum {
    pub g: f64,
}

#[lagrangian]
impl SphericalPendulum {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let s = q[0].sin();
        0.5 * (v[0] * v[0] + s * s * v[1] * v[1]) + self.g * q[0].cos()
    }
}

/// Three links, every mass-matrix entry depending on `q`: dense.
pub struct ThreeLinks;

#[lagrangian]
impl ThreeLinks {
    fn lagrangian(&self, q: [f64; 3], v: [f64; 3]) -> f64 {
        let mut kinetic = 0.0;
        for i in 0..3 {
            for j in 0..3 {
                let m = (3 - if i > j { i } else { j }) as f64;
                kinetic += 0.5 * m * v[i] * v[j] * (q[i] - q[j]).cos();
            }
        }
        let mut potential = 0.0;
        for i in 0..3 {
            potential -= (3 - i) as f64 * 9.81 * q[i].cos();
        }
        kinetic - potential
    }
}

// ------------------------------------- bodies the analysis must not overstate

/// A charged particle in a magnetic field: a term linear in `v`.
pub struct Magnetic {
    pub b: f64,
}

#[lagrangian]
impl Magnetic {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) + 0.5 * self.b * (q[0] * v[1] - q[1] * v[0])
    }
}

/// A relativistic particle: not a polynomial in `v`.
pub struct Relativistic;

#[lagrangian]
impl Relativistic {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        -(1.0 - v[0] * v[0] - v[1] * v[1]).sqrt() - 0.5 * q[0] * q[0]
    }
}

/// A mass that changes with time.
pub struct TimeMass;

#[lagrangian]
impl TimeMass {
    fn lagrangian(&self, t: f64, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * (1.5 + t.sin()) * v[0] * v[0] - q[0] * q[0]
    }
}

/// A chain whose neighbour is carried across iterations (`prev` is
/// `q[i − 1]`), and whose last link couples to the first: a reading of
/// `prev` as `q[i]` would claim a diagonal `q–q` block, and a band would
/// miss the corner.
pub struct Carried<const N: usize>;

#[lagrangian]
impl<const N: usize> Carried<N> {
    fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
        let mut l = 0.0;
        let mut prev = q[N - 1];
        for i in 0..N {
            l += 0.5 * v[i] * v[i] - (q[i] - prev).powi(2) * 0.5;
            prev = q[i];
        }
        l
    }
}

/// Summarised arrays: a loose, sound answer.
pub struct Arrays<const N: usize>;

#[lagrangian]
impl<const N: usize> Arrays<N> {
    fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
        let mut x = [0.0; N];
        for i in 0..N {
            x[i] = q[i].sin();
        }
        let mut l = 0.0;
        for i in 0..N - 1 {
            l += 0.5 * v[i] * v[i] + x[i] * x[i + 1];
        }
        l + 0.5 * v[N - 1] * v[N - 1]
    }
}

// ------------------------------------------------- run-time-sized chains

/// The FPU-β chain over slices (`DynLagrangian`), bounded by `q.len()`.
pub struct FpuSlices {
    pub beta: f64,
    pub n: usize,
}

#[lagrangian]
impl FpuSlices {
    fn dimension(&self) -> usize {
        self.n
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        let mut l = 0.0;
        for i in 0..v.len() {
            l += 0.5 * v[i] * v[i];
        }
        for i in 0..q.len() - 1 {
            let d = q[i + 1] - q[i];
            l -= 0.5 * d * d + 0.25 * self.beta * d.powi(4);
        }
        l - 0.5 * q[0] * q[0] - 0.5 * q[q.len() - 1] * q[q.len() - 1]
    }
}

/// The coupled pendula over slices, loops bounded by a field.
pub struct PendulaSlices {
    pub n: usize,
    pub c: f64,
}

#[lagrangian]
impl PendulaSlices {
    fn dimension(&self) -> usize {
        self.n
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        let mut l = 0.0;
        for i in 0..self.n {
            l += 0.5 * v[i] * v[i] + q[i].cos();
        }
        for i in 1..self.n {
            l += self.c * v[i - 1] * v[i] * (q[i - 1] - q[i]).cos();
        }
        l
    }
}

/// A run-time-sized system seen at dimension `N`, its bandwidths normalised
/// against `N` as the runtime does, so that [`check`] applies to it.
struct AtDimension<S, const N: usize>(S);

const fn normalised(p: Pattern, n: usize) -> Pattern {
    match p {
        Pattern::Banded { bandwidth } => Pattern::banded(n, bandwidth),
        other => other,
    }
}

impl<S: DynLagrangian, const N: usize> Lagrangian<N> for AtDimension<S, N> {
    const AUTONOMOUS: bool = S::AUTONOMOUS;
    const CYCLIC: [bool; N] = [false; N];
    const SEPARABILITY: Separability = S::SEPARABILITY;
    const COUPLING: Coupling = Coupling {
        q_q: normalised(S::COUPLING.q_q, N),
        q_v: normalised(S::COUPLING.q_v, N),
        v_v: normalised(S::COUPLING.v_v, N),
    };
    const FORCE_COUPLING: ForceCoupling = ForceCoupling::NONE;
    fn lagrangian<T: Scalar>(&self, t: T, q: [T; N], v: [T; N]) -> T {
        assert_eq!(self.0.dimension(), N);
        DynLagrangian::lagrangian(&self.0, t, &q, &v)
    }
}

// ------------------------------------------------------------------ checks

/// A small deterministic generator (SplitMix64), for reproducible points.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64
    }

    fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next()
    }

    /// `t ∈ [0, 10]`, `q ∈ [0.3, 1.3]` (inside every system's domain: Kepler's
    /// radius, the sensor's gap), `v ∈ [−0.5, 0.5]` (the relativistic
    /// particle's `|v| < 1`).
    fn point<const N: usize>(&mut self) -> (f64, [f64; N], [f64; N]) {
        let t = self.uniform(0.0, 10.0);
        let q = std::array::from_fn(|_| self.uniform(0.3, 1.3));
        let v = std::array::from_fn(|_| self.uniform(-0.5, 0.5));
        (t, q, v)
    }
}

/// The Hessian of `L` in `(q, v)` at a point, `2N × 2N`, variables ordered
/// `q₀ … q_{N−1}, v₀ … v_{N−1}`; one hyper-dual evaluation per entry.
fn hessian<S: Lagrangian<N>, const N: usize>(s: &S, t: f64, q: [f64; N], v: [f64; N]) -> Vec<Vec<f64>> {
    let x: Vec<f64> = q.iter().chain(&v).copied().collect();
    let mut h = vec![vec![0.0; 2 * N]; 2 * N];
    for a in 0..2 * N {
        for b in a..2 * N {
            let seeded: Vec<HyperDual64> = (0..2 * N)
                .map(|k| HyperDual64::new(x[k], f64::from(u8::from(k == a)), f64::from(u8::from(k == b)), 0.0))
                .collect();
            let qd: [HyperDual64; N] = std::array::from_fn(|i| seeded[i]);
            let vd: [HyperDual64; N] = std::array::from_fn(|i| seeded[N + i]);
            let value = s.lagrangian(HyperDual64::from_re(t), qd, vd);
            h[a][b] = value.eps1eps2;
            h[b][a] = value.eps1eps2;
        }
    }
    h
}

/// `∂L/∂v` at a point.
fn velocity_gradient<S: Lagrangian<N>, const N: usize>(s: &S, t: f64, q: [f64; N], v: [f64; N]) -> [f64; N] {
    std::array::from_fn(|j| {
        let vd: [Dual64; N] = std::array::from_fn(|i| Dual64::new(v[i], f64::from(u8::from(i == j))));
        s.lagrangian(Dual64::from_re(t), q.map(Dual64::from_re), vd).eps
    })
}

/// The Jacobians `∂F/∂q` and `∂F/∂v` of `F = Q − ∂R/∂v` at a point.
fn force_jacobians<S: Lagrangian<N>, const N: usize>(
    s: &S,
    t: f64,
    q: [f64; N],
    v: [f64; N],
) -> ([[f64; N]; N], [[f64; N]; N]) {
    let mut jq = [[0.0; N]; N];
    let mut jv = [[0.0; N]; N];
    for j in 0..N {
        let seed =
            |x: &[f64; N]| -> [Dual64; N] { std::array::from_fn(|i| Dual64::new(x[i], f64::from(u8::from(i == j)))) };
        let fq = generalized_force(s, Dual64::from_re(t), seed(&q), v.map(Dual64::from_re));
        let fv = generalized_force(s, Dual64::from_re(t), q.map(Dual64::from_re), seed(&v));
        for i in 0..N {
            jq[i][j] = fq[i].eps;
            jv[i][j] = fv[i].eps;
        }
    }
    (jq, jv)
}

fn max_abs(m: &[Vec<f64>]) -> f64 {
    m.iter().flatten().fold(0.0f64, |a, x| a.max(x.abs()))
}

/// Zero up to round-off relative to the matrix's scale.
fn negligible(x: f64, scale: f64) -> bool {
    x.abs() <= 1e-13 * (1.0 + scale)
}

fn describe(p: Pattern) -> String {
    match p {
        Pattern::Diagonal => "diagonal".to_owned(),
        Pattern::Banded { bandwidth } => format!("banded {bandwidth}"),
        Pattern::General => "general".to_owned(),
    }
}

/// Prints the claims of `S` and checks them at four random points.
pub(crate) fn check<S: Lagrangian<N>, const N: usize>(name: &str, s: &S, seed: u64) {
    let (sep, coupling, force) = (S::SEPARABILITY, S::COUPLING, S::FORCE_COUPLING);
    println!(
        "{name:<22} N = {N:<3} {:<17} q–q {:<10} q–v {:<10} v–v {:<10} force: ∂F/∂q {:<10} ∂F/∂v {}",
        format!("{sep:?}"),
        describe(coupling.q_q),
        describe(coupling.q_v),
        describe(coupling.v_v),
        describe(force.q),
        describe(force.v),
    );
    let mut rng = Rng(seed);
    let mut first_mass: Option<Vec<Vec<f64>>> = None;
    for _ in 0..4 {
        let (t, q, v) = rng.point::<N>();
        let h = hessian(s, t, q, v);
        let scale = max_abs(&h);
        for i in 0..N {
            for j in 0..N {
                for (block, pattern, a, b) in
                    [("q–q", coupling.q_q, i, j), ("q–v", coupling.q_v, i, N + j), ("v–v", coupling.v_v, N + i, N + j)]
                {
                    assert!(
                        pattern.may_couple(i, j) || negligible(h[a][b], scale),
                        "{name}: {block} entry ({i}, {j}) = {:e} outside the claimed pattern {pattern:?}",
                        h[a][b]
                    );
                }
            }
        }
        let (jq, jv) = force_jacobians(s, t, q, v);
        let fscale = jq.iter().chain(&jv).flatten().fold(0.0f64, |a, x| a.max(x.abs()));
        for i in 0..N {
            for j in 0..N {
                assert!(
                    force.q.may_couple(i, j) || negligible(jq[i][j], fscale),
                    "{name}: ∂F{i}/∂q{j} = {:e}",
                    jq[i][j]
                );
                assert!(
                    force.v.may_couple(i, j) || negligible(jv[i][j], fscale),
                    "{name}: ∂F{i}/∂v{j} = {:e}",
                    jv[i][j]
                );
            }
        }
        let mass: Vec<Vec<f64>> = (0..N).map(|i| h[N + i][N..].to_vec()).collect();
        if sep.is_quadratic_kinetic() {
            // Homogeneous of degree 2 in `v`.
            let at = |v: [f64; N]| s.lagrangian::<f64>(t, q, v);
            let (l0, l1) = (at([0.0; N]), at(v));
            for scale_v in [-1.3, 0.5, 2.0] {
                let ls = at(v.map(|x| scale_v * x));
                let expected = scale_v * scale_v * (l1 - l0);
                assert!(
                    ((ls - l0) - expected).abs() <= 1e-12 * (1.0 + l0.abs() + l1.abs()),
                    "{name}: L(t, q, {scale_v} v) − L(t, q, 0) = {} ≠ {expected}",
                    ls - l0
                );
            }
            // The mass matrix does not change with `v` or `t`.
            let (t2, _, v2) = rng.point::<N>();
            let h2 = hessian(s, t2, q, v2);
            for i in 0..N {
                for j in 0..N {
                    assert!(
                        (h2[N + i][N + j] - mass[i][j]).abs() <= 1e-12 * (1.0 + scale),
                        "{name}: M[{i}][{j}] changes with v or t"
                    );
                }
            }
        }
        if sep.has_constant_mass() {
            for i in 0..N {
                for j in 0..N {
                    assert!(negligible(h[i][N + j], scale), "{name}: q–v entry ({i}, {j}) = {:e}", h[i][N + j]);
                }
            }
            let p0 = velocity_gradient(s, t, q, [0.0; N]);
            assert!(p0.iter().all(|p| negligible(*p, scale)), "{name}: ∂L/∂v at v = 0 is {p0:?}");
            match &first_mass {
                None => first_mass = Some(mass),
                Some(m0) => {
                    for i in 0..N {
                        for j in 0..N {
                            assert!(
                                (m0[i][j] - mass[i][j]).abs() <= 1e-12 * (1.0 + scale),
                                "{name}: M[{i}][{j}] is {} at one point, {} at another",
                                m0[i][j],
                                mass[i][j]
                            );
                        }
                    }
                }
            }
        }
    }
}

/// Checks `AUTONOMOUS` and `CYCLIC` at four random points: an autonomous
/// `L` takes the same value at two times, and `∂L/∂qᵢ` of a coordinate
/// claimed cyclic is zero (the claims may be conservative, never wrong).
pub(crate) fn check_autonomy_and_cyclic<S: Lagrangian<N>, const N: usize>(name: &str, s: &S, seed: u64) {
    let mut rng = Rng(seed);
    for _ in 0..4 {
        let (t, q, v) = rng.point::<N>();
        let (t2, _, _) = rng.point::<N>();
        if S::AUTONOMOUS {
            let (a, b) = (s.lagrangian::<f64>(t, q, v), s.lagrangian::<f64>(t2, q, v));
            assert_eq!(a.to_bits(), b.to_bits(), "{name}: claimed autonomous, L(t = {t}) = {a}, L(t = {t2}) = {b}");
        }
        for i in (0..N).filter(|&i| S::CYCLIC[i]) {
            let qd: [Dual64; N] = std::array::from_fn(|j| Dual64::new(q[j], f64::from(u8::from(i == j))));
            let derivative = s.lagrangian(Dual64::from_re(t), qd, v.map(Dual64::from_re)).eps;
            assert_eq!(derivative, 0.0, "{name}: q[{i}] claimed cyclic, ∂L/∂q[{i}] = {derivative:e}");
        }
    }
}

fn coupling(q_q: Pattern, q_v: Pattern, v_v: Pattern) -> Coupling {
    Coupling { q_q, q_v, v_v }
}

const D: Pattern = Pattern::Diagonal;
const G: Pattern = Pattern::General;
const B1: Pattern = Pattern::Banded { bandwidth: 1 };

fn claims<S: Lagrangian<N>, const N: usize>(_: &S) -> (Separability, Coupling, ForceCoupling) {
    (S::SEPARABILITY, S::COUPLING, S::FORCE_COUPLING)
}

#[test]
fn the_examples_systems() {
    use Separability::{ConstantMass, QuadraticKinetic};
    let none = ForceCoupling::NONE;

    let s = Pendulum { m: 1.3, l: 0.7, g: 9.81 };
    check("pendulum", &s, 1);
    assert_eq!(claims(&s), (ConstantMass, coupling(D, D, D), none));

    let s = DoublePendulum { m1: 1.0, m2: 1.5, l1: 1.0, l2: 0.8, g: 9.81 };
    check("double pendulum", &s, 2);
    // `N = 2`: a bandwidth of 1 is the whole matrix.
    assert_eq!(claims(&s), (QuadraticKinetic, coupling(G, G, G), none));

    let s = KeplerPolar { mu: 1.0 };
    check("Kepler (polar)", &s, 3);
    assert_eq!(claims(&s), (QuadraticKinetic, coupling(D, G, D), none));

    let s = KeplerCartesian { mu: 1.0, c: 0.1, s: 0.05 };
    check("Kepler (Cartesian)", &s, 4);
    assert_eq!(claims(&s), (ConstantMass, coupling(G, D, D), ForceCoupling { q: G, v: D }));

    let s = Oscillator { m: 2.0, k: 8.0 };
    check("harmonic oscillator", &s, 5);
    assert_eq!(claims(&s), (ConstantMass, coupling(D, D, D), none));

    let s = Damped { m: 1.0, k: 4.0, c: 0.3 };
    check("damped oscillator", &s, 6);
    assert_eq!(claims(&s), (ConstantMass, coupling(D, D, D), none));

    let s = Rlc { l: 0.5, c: 0.2, r: 0.1, e0: 1.0, omega: 3.0 };
    check("RLC circuit", &s, 7);
    assert_eq!(claims(&s), (ConstantMass, coupling(D, D, D), none));

    let s = Sensor { m: 0.1, k: 50.0, g: 9.81, l0: 0.02, a: 0.01, r: 5.0, e: 1.0 };
    check("sensor", &s, 8);
    assert_eq!(claims(&s), (QuadraticKinetic, coupling(D, G, D), none));

    check("perturbed pendulum", &PerturbedPendulum, 9);
    assert_eq!(claims(&PerturbedPendulum), (ConstantMass, coupling(D, D, D), none));

    let s = SlowOscillator { eps: 0.01 };
    check("slow oscillator", &s, 10);
    assert_eq!(claims(&s), (ConstantMass, coupling(D, D, D), none));
}

#[test]
fn chains_written_with_loops_over_neighbours() {
    let s = Fpu::<8> { beta: 1.0 };
    check("FPU-β chain", &s, 11);
    assert_eq!(claims(&s), (Separability::ConstantMass, coupling(B1, D, D), ForceCoupling::NONE));
    let s = Fpu::<16> { beta: 0.3 };
    check("FPU-β chain", &s, 12);
    assert_eq!(claims(&s).1, coupling(B1, D, D));
    // Too short for a band.
    assert_eq!(claims(&Fpu::<2> { beta: 1.0 }).1, coupling(G, D, D));
    assert_eq!(claims(&Fpu::<1> { beta: 1.0 }).1, coupling(D, D, D));

    let s = CoupledPendula::<10> { c: 0.3, k: 0.5 };
    check("coupled pendula", &s, 13);
    assert_eq!(claims(&s), (Separability::QuadraticKinetic, coupling(B1, B1, B1), ForceCoupling::NONE));

    let s = DampedChain::<9> { k: 1.0, c: 0.2 };
    check("damped chain", &s, 14);
    assert_eq!(claims(&s), (Separability::ConstantMass, coupling(D, D, D), ForceCoupling { q: B1, v: D }));
}

#[test]
fn run_time_sized_chains() {
    // The same claims as the `[f64; N]` chains, at two dimensions each.
    let s = AtDimension::<_, 7>(FpuSlices { beta: 1.0, n: 7 });
    check("FPU-β chain (slices)", &s, 23);
    assert_eq!(claims(&s), (Separability::ConstantMass, coupling(B1, D, D), ForceCoupling::NONE));
    check("FPU-β chain (slices)", &AtDimension::<_, 12>(FpuSlices { beta: 0.4, n: 12 }), 24);
    let s = AtDimension::<_, 6>(PendulaSlices { n: 6, c: 0.3 });
    check("pendula (slices)", &s, 25);
    assert_eq!(claims(&s), (Separability::QuadraticKinetic, coupling(B1, B1, B1), ForceCoupling::NONE));
    check("pendula (slices)", &AtDimension::<_, 11>(PendulaSlices { n: 11, c: 0.2 }), 26);
}

#[test]
fn position_dependent_mass_matrices() {
    let s = SphericalPendulum { g: 9.81 };
    check("spherical pendulum", &s, 15);
    assert_eq!(claims(&s).0, Separability::QuadraticKinetic);
    assert_eq!(claims(&s).1, coupling(D, G, D));
    check("three links", &ThreeLinks, 16);
    // Two loop variables: general.
    assert_eq!(claims(&ThreeLinks).1, coupling(G, G, G));
    assert_eq!(claims(&ThreeLinks).0, Separability::QuadraticKinetic);
}

#[test]
fn what_the_syntax_does_not_prove_is_not_claimed() {
    let s = Magnetic { b: 0.7 };
    check("magnetic field", &s, 17);
    assert_eq!(claims(&s).0, Separability::NotProven);
    check("relativistic", &Relativistic, 18);
    assert_eq!(claims(&Relativistic).0, Separability::NotProven);
    check("time-dependent mass", &TimeMass, 19);
    assert_eq!(claims(&TimeMass).0, Separability::NotProven);
    check("carried neighbour", &Carried::<6>, 20);
    assert_eq!(claims(&Carried::<6>).1.q_q, G);
    check("summarised arrays", &Arrays::<6>, 21);
    assert_eq!(claims(&Arrays::<6>).0, Separability::ConstantMass);
}

/// The checker itself catches a wrong claim: a hand implementation claiming
/// a diagonal `q–q` block for a coupled system fails it.
#[test]
#[should_panic(expected = "outside the claimed pattern")]
fn a_wrong_claim_is_caught() {
    struct Liar;
    impl Lagrangian<3> for Liar {
        const AUTONOMOUS: bool = true;
        const CYCLIC: [bool; 3] = [false; 3];
        const COUPLING: Coupling = Coupling { q_q: Pattern::Diagonal, q_v: Pattern::Diagonal, v_v: Pattern::Diagonal };
        const FORCE_COUPLING: ForceCoupling = ForceCoupling::NONE;
        fn lagrangian<T: Scalar>(&self, _: T, q: [T; 3], v: [T; 3]) -> T {
            (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]) * 0.5 - (q[0] - q[2]).cos()
        }
    }
    check("liar", &Liar, 22);
}

/// A hand implementation that says nothing gets the conservative defaults.
#[test]
fn hand_implementations_default_to_nothing_proven() {
    struct Hand;
    impl Lagrangian<2> for Hand {
        const AUTONOMOUS: bool = true;
        const CYCLIC: [bool; 2] = [false; 2];
        fn lagrangian<T: Scalar>(&self, _: T, q: [T; 2], v: [T; 2]) -> T {
            (v[0] * v[0] + v[1] * v[1]) * 0.5 - q[0] * q[1]
        }
    }
    assert_eq!(claims(&Hand), (Separability::NotProven, Coupling::GENERAL, ForceCoupling::GENERAL));
    check("hand-written", &Hand, 23);
}
