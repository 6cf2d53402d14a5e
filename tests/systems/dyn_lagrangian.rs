//! `#[lagrangian]` on run-time-sized systems: a `lagrangian` over slices
//! (`q: &[f64], v: &[f64]`) with `fn dimension` implements `DynLagrangian`.
//!
//! Each chain is written twice, once with slices and once with `[f64; N]`,
//! with the same arithmetic in the same order. At random states (N = 8) the
//! two agree on `f64`, on first derivatives from `Dual64` and on the whole
//! Hessian in `(q, v)` from `HyperDual64`; their `SEPARABILITY` and
//! `COUPLING` agree (the slice form's bandwidth normalised against 8); and
//! the slice form's pattern is checked against its Hessian at two other
//! dimensions: every entry outside the pattern is exactly zero (forward-mode
//! second derivatives of terms that do not involve a pair are `0.0`
//! exactly). A ring and a chain indexed through data must come out
//! `General`, and their Hessians show why.
#![allow(missing_docs)]

use lagrangian::num_dual::{Dual64, HyperDual64};
use lagrangian::prelude::*;
use lagrangian::{Coupling, Pattern, Separability};

// ------------------------------------------------------------- FPU-β chain

/// The FPU-β chain with fixed ends, run-time-sized: bounds from `q.len()`
/// and `v.len()`.
pub struct FpuDyn {
    pub beta: f64,
    pub n: usize,
}

#[lagrangian]
impl FpuDyn {
    fn dimension(&self) -> usize {
        self.n
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        let n = q.len();
        let mut kinetic = 0.0;
        for i in 0..v.len() {
            kinetic += 0.5 * v[i] * v[i];
        }
        let mut d = q[0];
        let mut potential = 0.5 * d * d + 0.25 * self.beta * d.powi(4);
        for i in 0..n - 1 {
            d = q[i + 1] - q[i];
            potential += 0.5 * d * d + 0.25 * self.beta * d.powi(4);
        }
        d = q[q.len() - 1];
        potential += 0.5 * d * d + 0.25 * self.beta * d.powi(4);
        kinetic - potential
    }
}

/// The same chain with a size fixed at compile time.
pub struct Fpu<const N: usize> {
    pub beta: f64,
}

#[lagrangian]
impl<const N: usize> Fpu<N> {
    fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
        let n = N;
        let mut kinetic = 0.0;
        for i in 0..N {
            kinetic += 0.5 * v[i] * v[i];
        }
        let mut d = q[0];
        let mut potential = 0.5 * d * d + 0.25 * self.beta * d.powi(4);
        for i in 0..n - 1 {
            d = q[i + 1] - q[i];
            potential += 0.5 * d * d + 0.25 * self.beta * d.powi(4);
        }
        d = q[N - 1];
        potential += 0.5 * d * d + 0.25 * self.beta * d.powi(4);
        kinetic - potential
    }
}

// ------------------------------------------------------------ coupled pendula

/// Pendula hanging from a driven line, each coupled to the next through the
/// kinetic energy and a torsion spring: not separable, a mass matrix that
/// depends on `q`, banded; time-dependent. Loops bounded by a field.
pub struct PendulaDyn {
    pub n: usize,
    pub c: f64,
    pub k: f64,
    pub drive: f64,
}

#[lagrangian]
impl PendulaDyn {
    fn dimension(&self) -> usize {
        self.n
    }

    fn lagrangian(&self, t: f64, q: &[f64], v: &[f64]) -> f64 {
        let mut l = 0.0;
        for i in 0..self.n {
            l += 0.5 * v[i] * v[i] + q[i].cos();
        }
        for i in 1..self.n {
            let (a, b) = (i - 1, i);
            l += self.c * v[a] * v[b] * (q[a] - q[b]).cos() - 0.5 * self.k * (q[b] - q[a]).powi(2);
        }
        l + self.drive * t.cos() * q[0].sin()
    }
}

