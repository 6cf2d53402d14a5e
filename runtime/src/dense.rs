//! Dense output: the solution between two nodes.
//!
//! An integrator publishes the state only at its nodes `t_k`. Dense output
//! interpolates one step `[t_k, t_{k+1}]` from what the step leaves behind:
//!
//! | interpolant | data | interpolation error (local, `τ` inside the step) |
//! | --- | --- | --- |
//! | [`Hermite::cubic`] | `q, v` at both nodes | `O(h⁴)`: `h⁴ |q⁗| / 384` at mid-step |
//! | [`Hermite::quintic`] | `q, v, a` at both nodes (`a` from the equations of motion, [`acceleration`]) | `O(h⁶)`: `h⁶ |q⁽⁶⁾| / 46080` at mid-step |
//! | [`GalerkinPolynomial`] | the `s + 1` nodes of a Galerkin step's polynomial | `O(h^{s+1})` (the continuous Galerkin curve; its end nodes are accurate to `O(h^{2s})`) |
//!
//! The value between nodes also carries the error of the nodes themselves
//! (global order `p` of the method): dense output of a method of order `p`
//! is accurate to `O(h^{min(p, r)})` over a run, with `r` the interpolant's
//! order above. So the cubic suits the second-order one-point rules, and a
//! Galerkin method of order `2s ≥ 6` needs the quintic to keep its accuracy
//! between nodes (`tests/verification/dense_output.rs` fits these orders). The velocity
//! at a node is the one whose momentum is the integrator's `p_k` (the inverse
//! Legendre transform), so both interpolants are `C¹` across nodes; the
//! Galerkin polynomial is only continuous (its slope at the nodes is not the
//! node velocity).

use nalgebra::SMatrix;

use crate::hyperdual::{HyperDualArray, Pair, Timed};
use crate::system::{Lagrangian, generalized_force};

/// The state at one node as dense output and solutions need it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Node<const N: usize> {
    /// `t_k`.
    pub t: f64,
    /// `q_k`.
    pub q: [f64; N],
    /// `p_k`, the integrator's momentum.
    pub p: [f64; N],
    /// `v_k` with `∂L/∂v(t_k, q_k, v_k) = p_k`.
    pub v: [f64; N],
}

impl<const N: usize> Node<N> {
    /// The node as a [`NodeView`].
    pub fn view(&self) -> NodeView<'_> {
        NodeView { t: self.t, q: &self.q, p: &self.p, v: &self.v }
    }
}

/// A node seen through slices, whatever the system's size (compile-time or
/// run-time): what [`Plan::observe_every`](crate::Plan::observe_every)'s
/// observer is given.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NodeView<'a> {
    /// `t_k`.
    pub t: f64,
    /// `q_k`.
    pub q: &'a [f64],
    /// `p_k`, the integrator's momentum.
    pub p: &'a [f64],
    /// `v_k` with `∂L/∂v(t_k, q_k, v_k) = p_k`.
    pub v: &'a [f64],
}

/// The interpolant of one step `[t0, t1]`.
pub trait DenseStep<const N: usize> {
    /// The start of the step.
    fn t0(&self) -> f64;
    /// The end of the step.
    fn t1(&self) -> f64;
    /// Position and velocity at `t` (meant for `t` in `[t0, t1]`; outside it
    /// the polynomial is extrapolated).
    fn eval(&self, t: f64) -> ([f64; N], [f64; N]);
}

/// Hermite interpolation of one step from the positions, velocities and
/// (for the quintic) accelerations at both nodes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hermite<const N: usize> {
    t0: f64,
    h: f64,
    q: [[f64; N]; 2],
    v: [[f64; N]; 2],
    /// `None`: the cubic.
    a: Option<[[f64; N]; 2]>,
}

/// Cubic Hermite basis in powers `1, s, s², s³` for `q0, h v0, q1, h v1`.
const CUBIC: [[f64; 6]; 4] = [
    [1.0, 0.0, -3.0, 2.0, 0.0, 0.0],
    [0.0, 1.0, -2.0, 1.0, 0.0, 0.0],
    [0.0, 0.0, 3.0, -2.0, 0.0, 0.0],
    [0.0, 0.0, -1.0, 1.0, 0.0, 0.0],
];

/// Quintic Hermite basis in powers `1 … s⁵` for `q0, h v0, h² a0, q1, h v1, h² a1`.
const QUINTIC: [[f64; 6]; 6] = [
    [1.0, 0.0, 0.0, -10.0, 15.0, -6.0],
    [0.0, 1.0, 0.0, -6.0, 8.0, -3.0],
    [0.0, 0.0, 0.5, -1.5, 1.5, -0.5],
    [0.0, 0.0, 0.0, 10.0, -15.0, 6.0],
    [0.0, 0.0, 0.0, -4.0, 7.0, -3.0],
    [0.0, 0.0, 0.0, 0.5, -1.0, 0.5],
];

/// Value and derivative in `s` of the polynomial with coefficients `c`.
#[inline]
fn poly(c: &[f64; 6], s: f64) -> (f64, f64) {
    let (mut value, mut slope) = (0.0, 0.0);
    for k in (0..6).rev() {
        slope = slope * s + value;
        value = value * s + c[k];
    }
    (value, slope)
}

impl<const N: usize> Hermite<N> {
    /// The cubic through `(q, v)` at `start` and `end`.
    pub fn cubic(start: &Node<N>, end: &Node<N>) -> Self {
        Self { t0: start.t, h: end.t - start.t, q: [start.q, end.q], v: [start.v, end.v], a: None }
    }

    /// The quintic through `(q, v, a)` at `start` (acceleration `a0`) and `end` (`a1`).
    pub fn quintic(start: &Node<N>, a0: [f64; N], end: &Node<N>, a1: [f64; N]) -> Self {
        Self { a: Some([a0, a1]), ..Self::cubic(start, end) }
    }
}

impl<const N: usize> DenseStep<N> for Hermite<N> {
    fn t0(&self) -> f64 {
        self.t0
    }

    fn t1(&self) -> f64 {
        self.t0 + self.h
    }

    fn eval(&self, t: f64) -> ([f64; N], [f64; N]) {
        let mut q = [0.0; N];
        let mut v = [0.0; N];
        let a = self.a.as_ref().map(|a| [&a[0][..], &a[1][..]]);
        hermite_into(self.t0, self.h, [&self.q[0], &self.q[1]], [&self.v[0], &self.v[1]], a, t, &mut q, &mut v);
        (q, v)
    }
}

/// The Hermite interpolant of one step at `t`, added into `q_out` and
/// `v_out` (zero on entry): the cubic through `q, v` at both nodes, or with
/// the accelerations `a` the quintic. One function for both sizes, so that
/// [`Hermite`] and [`HermiteRows`] give the same bits from the same nodes.
#[allow(clippy::too_many_arguments)]
#[inline]
fn hermite_into(
    t0: f64,
    h: f64,
    q: [&[f64]; 2],
    v: [&[f64]; 2],
    a: Option<[&[f64]; 2]>,
    t: f64,
    q_out: &mut [f64],
    v_out: &mut [f64],
) {
    let s = (t - t0) / h;
    let mut add = |c: &[f64; 6], x: &[f64], scale: f64| {
        let (b, db) = poly(c, s);
        for ((q, v), x) in q_out.iter_mut().zip(v_out.iter_mut()).zip(x) {
            *q += b * scale * x;
            *v += db * scale * x / h;
        }
    };
    match a {
        None => {
            add(&CUBIC[0], q[0], 1.0);
            add(&CUBIC[1], v[0], h);
            add(&CUBIC[2], q[1], 1.0);
            add(&CUBIC[3], v[1], h);
        }
        Some(a) => {
            add(&QUINTIC[0], q[0], 1.0);
            add(&QUINTIC[1], v[0], h);
            add(&QUINTIC[2], a[0], h * h);
            add(&QUINTIC[3], q[1], 1.0);
            add(&QUINTIC[4], v[1], h);
            add(&QUINTIC[5], a[1], h * h);
        }
    }
}