/// The same pendula with a size fixed at compile time.
pub struct Pendula<const N: usize> {
    pub c: f64,
    pub k: f64,
    pub drive: f64,
}

#[lagrangian]
impl<const N: usize> Pendula<N> {
    fn lagrangian(&self, t: f64, q: [f64; N], v: [f64; N]) -> f64 {
        let mut l = 0.0;
        for i in 0..N {
            l += 0.5 * v[i] * v[i] + q[i].cos();
        }
        for i in 1..N {
            let (a, b) = (i - 1, i);
            l += self.c * v[a] * v[b] * (q[a] - q[b]).cos() - 0.5 * self.k * (q[b] - q[a]).powi(2);
        }
        l + self.drive * t.cos() * q[0].sin()
    }
}

// ------------------------------------------------ patterns that are not bands

/// A ring: the last particle is bound to the first, so `q₀` and `q_{n−1}`
/// couple and no band narrower than the system holds.
pub struct Ring {
    pub n: usize,
}

#[lagrangian]
impl Ring {
    fn dimension(&self) -> usize {
        self.n
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        let mut l = 0.0;
        for i in 0..q.len() {
            let j = (i + 1) % q.len();
            l += 0.5 * v[i] * v[i] - (q[j] - q[i]).powi(4);
        }
        l
    }
}

/// Springs between the particles listed in `order`: the index comes from
/// data.
pub struct Listed {
    pub order: Vec<usize>,
}

#[lagrangian]
impl Listed {
    fn dimension(&self) -> usize {
        self.order.len()
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        let mut l = 0.0;
        for i in 1..v.len() {
            let (a, b) = (self.order[i - 1], self.order[i]);
            l += 0.5 * v[i] * v[i] - (q[a] - q[b]).powi(2) * q[i].cos();
        }
        l
    }
}

// ------------------------------------------------------------------ helpers

/// SplitMix64, for reproducible states.
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

    fn vec(&mut self, n: usize, lo: f64, hi: f64) -> Vec<f64> {
        (0..n).map(|_| lo + (hi - lo) * self.next()).collect()
    }

    /// `t ∈ [0, 10]`, `q ∈ [−1, 1]`, `v ∈ [−1, 1]`.
    fn state(&mut self, n: usize) -> (f64, Vec<f64>, Vec<f64>) {
        let t = 10.0 * self.next();
        (t, self.vec(n, -1.0, 1.0), self.vec(n, -1.0, 1.0))
    }
}

/// Hyper-dual seeds for entry `(a, b)` of the Hessian in `x = (q, v)`.
fn seeded(x: &[f64], a: usize, b: usize) -> Vec<HyperDual64> {
    let one = |k: usize, at: usize| f64::from(u8::from(k == at));
    x.iter().enumerate().map(|(k, &x)| HyperDual64::new(x, one(k, a), one(k, b), 0.0)).collect()
}

/// The Hessian of `L` in `(q, v)` of a slice system, `2n × 2n`.
fn dyn_hessian<S: DynLagrangian>(s: &S, t: f64, q: &[f64], v: &[f64]) -> Vec<Vec<f64>> {
    let n = q.len();
    let x: Vec<f64> = q.iter().chain(v).copied().collect();
    let mut h = vec![vec![0.0; 2 * n]; 2 * n];
    for a in 0..2 * n {
        for b in a..2 * n {
            let x = seeded(&x, a, b);
            let value = DynLagrangian::lagrangian(s, HyperDual64::from_re(t), &x[..n], &x[n..]);
            h[a][b] = value.eps1eps2;
            h[b][a] = value.eps1eps2;
        }
    }
    h
}