/// The coordinates of a node as the solution driver carries them: an
/// array at a compile-time size, a vector at a run-time size.
pub(crate) trait Coordinates: Clone + AsRef<[f64]> + AsMut<[f64]> {
    /// `width` values `x` (the width is the array's own at a compile-time size).
    fn filled(width: usize, x: f64) -> Self;
}

impl<const N: usize> Coordinates for [f64; N] {
    fn filled(_width: usize, x: f64) -> Self {
        [x; N]
    }
}

impl Coordinates for Vec<f64> {
    fn filled(width: usize, x: f64) -> Self {
        vec![x; width]
    }
}

/// A node with coordinates `V` ([`Coordinates`]): [`Node`] at either size.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Point<V> {
    /// `t_k`.
    pub(crate) t: f64,
    /// `q_k`.
    pub(crate) q: V,
    /// `p_k`.
    pub(crate) p: V,
    /// `v_k` with `∂L/∂v(t_k, q_k, v_k) = p_k`.
    pub(crate) v: V,
}

impl<V: Coordinates> Point<V> {
    /// The node as slices.
    pub(crate) fn view(&self) -> NodeView<'_> {
        NodeView { t: self.t, q: self.q.as_ref(), p: self.p.as_ref(), v: self.v.as_ref() }
    }
}

impl<const N: usize> From<&Point<[f64; N]>> for Node<N> {
    fn from(x: &Point<[f64; N]>) -> Self {
        Node { t: x.t, q: x.q, p: x.p, v: x.v }
    }
}

/// The interpolant of one step with coordinates `V`, at either size.
pub(crate) trait Interpolant<V> {
    /// Position and velocity at `t`.
    fn eval(&self, t: f64) -> (V, V);
}

impl<D: DenseStep<N>, const N: usize> Interpolant<[f64; N]> for D {
    #[inline]
    fn eval(&self, t: f64) -> ([f64; N], [f64; N]) {
        DenseStep::eval(self, t)
    }
}

/// A Galerkin step's polynomial `q(t_0 + τh) = q_0 + Σ_m ℓ_m(τ) D_m`
/// through its `s + 1` control nodes, at a run-time size.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct StepPolynomial {
    pub(crate) t0: f64,
    pub(crate) h: f64,
    /// `τ_0 = 0, τ_1, …, τ_s`.
    pub(crate) tau: Vec<f64>,
    pub(crate) q0: Vec<f64>,
    /// `D_m = Q_m − q_0`, coordinate `i`'s at `i·s + m − 1`.
    pub(crate) d: Vec<f64>,
}

impl Interpolant<Vec<f64>> for StepPolynomial {
    fn eval(&self, t: f64) -> (Vec<f64>, Vec<f64>) {
        let s = self.tau.len() - 1;
        let x = (t - self.t0) / self.h;
        let mut q = self.q0.clone();
        let mut v = vec![0.0; q.len()];
        // ℓ_m and ℓ_m' for m = 1 … s (ℓ_0 multiplies Q_0 − Q_0 = 0), in the
        // order of the compile-time size's polynomial.
        for m in 1..=s {
            let (mut value, mut slope) = (1.0, 0.0);
            for k in (0..=s).filter(|&k| k != m) {
                let w = 1.0 / (self.tau[m] - self.tau[k]);
                slope = slope * (x - self.tau[k]) * w + value * w;
                value *= (x - self.tau[k]) * w;
            }
            for (i, (q, v)) in q.iter_mut().zip(v.iter_mut()).enumerate() {
                let d = self.d[i * s + m - 1];
                *q += value * d;
                *v += slope * d / self.h;
            }
        }
        (q, v)
    }
}

/// The dense output of one step at a run-time size: a Galerkin rule's step
/// polynomial, or the cubic (quintic) Hermite of the nodes for the other
/// methods.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum RunTimeStep {
    /// A Galerkin rule's own interpolant, as at a compile-time size.
    Polynomial(StepPolynomial),
    /// The Hermite of the step's nodes.
    Hermite(HermiteRows),
}

impl Interpolant<Vec<f64>> for RunTimeStep {
    fn eval(&self, t: f64) -> (Vec<f64>, Vec<f64>) {
        match self {
            RunTimeStep::Polynomial(p) => p.eval(t),
            RunTimeStep::Hermite(h) => h.eval(t),
        }
    }
}

/// [`Hermite`] at a run-time size: the same interpolant of one step, its
/// nodes on the heap.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct HermiteRows {
    t0: f64,
    h: f64,
    q: [Vec<f64>; 2],
    v: [Vec<f64>; 2],
    /// `None`: the cubic.
    a: Option<[Vec<f64>; 2]>,
}

impl HermiteRows {
    /// The cubic through `(q, v)` at `start` and `end`, or with
    /// accelerations `a = (a0, a1)` the quintic.
    pub(crate) fn new(start: &Point<Vec<f64>>, end: &Point<Vec<f64>>, a: Option<(&Vec<f64>, &Vec<f64>)>) -> Self {
        Self {
            t0: start.t,
            h: end.t - start.t,
            q: [start.q.clone(), end.q.clone()],
            v: [start.v.clone(), end.v.clone()],
            a: a.map(|(a0, a1)| [a0.clone(), a1.clone()]),
        }
    }
}

impl Interpolant<Vec<f64>> for HermiteRows {
    fn eval(&self, t: f64) -> (Vec<f64>, Vec<f64>) {
        let n = self.q[0].len();
        let (mut q, mut v) = (vec![0.0; n], vec![0.0; n]);
        let a = self.a.as_ref().map(|a| [&a[0][..], &a[1][..]]);
        hermite_into(self.t0, self.h, [&self.q[0], &self.q[1]], [&self.v[0], &self.v[1]], a, t, &mut q, &mut v);
        (q, v)
    }
}

/// A Galerkin step's own polynomial `q(t_0 + τh) = Σ_m ℓ_m(τ) Q_m` through
/// its `s + 1` control nodes `τ_0 = 0, τ_1, …, τ_s = 1`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GalerkinPolynomial<const N: usize, const S: usize> {
    t0: f64,
    h: f64,
    /// `τ_1 … τ_s`.
    tau: [f64; S],
    /// `Q_0`.
    q0: [f64; N],
    /// `Q_m − Q_0`, `m = 1 … s`: differences keep the interpolation free of
    /// the cancellation of large coordinates.
    d: [[f64; N]; S],
}

impl<const N: usize, const S: usize> GalerkinPolynomial<N, S> {
    /// The polynomial of a step of size `h` from `t0`, with control nodes
    /// `tau` (`τ_1 … τ_s`), start `q0` and node values `nodes` (`Q_1 … Q_s`).
    pub fn new(t0: f64, h: f64, tau: [f64; S], q0: [f64; N], nodes: [[f64; N]; S]) -> Self {
        let d = nodes.map(|x| core::array::from_fn(|i| x[i] - q0[i]));
        Self { t0, h, tau, q0, d }
    }

    fn node(&self, m: usize) -> f64 {
        if m == 0 { 0.0 } else { self.tau[m - 1] }
    }
}

impl<const N: usize, const S: usize> DenseStep<N> for GalerkinPolynomial<N, S> {
    fn t0(&self) -> f64 {
        self.t0
    }

    fn t1(&self) -> f64 {
        self.t0 + self.h
    }

    fn eval(&self, t: f64) -> ([f64; N], [f64; N]) {
        let s = (t - self.t0) / self.h;
        let mut q = self.q0;
        let mut v = [0.0; N];
        // ℓ_m and ℓ_m' for m = 1 … s (ℓ_0 multiplies Q_0 − Q_0 = 0).
        for m in 1..=S {
            let (mut value, mut slope) = (1.0, 0.0);
            for k in (0..=S).filter(|&k| k != m) {
                let w = 1.0 / (self.node(m) - self.node(k));
                slope = slope * (s - self.node(k)) * w + value * w;
                value *= (s - self.node(k)) * w;
            }
            for i in 0..N {
                q[i] += value * self.d[m - 1][i];
                v[i] += slope * self.d[m - 1][i] / self.h;
            }
        }
        (q, v)
    }
}