/// The same for an array system.
fn array_hessian<S: Lagrangian<N>, const N: usize>(s: &S, t: f64, q: &[f64], v: &[f64]) -> Vec<Vec<f64>> {
    let x: Vec<f64> = q.iter().chain(v).copied().collect();
    let mut h = vec![vec![0.0; 2 * N]; 2 * N];
    for a in 0..2 * N {
        for b in a..2 * N {
            let x = seeded(&x, a, b);
            let (qd, vd): ([HyperDual64; N], [HyperDual64; N]) =
                (std::array::from_fn(|i| x[i]), std::array::from_fn(|i| x[N + i]));
            let value = Lagrangian::lagrangian(s, HyperDual64::from_re(t), qd, vd);
            h[a][b] = value.eps1eps2;
            h[b][a] = value.eps1eps2;
        }
    }
    h
}

/// The gradient of `L` in `(q, v)` of a slice system, one `Dual64` pass per
/// variable.
fn dyn_gradient<S: DynLagrangian>(s: &S, t: f64, q: &[f64], v: &[f64]) -> Vec<f64> {
    let n = q.len();
    let x: Vec<f64> = q.iter().chain(v).copied().collect();
    (0..2 * n)
        .map(|a| {
            let x: Vec<Dual64> =
                x.iter().enumerate().map(|(k, &x)| Dual64::new(x, f64::from(u8::from(k == a)))).collect();
            DynLagrangian::lagrangian(s, Dual64::from_re(t), &x[..n], &x[n..]).eps
        })
        .collect()
}

/// The same for an array system.
fn array_gradient<S: Lagrangian<N>, const N: usize>(s: &S, t: f64, q: &[f64], v: &[f64]) -> Vec<f64> {
    let x: Vec<f64> = q.iter().chain(v).copied().collect();
    (0..2 * N)
        .map(|a| {
            let x: Vec<Dual64> =
                x.iter().enumerate().map(|(k, &x)| Dual64::new(x, f64::from(u8::from(k == a)))).collect();
            let (qd, vd): ([Dual64; N], [Dual64; N]) =
                (std::array::from_fn(|i| x[i]), std::array::from_fn(|i| x[N + i]));
            Lagrangian::lagrangian(s, Dual64::from_re(t), qd, vd).eps
        })
        .collect()
}

/// `|a − b| ≤ 4 ε max(1, |a|, |b|)`: the two forms evaluate the same
/// operations, so anything beyond a few ulps is a difference in the rewrite.
fn same(a: f64, b: f64) -> bool {
    (a - b).abs() <= 4.0 * f64::EPSILON * a.abs().max(b.abs()).max(1.0)
}

/// A pattern of a run-time-sized system as the array system of size `n`
/// reports it.
fn at(pattern: Pattern, n: usize) -> Pattern {
    match pattern {
        Pattern::Banded { bandwidth } => Pattern::banded(n, bandwidth),
        other => other,
    }
}

fn coupling_at(c: Coupling, n: usize) -> Coupling {
    Coupling { q_q: at(c.q_q, n), q_v: at(c.q_v, n), v_v: at(c.v_v, n) }
}

/// The slice and array forms agree at five random states of size `N`:
/// values, gradients and Hessians.
fn agree<D: DynLagrangian, A: Lagrangian<N>, const N: usize>(name: &str, d: &D, a: &A, seed: u64) {
    assert_eq!(d.dimension(), N, "{name}: dimension");
    let mut rng = Rng(seed);
    let mut largest = 0.0f64;
    for _ in 0..5 {
        let (t, q, v) = rng.state(N);
        let (qa, va): ([f64; N], [f64; N]) = (std::array::from_fn(|i| q[i]), std::array::from_fn(|i| v[i]));
        let (ld, la) = (DynLagrangian::lagrangian(d, t, &q, &v), Lagrangian::lagrangian(a, t, qa, va));
        assert!(same(ld, la), "{name}: L = {ld} (slices) against {la} (arrays)");
        for (k, (gd, ga)) in dyn_gradient(d, t, &q, &v).into_iter().zip(array_gradient(a, t, &q, &v)).enumerate() {
            assert!(same(gd, ga), "{name}: ∂L/∂x{k} = {gd} (slices) against {ga} (arrays)");
        }
        let (hd, ha) = (dyn_hessian(d, t, &q, &v), array_hessian(a, t, &q, &v));
        for i in 0..2 * N {
            for j in 0..2 * N {
                assert!(same(hd[i][j], ha[i][j]), "{name}: H[{i}][{j}] = {} against {}", hd[i][j], ha[i][j]);
                largest = largest.max(hd[i][j].abs());
            }
        }
    }
    // A Hessian of zeros would agree trivially.
    assert!(largest > 0.1, "{name}: Hessian entries up to {largest}");
}