/// The acceleration `a = q̈` of the equations of motion
/// `d/dt ∂L/∂v − ∂L/∂q = F` at `(t, q, v)`:
///
/// ```text
/// ∂²L/∂v² a = ∂L/∂q + F − ∂²L/∂v∂q v − ∂²L/∂v∂t
/// ```
///
/// One evaluation of `L` on a hyper-dual seeded on `v` (first infinitesimal)
/// and on `(q, t, v)` (second), plus the force; above 8 coordinates
/// evaluations on blocks of eight seeds (two above 128 coordinates), whose
/// numbers do not grow with `N`.
/// `None` where `∂²L/∂v²` is singular or a value is not finite.
pub fn acceleration<S: Lagrangian<N> + ?Sized, const N: usize>(
    system: &S,
    t: f64,
    q: [f64; N],
    v: [f64; N],
) -> Option<[f64; N]> {
    if const { N > NARROW_ABOVE } {
        return acceleration_by_blocks::<S, N, 2, 3>(system, t, q, v);
    }
    if const { N > BLOCKS_ABOVE } {
        return acceleration_by_blocks::<S, N, 8, 9>(system, t, q, v);
    }
    acceleration_at_once(system, t, q, v)
}

/// [`acceleration`] from one evaluation.
fn acceleration_at_once<S: Lagrangian<N> + ?Sized, const N: usize>(
    system: &S,
    t: f64,
    q: [f64; N],
    v: [f64; N],
) -> Option<[f64; N]> {
    type E2<const N: usize> = Pair<Timed<f64, N>, [f64; N]>;
    type D<const N: usize> = HyperDualArray<[f64; N], E2<N>>;
    let mut qd = q.map(D::<N>::from_re);
    let mut vd = v.map(D::<N>::from_re);
    for i in 0..N {
        qd[i].eps2.a.q[i] = 1.0;
        vd[i].eps1[i] = 1.0;
        vd[i].eps2.b[i] = 1.0;
    }
    let mut td = D::<N>::from_re(t);
    td.eps2.a.t = 1.0;
    let l = system.lagrangian(td, qd, vd);
    let f = generalized_force(system, t, q, v);
    // Slots of ε2: q_j at j, t at N, v_j at N + 1 + j.
    let mass = SMatrix::<f64, N, N>::from_fn(|i, j| l.mixed(i, N + 1 + j));
    let rhs = nalgebra::SVector::<f64, N>::from_fn(|i, _| {
        let coupling: f64 = (0..N).map(|j| l.mixed(i, j) * v[j]).sum();
        l.eps2.a.q[i] + f[i] - coupling - l.mixed(i, N)
    });
    let a = mass.try_inverse()? * rhs;
    a.iter().all(|x| x.is_finite()).then(|| core::array::from_fn(|i| a[i]))
}

/// Above this many coordinates [`acceleration`] evaluates `L` on blocks of
/// eight seeds: the one evaluation's numbers carry `N × (2N + 1)` mixed
/// parts (16 kB at `N = 32`, 1 MiB at `N = 256`), far more than a thread's
/// stack holds for the `2N` arguments of `L`.
const BLOCKS_ABOVE: usize = 8;

/// Above this many coordinates the blocks have two seeds a side: a number
/// of eight (90 parts, 720 bytes) makes the `2N` arguments of `L` 1.4 MB at
/// `N = 1000`, of two (12 parts) 190 kB. The work is about the same, `N³`
/// products of parts, in more evaluations of fewer parts.
const NARROW_ABOVE: usize = 128;

/// [`acceleration`] by blocks of `L` seeds a side (`L1 = L + 1`):
/// `∂²L/∂v²` from `⌈N/L⌉²` evaluations seeded on `L` velocities on each
/// side, the last of each row of blocks also seeded (second infinitesimal)
/// along `(q̇, ṫ) = (v, 1)`, which gives `∂²L/∂v∂q v + ∂²L/∂v∂t` directly;
/// `∂L/∂q` from `⌈N/L⌉` dual evaluations. The mass matrix and the solve are
/// on the heap.
fn acceleration_by_blocks<S: Lagrangian<N> + ?Sized, const N: usize, const LANES: usize, const L1: usize>(
    system: &S,
    t: f64,
    q: [f64; N],
    v: [f64; N],
) -> Option<[f64; N]> {
    const { assert!(L1 == LANES + 1) };
    // ε2 lanes: `LANES` velocities, then the direction (v, 1) in `(q, t)`.
    type H<const L: usize, const L1: usize> = HyperDualArray<[f64; L], [f64; L1]>;
    type D<const L: usize> = crate::hyperdual::DualArray<[f64; L]>;
    let mut mass = nalgebra::DMatrix::<f64>::zeros(N, N);
    let mut rhs = nalgebra::DVector::<f64>::zeros(N);
    let f = generalized_force(system, t, q, v);
    for i0 in (0..N).step_by(LANES) {
        let rows = LANES.min(N - i0);
        for j0 in (0..N).step_by(LANES) {
            let columns = LANES.min(N - j0);
            let last = j0 + LANES >= N;
            let mut qd = q.map(H::<LANES, L1>::from_re);
            let mut vd = v.map(H::<LANES, L1>::from_re);
            let mut td = H::<LANES, L1>::from_re(t);
            for i in 0..rows {
                vd[i0 + i].eps1[i] = 1.0;
            }
            for j in 0..columns {
                vd[j0 + j].eps2[j] = 1.0;
            }
            if last {
                for k in 0..N {
                    qd[k].eps2[LANES] = v[k];
                }
                td.eps2[LANES] = 1.0;
            }
            let l = system.lagrangian(td, qd, vd);
            for i in 0..rows {
                for j in 0..columns {
                    mass[(i0 + i, j0 + j)] = l.eps1eps2[i][j];
                }
                if last {
                    rhs[i0 + i] -= l.eps1eps2[i][LANES];
                }
            }
        }
        let mut qd = q.map(D::<LANES>::from_re);
        for i in 0..rows {
            qd[i0 + i].eps[i] = 1.0;
        }
        let l = system.lagrangian(D::<LANES>::from_re(t), qd, v.map(D::<LANES>::from_re));
        for i in 0..rows {
            rhs[i0 + i] += l.eps[i] + f[i0 + i];
        }
    }
    let a = mass.lu().solve(&rhs)?;
    a.iter().all(|x| x.is_finite()).then(|| core::array::from_fn(|i| a[i]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::system::Scalar;

    /// Not separable, time-dependent: `L = ½(1 + q₀²) v₀² + v₀ v₁ sin t + ½ v₁² − q₀ q₁`.
    struct Coupled;

    impl Lagrangian<2> for Coupled {
        const AUTONOMOUS: bool = false;
        const CYCLIC: [bool; 2] = [false, false];
        fn lagrangian<D: Scalar>(&self, t: D, q: [D; 2], v: [D; 2]) -> D {
            (q[0] * q[0] + 1.0) * v[0] * v[0] * 0.5 + v[0] * v[1] * t.sin() + v[1] * v[1] * 0.5 - q[0] * q[1]
        }
    }

    /// Against the equations of motion written out by hand.
    #[test]
    fn acceleration_solves_the_equations_of_motion() {
        let (t, q, v) = (0.7, [0.4, -1.1], [0.9, 0.3]);
        let a = acceleration(&Coupled, t, q, v).unwrap();
        let (s, c) = (t.sin(), t.cos());
        // p₀ = (1 + q₀²) v₀ + v₁ sin t,  p₁ = v₀ sin t + v₁.
        // ṗ₀ = 2 q₀ v₀² + (1 + q₀²) a₀ + a₁ s + v₁ c = ∂L/∂q₀ = q₀ v₀² − q₁
        // ṗ₁ = a₀ s + v₀ c + a₁ = ∂L/∂q₁ = −q₀
        let r0 = q[0] * v[0] * v[0] - q[1] - 2.0 * q[0] * v[0] * v[0] - v[1] * c;
        let r1 = -q[0] - v[0] * c;
        let m = 1.0 + q[0] * q[0];
        let det = m - s * s;
        let expected = [(r0 - s * r1) / det, (m * r1 - s * r0) / det];
        for i in 0..2 {
            assert!((a[i] - expected[i]).abs() < 1e-14, "{a:?} against {expected:?}");
        }
    }

    /// A ring of 11 rotors with coupled, position-dependent masses, a
    /// time-dependent drive and a force: two full blocks and a partial one.
    struct Rotors;

    impl Lagrangian<11> for Rotors {
        const AUTONOMOUS: bool = false;
        const CYCLIC: [bool; 11] = [false; 11];
        const HAS_FORCE: bool = true;
        fn lagrangian<D: Scalar>(&self, t: D, q: [D; 11], v: [D; 11]) -> D {
            let mut l = D::zero();
            for i in 0..11 {
                let j = (i + 1) % 11;
                l += v[i] * v[i] * (q[i].cos() * 0.2 + 1.0 + 0.1 * i as f64) * 0.5 + q[i].cos() * t.sin();
                l += v[i] * v[j] * (q[i] - q[j]).cos() * 0.2 + v[i] * q[j] * 0.3;
            }
            l
        }
        fn force<D: Scalar>(&self, _t: D, q: [D; 11], v: [D; 11]) -> [D; 11] {
            core::array::from_fn(|i| v[i] * -0.05 + q[i] * 0.01)
        }
    }

    /// The blocked evaluation against the one evaluation.
    #[test]
    fn acceleration_by_blocks_agrees_with_the_one_evaluation() {
        let q = core::array::from_fn(|i| 0.37 * i as f64 - 1.3);
        let v = core::array::from_fn(|i| (0.7 * i as f64).sin());
        let one = acceleration_at_once(&Rotors, 0.4, q, v).unwrap();
        let blocks = acceleration_by_blocks::<_, 11, 8, 9>(&Rotors, 0.4, q, v).unwrap();
        // Two seeds a side, as above `NARROW_ABOVE` (blocks that straddle
        // the eight-seed blocks' edges).
        let narrow = acceleration_by_blocks::<_, 11, 2, 3>(&Rotors, 0.4, q, v).unwrap();
        let scale = one.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        for i in 0..11 {
            assert!((one[i] - blocks[i]).abs() <= 1e-13 * scale, "{i}: {} vs {}", one[i], blocks[i]);
            assert!((one[i] - narrow[i]).abs() <= 1e-13 * scale, "{i}: {} vs {}", one[i], narrow[i]);
        }
        assert_eq!(acceleration(&Rotors, 0.4, q, v), Some(blocks));
    }

    #[test]
    fn interpolants_reproduce_their_data() {
        let start = Node { t: 1.0, q: [0.3], p: [0.0], v: [-0.2] };
        let end = Node { t: 1.5, q: [0.1], p: [0.0], v: [0.4] };
        for dense in [Hermite::cubic(&start, &end), Hermite::quintic(&start, [0.7], &end, [-1.3])] {
            for node in [&start, &end] {
                let (q, v) = DenseStep::eval(&dense, node.t);
                assert!((q[0] - node.q[0]).abs() < 1e-15 && (v[0] - node.v[0]).abs() < 1e-14);
            }
        }
        // A cubic is reproduced exactly by both Hermite interpolants.
        let f = |t: f64| (t * t * t - 2.0 * t, 3.0 * t * t - 2.0, 6.0 * t);
        let node = |t: f64| Node { t, q: [f(t).0], p: [0.0], v: [f(t).1] };
        let (a, b) = (node(1.0), node(1.5));
        for dense in [Hermite::cubic(&a, &b), Hermite::quintic(&a, [f(1.0).2], &b, [f(1.5).2])] {
            let (q, v) = DenseStep::eval(&dense, 1.2);
            assert!((q[0] - f(1.2).0).abs() < 1e-14 && (v[0] - f(1.2).1).abs() < 1e-13);
        }
        // The Galerkin polynomial through a quadratic.
        let g = |t: f64| 2.0 * t * t - t;
        let poly = GalerkinPolynomial::new(1.0, 0.5, [0.5, 1.0], [g(1.0)], [[g(1.25)], [g(1.5)]]);
        let (q, v) = DenseStep::eval(&poly, 1.1);
        assert!((q[0] - g(1.1)).abs() < 1e-14 && (v[0] - (4.0 * 1.1 - 1.0)).abs() < 1e-13);
    }
}