/// Every entry of the Hessian outside `S::COUPLING` is exactly zero, at two
/// random states of dimension `s.dimension()`.
fn pattern_holds<S: DynLagrangian>(name: &str, s: &S, seed: u64) {
    let n = s.dimension();
    let c = S::COUPLING;
    let mut rng = Rng(seed);
    for _ in 0..2 {
        let (t, q, v) = rng.state(n);
        let h = dyn_hessian(s, t, &q, &v);
        for i in 0..n {
            for j in 0..n {
                for (block, pattern, a, b) in
                    [("q–q", c.q_q, i, j), ("q–v", c.q_v, i, n + j), ("v–v", c.v_v, n + i, n + j)]
                {
                    assert!(
                        pattern.may_couple(i, j) || h[a][b] == 0.0,
                        "{name}, n = {n}: {block} entry ({i}, {j}) = {:e} outside {pattern:?}",
                        h[a][b]
                    );
                }
            }
        }
    }
}

// -------------------------------------------------------------------- tests

#[test]
fn fpu_slices_evaluate_like_arrays() {
    agree("FPU-β", &FpuDyn { beta: 1.3, n: 8 }, &Fpu::<8> { beta: 1.3 }, 1);
}

#[test]
fn coupled_pendula_slices_evaluate_like_arrays() {
    let (c, k, drive) = (0.4, 2.5, 0.7);
    agree("pendula", &PendulaDyn { n: 8, c, k, drive }, &Pendula::<8> { c, k, drive }, 2);
}

#[test]
fn structure_matches_the_array_forms() {
    assert_eq!(<FpuDyn as DynLagrangian>::SEPARABILITY, <Fpu<8> as Lagrangian<8>>::SEPARABILITY);
    assert_eq!(coupling_at(FpuDyn::COUPLING, 8), <Fpu<8> as Lagrangian<8>>::COUPLING);
    assert_eq!(<PendulaDyn as DynLagrangian>::SEPARABILITY, <Pendula<8> as Lagrangian<8>>::SEPARABILITY);
    assert_eq!(coupling_at(PendulaDyn::COUPLING, 8), <Pendula<8> as Lagrangian<8>>::COUPLING);

    // What the analysis should find, so that "general" everywhere fails.
    let band = Pattern::Banded { bandwidth: 1 };
    assert_eq!(<FpuDyn as DynLagrangian>::SEPARABILITY, Separability::ConstantMass);
    assert_eq!(FpuDyn::COUPLING, Coupling { q_q: band, q_v: Pattern::Diagonal, v_v: Pattern::Diagonal });
    assert_eq!(<PendulaDyn as DynLagrangian>::SEPARABILITY, Separability::QuadraticKinetic);
    assert_eq!(PendulaDyn::COUPLING, Coupling { q_q: band, q_v: band, v_v: band });
    let flags = |autonomous: bool, discontinuous: bool| (autonomous, discontinuous);
    assert_eq!(flags(<FpuDyn as DynLagrangian>::AUTONOMOUS, FpuDyn::DISCONTINUOUS), (true, false));
    assert_eq!(flags(<PendulaDyn as DynLagrangian>::AUTONOMOUS, PendulaDyn::DISCONTINUOUS), (false, false));
}

#[test]
fn patterns_hold_at_other_dimensions() {
    for (seed, n) in [(3, 5), (4, 13)] {
        pattern_holds("FPU-β", &FpuDyn { beta: 0.9, n }, seed);
        pattern_holds("pendula", &PendulaDyn { n, c: 0.3, k: 1.7, drive: 0.5 }, seed);
        pattern_holds("ring", &Ring { n }, seed);
        pattern_holds("listed", &Listed { order: (0..n).rev().collect() }, seed);
    }
}

#[test]
fn what_is_not_a_band_is_general_and_needs_to_be() {
    // The ring couples `q₀` with `q_{n−1}`; the listed chain, walked
    // backwards, couples `q_i` with `q_{n−1−i}`.
    assert_eq!(Ring::COUPLING.q_q, Pattern::General);
    assert_eq!(Listed::COUPLING.q_q, Pattern::General);
    let n = 9;
    let mut rng = Rng(5);
    let (t, q, v) = rng.state(n);
    let ring = dyn_hessian(&Ring { n }, t, &q, &v);
    assert!(ring[0][n - 1] != 0.0, "the ring's corner entry is {}", ring[0][n - 1]);
    let listed = dyn_hessian(&Listed { order: (0..n).rev().collect() }, t, &q, &v);
    assert!(listed[1][n - 1] != 0.0, "the listed chain's entry (1, {}) is {}", n - 1, listed[1][n - 1]);
}

#[test]
fn dimension_is_the_users_method() {
    let s = Listed { order: vec![2, 0, 1] };
    // Inherent and trait method are the same function.
    assert_eq!(s.dimension(), 3);
    assert_eq!(DynLagrangian::dimension(&s), 3);
    // The user's own `f64` method is still there, over slices.
    let (q, v) = ([0.1, 0.2, 0.3], [1.0, 0.0, 0.0]);
    assert_eq!(s.lagrangian(&q, &v), DynLagrangian::lagrangian(&s, 0.0, &q, &v));
}

#[test]
fn a_chain_of_100_000_evaluates_in_a_small_thread() {
    // By-value arrays of this size would not fit the 2 MiB stack of a
    // default thread; slices live on the heap.
    let handle = std::thread::spawn(|| {
        let (n, beta) = (100_000, 0.7);
        let s = FpuDyn { beta, n };
        let mut rng = Rng(6);
        let (_, q, v) = rng.state(n);
        // Hand-written: ½|v|² − Σ φ(d) over the links and both walls.
        let phi = |d: f64| 0.5 * d * d + 0.25 * beta * d.powi(4);
        let walls = phi(q[0]) + phi(q[n - 1]);
        let links: f64 = q.windows(2).map(|w| phi(w[1] - w[0])).sum();
        let kinetic: f64 = v.iter().map(|v| 0.5 * v * v).sum();
        let expected = kinetic - links - walls;
        let l = DynLagrangian::lagrangian(&s, 0.0, &q, &v);
        // Sums of 10⁵ terms of size ≤ 1 in another order: 1e-10 relative is
        // far above their round-off and far below any missing term.
        assert!((l - expected).abs() <= 1e-10 * kinetic, "L = {l}, by hand {expected}");
        // One directional derivative along v: ∂L/∂v · v = |v|² = 2 T.
        let qd: Vec<Dual64> = q.iter().map(|&x| Dual64::from_re(x)).collect();
        let vd: Vec<Dual64> = v.iter().map(|&x| Dual64::new(x, x)).collect();
        let dl = DynLagrangian::lagrangian(&s, Dual64::from_re(0.0), &qd, &vd).eps;
        assert!((dl - 2.0 * kinetic).abs() <= 1e-10 * kinetic, "∂L/∂v · v = {dl}, by hand {}", 2.0 * kinetic);
    });
    handle.join().expect("the evaluation thread");
}
