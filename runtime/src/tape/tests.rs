//! The tape against num-dual's scalar hyper-duals (every function and
//! operator) and against the crate's array hyper-duals (Hessian blocks of
//! discrete Lagrangians of banded chains), its misuse errors, and a chain of
//! 100 000 coordinates in a default 2 MiB thread.
#![allow(clippy::op_ref)] // the reference forms of the operators are under test

use num_dual::{BesselDual, DualNum};
use num_traits::{Inv, Signed, Zero};

use super::*;
use crate::Scalar;
use crate::hyperdual::HyperDualArray;
use crate::structure::{Coupling, Pattern};
use crate::system::Lagrangian;

/// Unary operations under test. Those marked `true` are one tape node (or
/// none) with the partials of `hyperdual.rs`: gradient and Hessian must be bit
/// for bit num-dual's. The others are compositions whose sweeps sum the same
/// terms in another order.
const UNARY: &[(&str, bool)] = &[
    ("recip", true),
    ("powi0", true),
    ("powi1", true),
    ("powi2", false),
    ("powi3", true),
    ("powi-2", true),
    ("powi7", true),
    ("powf0", true),
    ("powf1", true),
    ("powf2", false),
    ("powf0.5", true),
    ("powf-1.5", true),
    ("powf3.7", true),
    ("sqrt", true),
    ("cbrt", true),
    ("exp", true),
    ("exp2", true),
    ("exp_m1", true),
    ("ln", true),
    ("log3", true),
    ("log2", true),
    ("log10", true),
    ("ln_1p", true),
    ("sin", true),
    ("cos", true),
    ("tan", false),
    ("sin_cos.0", true),
    ("sin_cos.1", true),
    ("asin", true),
    ("acos", true),
    ("atan", true),
    ("sinh", true),
    ("cosh", true),
    ("tanh", false),
    ("asinh", true),
    ("acosh", true),
    ("atanh", true),
    ("sph_j0", false),
    ("sph_j1", false),
    ("sph_j2", false),
    ("bessel_j0", false),
    ("bessel_j1", false),
    ("bessel_j2", false),
    ("abs", true),
    ("signum", true),
    ("neg", true),
    ("inv", true),
    ("scale", true),
    ("mul_add_self", false),
    ("powd_self", false),
    ("add_f64", true),
    ("sub_f64", true),
    ("mul_f64", true),
    ("div_f64", false),
    ("rem_f64", true),
    ("add_assign_f64", true),
    ("sub_assign_f64", true),
    ("mul_assign_f64", true),
    ("div_assign_f64", false),
    ("rem_assign_f64", true),
    ("square", false),
    ("quotient_self", false),
    ("sum", false),
    ("product", false),
];

fn unary<D: DualNum<Primitive = f64, InnerDual = f64> + Copy>(name: &str, x: D) -> D {
    match name {
        "recip" => x.recip(),
        "powi0" => x.powi(0),
        "powi1" => x.powi(1),
        "powi2" => x.powi(2),
        "powi3" => x.powi(3),
        "powi-2" => x.powi(-2),
        "powi7" => x.powi(7),
        "powf0" => x.powf(0.0),
        "powf1" => x.powf(1.0),
        "powf2" => x.powf(2.0),
        "powf0.5" => x.powf(0.5),
        "powf-1.5" => x.powf(-1.5),
        "powf3.7" => x.powf(3.7),
        "sqrt" => x.sqrt(),
        "cbrt" => x.cbrt(),
        "exp" => x.exp(),
        "exp2" => x.exp2(),
        "exp_m1" => x.exp_m1(),
        "ln" => x.ln(),
        "log3" => x.log(3.0),
        "log2" => x.log2(),
        "log10" => x.log10(),
        "ln_1p" => x.ln_1p(),
        "sin" => x.sin(),
        "cos" => x.cos(),
        "tan" => x.tan(),
        "sin_cos.0" => x.sin_cos().0,
        "sin_cos.1" => x.sin_cos().1,
        "asin" => x.asin(),
        "acos" => x.acos(),
        "atan" => x.atan(),
        "sinh" => x.sinh(),
        "cosh" => x.cosh(),
        "tanh" => x.tanh(),
        "asinh" => x.asinh(),
        "acosh" => (x + 1.5).acosh(),
        "atanh" => x.atanh(),
        "sph_j0" => x.sph_j0(),
        "sph_j1" => x.sph_j1(),
        "sph_j2" => x.sph_j2(),
        "bessel_j0" => x.bessel_j0(),
        "bessel_j1" => x.bessel_j1(),
        "bessel_j2" => x.bessel_j2(),
        "abs" => x.abs(),
        "signum" => x.signum(),
        "neg" => -x,
        "inv" => x.inv(),
        "scale" => x.scale(&-2.5),
        "mul_add_self" => x.mul_add(x, x),
        "powd_self" => x.powd(x),
        "add_f64" => x + 1.25,
        "sub_f64" => x - 1.25,
        "mul_f64" => x * 1.25,
        "div_f64" => x / 1.25,
        "rem_f64" => x % 0.3,
        "add_assign_f64" => {
            let mut y = x;
            y += 0.75;
            y
        }
        "sub_assign_f64" => {
            let mut y = x;
            y -= 0.75;
            y
        }
        "mul_assign_f64" => {
            let mut y = x;
            y *= 0.75;
            y
        }
        "div_assign_f64" => {
            let mut y = x;
            y /= 0.75;
            y
        }
        "rem_assign_f64" => {
            let mut y = x;
            y %= 0.3;
            y
        }
        "square" => x * x,
        "quotient_self" => (x + 2.0) / x,
        "sum" => [x, x * 2.0, x.sin()].into_iter().sum::<D>(),
        "product" => [x, x * 2.0, x.sin()].into_iter().product::<D>(),
        _ => unreachable!("{name}"),
    }
}

/// Binary operations; `true` as in [`UNARY`].
const BINARY: &[(&str, bool)] = &[
    ("add", true),
    ("sub", true),
    ("mul", true),
    ("div", true),
    ("rem", false),
    ("atan2", false),
    ("powd", false),
    ("mul_add", false),
    ("add_ref", true),
    ("sub_ref", true),
    ("div_assign", false),
    ("rem_assign", false),
    ("abs_sub", false),
    ("const_sub", false),
    ("const_div", false),
];

fn binary<D: DualNum<Primitive = f64, InnerDual = f64> + Copy>(name: &str, x: D, y: D) -> D {
    match name {
        "add" => x + y,
        "sub" => x - y,
        "mul" => x * y,
        "div" => x / y,
        "rem" => x % y,
        "atan2" => x.atan2(y),
        "powd" => x.powd(y),
        "mul_add" => x.mul_add(y, x * 3.0),
        "add_ref" => x + &y,
        "sub_ref" => x - &y,
        "div_assign" => {
            let mut z = x;
            z /= y;
            z *= x;
            z -= y;
            z += x;
            z
        }
        "rem_assign" => {
            let mut z = x * 7.0;
            z %= y;
            z
        }
        "abs_sub" => x.abs_sub(&y) + y.abs_sub(&x),
        // A constant on the left: the tape drops its parent.
        "const_sub" => D::from(2.5) - x * y,
        "const_div" => D::from(2.5) / (x - y * 3.0),
        _ => unreachable!("{name}"),
    }
}

/// The distance in units in the last place of `max(|a|, |b|, floor)`; 0 when
/// both are NaN or equal (so `0.0` and `-0.0` agree).
fn ulps(a: f64, b: f64, floor: f64) -> f64 {
    if (a.is_nan() && b.is_nan()) || a == b {
        return 0.0;
    }
    let scale = a.abs().max(b.abs()).max(floor);
    (a - b).abs() / (scale * f64::EPSILON)
}

/// Value, gradient and Hessian of `f` at `x` from the tape (the Hessian by
/// dense seeds, and again by the colouring of [`Seeds::Colours`]).
fn tape_derivatives(x: &[f64], f: impl Fn(&[Var]) -> Var) -> (f64, Vec<f64>, Vec<f64>) {
    let n = x.len();
    let mut tape = Tape::new();
    let value = tape.record(x, &f).unwrap();
    let mut g = vec![0.0; n];
    tape.gradient(&mut g).unwrap();
    let mut g2 = vec![0.0; n];
    let mut h = vec![0.0; n * n];
    tape.hessian_product(&Seeds::dense(0..n), &mut g2, &mut h).unwrap();
    let same = |a: &[f64], b: &[f64]| a.iter().zip(b).all(|(x, y)| x == y || x.is_nan() && y.is_nan());
    assert!(same(&g, &g2), "gradient of the reverse sweep {g:?} and of the second-order sweep {g2:?}");
    let colour: Vec<Option<u32>> = (0..n as u32).map(Some).collect();
    let mut h2 = vec![0.0; n * n];
    tape.hessian_product(&Seeds::Colours { colour: &colour, directions: n }, &mut g2, &mut h2).unwrap();
    assert!(same(&h, &h2), "dense seeds {h:?} and the identity colouring {h2:?}");
    (value, g, h)
}

/// The crate's scalar hyper-dual (bit for bit num-dual's `HyperDual64`, see
/// `hyperdual/tests.rs`, and with a remainder, which num-dual lacks).
type Hd = HyperDualArray<[f64; 1], [f64; 1]>;

/// Value, gradient and Hessian of a function of `n` variables from `n²`
/// scalar hyper-dual evaluations.
fn hyper_dual_derivatives(x: &[f64], f: impl Fn(&[Hd]) -> Hd) -> (f64, Vec<f64>, Vec<f64>) {
    let n = x.len();
    let mut g = vec![0.0; n];
    let mut h = vec![0.0; n * n];
    let mut value = f64::NAN;
    for i in 0..n {
        for j in 0..n {
            let args: Vec<Hd> =
                (0..n).map(|k| Hd::new(x[k], [f64::from(k == i)], [f64::from(k == j)], [[0.0]])).collect();
            let y = f(&args);
            value = y.re;
            g[i] = y.eps1[0];
            h[i * n + j] = y.eps1eps2[0][0];
        }
    }
    (value, g, h)
}

/// Compares tape and hyper-dual derivatives: bit for bit for an exact
/// operation, within `max_ulps` (of `max(|a|, |b|, 1)`) otherwise. Returns
/// the largest distance.
fn compare(
    what: &str,
    x: &[f64],
    exact: bool,
    max_ulps: f64,
    tape: (f64, Vec<f64>, Vec<f64>),
    hd: (f64, Vec<f64>, Vec<f64>),
) -> f64 {
    let (v, g, h) = tape;
    let (vw, gw, hw) = hd;
    assert!(ulps(v, vw, 0.0) == 0.0, "{what} at {x:?}: value {v} against {vw}");
    let mut worst: f64 = 0.0;
    for (part, got, want) in [("gradient", &g, &gw), ("hessian", &h, &hw)] {
        for (k, (&a, &b)) in got.iter().zip(want).enumerate() {
            // Compositions cancel (tanh′ = (cosh² − sinh²)/cosh²): their
            // rounding is relative to intermediate terms of order 1.
            let d = ulps(a, b, if exact { 0.0 } else { 1.0 });
            worst = worst.max(d);
            if exact {
                assert!(d == 0.0, "{what} at {x:?}: {part}[{k}] {a:e} against {b:e} (must be bit for bit)");
            } else {
                // Compositions: the same terms summed in another order.
                assert!(d <= max_ulps, "{what} at {x:?}: {part}[{k}] {a:e} against {b:e}, {d} ulps");
            }
        }
    }
    worst
}

/// Points inside every function's domain, one near zero for the series
/// branches, one above 5 for the asymptotic Bessel branch.
const POINTS: [f64; 5] = [0.37, -0.62, 1e-17, 0.91, 7.3];

fn in_domain(name: &str, x: f64) -> bool {
    let unit = ["asin", "acos", "atanh"].contains(&name);
    let positive =
        ["sqrt", "ln", "log3", "log2", "log10", "powf0.5", "powf-1.5", "powf3.7", "powd_self", "cbrt"].contains(&name);
    !(unit && x.abs() >= 1.0 || positive && x <= 0.0)
}

#[test]
fn unary_functions_agree_with_num_dual() {
    let mut worst: f64 = 0.0;
    for &(name, exact) in UNARY {
        for &x0 in &POINTS {
            if !in_domain(name, x0) {
                continue;
            }
            let x = [x0];
            // `2 J1(x)/x − J0(x)` near 0: derivative terms of order 1/x² cancel,
            // and both evaluations return rounding noise of order 1e34·ε.
            if name == "bessel_j2" && x0.abs() < 1e-8 {
                continue;
            }
            // `(sin x − x cos x)/x²` and the like cancel to order x² (measured
            // up to 33 ulps at x = −0.62); other compositions stay within 8.
            let max_ulps = if name.starts_with("sph_j") { 64.0 } else { 8.0 };
            let tape = tape_derivatives(&x, |v| unary(name, v[0]));
            let hd = hyper_dual_derivatives(&x, |v| unary(name, v[0]));
            worst = worst.max(compare(name, &x, exact, max_ulps, tape, hd));
        }
    }
    eprintln!("unary compositions: largest distance {worst} ulps");
}

#[test]
fn binary_operations_agree_with_num_dual() {
    for &(name, exact) in BINARY {
        for (x0, y0) in [(0.37, 1.9), (2.3, -0.8), (-1.7, 0.45), (5.5, 2.0)] {
            if name == "powd" && x0 <= 0.0 {
                continue;
            }
            let x = [x0, y0];
            let tape = tape_derivatives(&x, |v| binary(name, v[0], v[1]));
            let hd = hyper_dual_derivatives(&x, |v| binary(name, v[0], v[1]));
            compare(name, &x, exact, 8.0, tape, hd);
            // The same operand twice: one node with two edges to one parent.
            let x = [x0];
            let tape = tape_derivatives(&x, |v| binary(name, v[0], v[0]));
            let hd = hyper_dual_derivatives(&x, |v| binary(name, v[0], v[0]));
            compare(&format!("{name}(x, x)"), &x, false, 8.0, tape, hd);
        }
    }
}

/// A deterministic generator of points (splitmix64), so that failures
/// reproduce.
struct Points(u64);

impl Points {
    fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        lo + (hi - lo) * ((z >> 11) as f64 / (1u64 << 53) as f64)
    }
}

fn composition<D: DualNum<Primitive = f64> + Copy>(v: &[D]) -> D {
    let [a, b, c] = [v[0], v[1], v[2]];
    (a * b).sin() * c.exp() + (a - c).powi(3) / (b * b + 1.0) - (a * c + 2.0).sqrt() * b.cos()
        + (a + b + c).tanh() % 0.7
}

#[test]
fn random_compositions_agree_with_num_dual() {
    let mut p = Points(12);
    for _ in 0..200 {
        let x: Vec<f64> = (0..3).map(|_| p.uniform(-1.5, 1.5)).collect();
        let tape = tape_derivatives(&x, composition);
        let hd = hyper_dual_derivatives(&x, composition);
        let (v, g, h) = tape;
        let (vw, gw, hw) = hd;
        assert_eq!(v, vw, "the value is the f64 evaluation");
        // Sums of up to a dozen terms in another order: relative to the
        // largest entry, a few ulps each.
        let scale = hw.iter().chain(&gw).fold(0.0f64, |m, x| m.max(x.abs()));
        for (a, b) in g.iter().chain(&h).zip(gw.iter().chain(&hw)) {
            assert!((a - b).abs() <= 16.0 * f64::EPSILON * scale, "{x:?}: {a:e} against {b:e}");
        }
    }
}

/// `Seeds::Along(w)` gives `H·w`: against the dense Hessian times `w`.
#[test]
fn a_weighted_direction_gives_the_hessian_vector_product() {
    let mut p = Points(13);
    for _ in 0..50 {
        let x: Vec<f64> = (0..3).map(|_| p.uniform(-1.5, 1.5)).collect();
        let w: Vec<f64> = (0..3).map(|_| p.uniform(-2.0, 2.0)).collect();
        let (_, _, h) = tape_derivatives(&x, composition);
        let mut tape = Tape::new();
        tape.record(&x, composition).unwrap();
        let (mut g, mut hw) = (vec![0.0; 3], vec![0.0; 3]);
        tape.hessian_product(&Seeds::Along { direction: &w }, &mut g, &mut hw).unwrap();
        let scale = h.iter().fold(0.0f64, |m, x| m.max(x.abs())) * w.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        for i in 0..3 {
            let want: f64 = (0..3).map(|j| h[i * 3 + j] * w[j]).sum();
            assert!((hw[i] - want).abs() <= 32.0 * f64::EPSILON * scale, "{x:?}: {} against {want}", hw[i]);
        }
        assert_eq!(Seeds::Along { direction: &w }.recover(&hw, 0..3, &mut [0.0; 3]), Err(TapeError::NoPattern));
    }
    // A direction of the wrong length is refused.
    let mut tape = Tape::new();
    tape.record(&[0.1, 0.2, 0.3], composition).unwrap();
    let err = tape.hessian_product(&Seeds::Along { direction: &[1.0; 2] }, &mut [0.0; 3], &mut [0.0; 3]);
    assert!(matches!(err, Err(TapeError::Length { .. })), "{err:?}");
}

// ---------------------------------------------------------------------------
// Chains written like a user's Lagrangian, through the `Lagrangian` trait.

/// An FPU-β chain with fixed ends: `Σ ½v² − Σ_{i=0}^{N} (½d² + β/4 d⁴)`,
/// `d = q_{i+1} − q_i` with `q_{−1} = q_N = 0`.
struct Fpu {
    beta: f64,
}

impl<const N: usize> Lagrangian<N> for Fpu {
    const AUTONOMOUS: bool = true;
    const CYCLIC: [bool; N] = [false; N];
    const COUPLING: Coupling = Coupling { q_q: Pattern::banded(N, 1), q_v: Pattern::Diagonal, v_v: Pattern::Diagonal };

    fn lagrangian<D: Scalar>(&self, _t: D, q: [D; N], v: [D; N]) -> D {
        fpu_slices(self.beta, &q, &v)
    }
}

/// The FPU Lagrangian on slices (the form that runs at any `N` without
/// `[D; N]` on the stack).
fn fpu_slices<D: Scalar>(beta: f64, q: &[D], v: &[D]) -> D {
    let n = q.len();
    let mut kinetic = D::zero();
    for i in 0..n {
        kinetic += v[i] * v[i] * 0.5;
    }
    let mut potential = D::zero();
    for i in 0..=n {
        let left = if i == 0 { D::zero() } else { q[i - 1] };
        let right = if i == n { D::zero() } else { q[i] };
        let d = right - left;
        potential += d * d * 0.5 + d.powi(4) * (beta / 4.0);
    }
    kinetic - potential
}

/// A chain of pendula coupled through the velocities: `Σ ½v_i² +
/// κ Σ cos(q_{i+1} − q_i) v_i v_{i+1} + Σ cos q_i` (non-separable, banded).
struct CoupledPendula {
    kappa: f64,
}

impl<const N: usize> Lagrangian<N> for CoupledPendula {
    const AUTONOMOUS: bool = true;
    const CYCLIC: [bool; N] = [false; N];
    const COUPLING: Coupling =
        Coupling { q_q: Pattern::banded(N, 1), q_v: Pattern::banded(N, 1), v_v: Pattern::banded(N, 1) };

    fn lagrangian<D: Scalar>(&self, _t: D, q: [D; N], v: [D; N]) -> D {
        let mut l = D::zero();
        for i in 0..N {
            l += v[i] * v[i] * 0.5 + q[i].cos();
        }
        for i in 0..N - 1 {
            l += (q[i + 1] - q[i]).cos() * v[i] * v[i + 1] * self.kappa;
        }
        l
    }
}

const H: f64 = 0.05;

/// The midpoint discrete Lagrangian `h L((q0 + q1)/2, (q1 − q0)/h)` on any
/// scalar, from the two ends.
fn midpoint<S: Lagrangian<N>, D: Scalar, const N: usize>(system: &S, q0: &[D], q1: &[D]) -> D {
    let q: [D; N] = core::array::from_fn(|i| (q0[i] + q1[i]) * 0.5);
    let v: [D; N] = core::array::from_fn(|i| (q1[i] - q0[i]) / H);
    system.lagrangian(D::zero(), q, v) * H
}

type Block<const N: usize> = HyperDualArray<[f64; N], [f64; N]>;

/// The blocks `∂²L_d/∂q0∂q1` and `∂²L_d/∂q1²` (row-major) from one
/// array hyper-dual evaluation each.
fn dense_blocks<S: Lagrangian<N>, const N: usize>(system: &S, q0: &[f64], q1: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let seeded = |x: &[f64], first: bool, second: bool| -> [Block<N>; N] {
        core::array::from_fn(|i| {
            let mut y = Block::<N>::from_re(x[i]);
            if first {
                y.eps1[i] = 1.0;
            }
            if second {
                y.eps2[i] = 1.0;
            }
            y
        })
    };
    let mixed = midpoint(system, &seeded(q0, true, false), &seeded(q1, false, true));
    let same = midpoint(system, &seeded(q0, false, false), &seeded(q1, true, true));
    let flat = |m: &Block<N>| (0..N * N).map(|k| m.mixed(k / N, k % N)).collect();
    (flat(&mixed), flat(&same))
}

fn check_banded_chain<S: Lagrangian<N>, const N: usize>(name: &str, system: &S, seed: u64) {
    let b = S::COUPLING.overall().bandwidth().unwrap();
    let mut p = Points(seed);
    let x: Vec<f64> = (0..2 * N).map(|_| p.uniform(-0.8, 0.8)).collect();
    let (q0, q1) = x.split_at(N);
    let (mixed, same) = dense_blocks(system, q0, q1);

    let mut tape = Tape::new();
    tape.record(&x, |v| midpoint(system, &v[..N], &v[N..])).unwrap();
    let seeds = Seeds::banded(N..2 * N, b);
    let k = seeds.directions();
    assert_eq!(k, 2 * b + 1);
    let mut g = vec![0.0; 2 * N];
    let mut hs = vec![0.0; 2 * N * k];
    tape.hessian_product(&seeds, &mut g, &mut hs).unwrap();
    let w = 2 * b + 1;
    let mut band = vec![0.0; N * w];
    let scale = mixed.iter().chain(&same).fold(0.0f64, |m, x| m.max(x.abs()));
    for (rows, dense) in [(0..N, &mixed), (N..2 * N, &same)] {
        seeds.recover(&hs, rows.clone(), &mut band).unwrap();
        for r in 0..N {
            for c in 0..N {
                let want = dense[r * N + c];
                if r.abs_diff(c) > b {
                    assert!(want == 0.0, "{name}: the pattern must hold ({r}, {c}) = {want}");
                    continue;
                }
                let got = band[r * w + (c + b - r)];
                // Sums of a handful of terms in another order.
                let ok = (got - want).abs() <= 8.0 * f64::EPSILON * scale;
                assert!(ok, "{name} rows {rows:?}: ({r}, {c}) tape {got:e} against array hyper-dual {want:e}");
            }
        }
        // Band slots outside the block are zero.
        assert_eq!(band[0], 0.0);
        assert_eq!(band[N * w - 1], 0.0);
    }
    // A non-zero coupling off the diagonal, so that the comparison means something.
    assert!(mixed[1] != 0.0 && same[1] != 0.0, "{name}: off-diagonal entries are non-zero");
}

#[test]
fn banded_blocks_of_chains_equal_the_dense_array_hyper_dual_ones() {
    check_banded_chain::<_, 8>("fpu", &Fpu { beta: 1.5 }, 1);
    check_banded_chain::<_, 8>("coupled pendula", &CoupledPendula { kappa: 0.3 }, 2);
}

#[test]
fn dense_recovery_equals_the_array_hyper_dual_blocks() {
    // Chunks of 8 directions: 11 columns take two sweeps.
    const N: usize = 11;
    struct AllPairs;
    impl Lagrangian<N> for AllPairs {
        const AUTONOMOUS: bool = true;
        const CYCLIC: [bool; N] = [false; N];
        fn lagrangian<D: Scalar>(&self, _t: D, q: [D; N], v: [D; N]) -> D {
            let s: D = q.into_iter().sum();
            let w: D = v.into_iter().zip(q).map(|(v, q)| v * q.sin()).sum();
            w * w * 0.5 - s.cos()
        }
    }
    let mut p = Points(3);
    let x: Vec<f64> = (0..2 * N).map(|_| p.uniform(-1.0, 1.0)).collect();
    let (mixed, same) = dense_blocks(&AllPairs, &x[..N], &x[N..]);
    let mut tape = Tape::new();
    tape.record(&x, |v| midpoint(&AllPairs, &v[..N], &v[N..])).unwrap();
    let seeds = Seeds::dense(N..2 * N);
    let mut g = vec![0.0; 2 * N];
    let mut hs = vec![0.0; 2 * N * N];
    tape.hessian_product(&seeds, &mut g, &mut hs).unwrap();
    let mut block = vec![0.0; N * N];
    let scale = mixed.iter().chain(&same).fold(0.0f64, |m, x| m.max(x.abs()));
    for (rows, dense) in [(0..N, &mixed), (N..2 * N, &same)] {
        seeds.recover(&hs, rows, &mut block).unwrap();
        for (k, (a, b)) in block.iter().zip(dense).enumerate() {
            assert!((a - b).abs() <= 16.0 * f64::EPSILON * scale, "({}, {}): {a:e} against {b:e}", k / N, k % N);
        }
    }
}

/// The hand-written gradient and tridiagonal Hessian of the FPU Lagrangian in
/// `q` (the `v` part is `v` and the identity).
fn fpu_by_hand(beta: f64, q: &[f64]) -> (Vec<f64>, Vec<[f64; 3]>) {
    let n = q.len();
    let at = |i: isize| if i < 0 || i as usize >= n { 0.0 } else { q[i as usize] };
    let mut g = vec![0.0; n];
    let mut h = vec![[0.0; 3]; n];
    for i in 0..=n as isize {
        let d = at(i) - at(i - 1);
        let f = d + beta * d * d * d; // ∂V/∂d
        let k = 1.0 + 3.0 * beta * d * d; // ∂²V/∂d²
        // L = T − V, d = q_i − q_{i−1}.
        if i < n as isize {
            g[i as usize] -= f;
            h[i as usize][1] -= k;
        }
        if i > 0 {
            g[i as usize - 1] += f;
            h[i as usize - 1][1] -= k;
        }
        if i > 0 && i < n as isize {
            h[i as usize][0] += k;
            h[i as usize - 1][2] += k;
        }
    }
    (g, h)
}

#[test]
fn a_chain_of_100_000_runs_in_a_default_thread() {
    const N: usize = 100_000;
    let handle = std::thread::Builder::new()
        .stack_size(2 << 20)
        .spawn(|| {
            let beta = 0.7;
            let mut p = Points(9);
            let x: Vec<f64> = (0..2 * N).map(|i| if i < N { p.uniform(-1.0, 1.0) } else { 0.3 }).collect();
            let mut tape = Tape::new();
            tape.record(&x, |v| fpu_slices(beta, &v[..N], &v[N..])).unwrap();
            let mut g = vec![0.0; 2 * N];
            tape.gradient(&mut g).unwrap();
            let seeds = Seeds::banded(0..N, 1);
            let mut hs = vec![0.0; 2 * N * 3];
            let mut g2 = vec![0.0; 2 * N];
            tape.hessian_product(&seeds, &mut g2, &mut hs).unwrap();
            let mut band = vec![0.0; N * 3];
            seeds.recover(&hs, 0..N, &mut band).unwrap();
            let (gw, hw) = fpu_by_hand(beta, &x[..N]);
            for i in 0..N {
                let scale = gw[i].abs().max(1.0);
                assert!((g[i] - gw[i]).abs() <= 8.0 * f64::EPSILON * scale, "g[{i}] {} against {}", g[i], gw[i]);
                assert_eq!(g[i], g2[i]);
                assert_eq!(g[N + i], 0.3, "∂L/∂v = v");
                for s in 0..3 {
                    let (got, want) = (band[3 * i + s], hw[i][s]);
                    assert!((got - want).abs() <= 16.0 * f64::EPSILON * want.abs().max(1.0), "h[{i}][{s}]");
                }
            }
            tape.len()
        })
        .unwrap();
    let nodes = handle.join().expect("no stack overflow, no panic");
    assert!(nodes > 2 * N);
}

// ---------------------------------------------------------------------------
// Misuse and bad input.

#[test]
fn nested_recording_is_an_error_and_the_outer_one_survives() {
    let mut outer = Tape::new();
    let mut inner_result = None;
    let value = outer
        .record(&[2.0], |x| {
            let mut inner = Tape::new();
            inner_result = Some(inner.record(&[1.0], |y| y[0] * y[0]));
            x[0] * x[0] * x[0]
        })
        .unwrap();
    assert_eq!(inner_result, Some(Err(TapeError::Nested)));
    assert_eq!(value, 8.0);
    let mut g = [0.0];
    outer.gradient(&mut g).unwrap();
    assert_eq!(g, [12.0]);
}

#[test]
fn a_var_from_an_earlier_recording_is_detected() {
    let mut tape = Tape::new();
    let mut kept = None;
    tape.record(&[3.0], |x| {
        let y = x[0] * 2.0;
        kept = Some(y);
        y
    })
    .unwrap();
    let stale = kept.unwrap();
    // Used inside an operation.
    assert_eq!(tape.record(&[1.0, 2.0], |x| x[0] * stale + x[1]), Err(TapeError::Stale));
    assert_eq!(tape.value(), None);
    let mut g = [0.0; 2];
    assert_eq!(tape.gradient(&mut g), Err(TapeError::NoRecording));
    // Returned as the result.
    assert_eq!(tape.record(&[1.0], |_| stale), Err(TapeError::Stale));
    // Returned after a constant shift (which records nothing).
    assert_eq!(tape.record(&[1.0], |_| stale + 1.0), Err(TapeError::Stale));
    // And the tape works again afterwards.
    assert_eq!(tape.record(&[1.5], |x| x[0] * x[0]), Ok(2.25));
}

#[test]
fn arithmetic_outside_a_recording_gives_constants() {
    let mut tape = Tape::new();
    let mut kept = None;
    tape.record(&[3.0], |x| {
        kept = Some(x[0]);
        x[0]
    })
    .unwrap();
    let y = kept.unwrap().sin() * 2.0;
    assert!(y.is_constant());
    assert_eq!(y.value(), 3.0f64.sin() * 2.0);
}

#[test]
fn a_panicking_closure_leaves_no_tape_installed() {
    let mut tape = Tape::new();
    let caught = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        let _ = tape.record(&[1.0], |x| -> Var { panic!("user code panics {}", x[0]) });
    }));
    assert!(caught.is_err());
    let mut fresh = Tape::new();
    assert_eq!(fresh.record(&[2.0], |x| x[0].exp()), Ok(2.0f64.exp()));
    assert_eq!(tape.record(&[2.0], |x| x[0] * 3.0), Ok(6.0));
}

#[test]
fn bad_lengths_ranges_and_colours_are_typed_errors() {
    let mut tape = Tape::new();
    let mut g = [0.0; 3];
    assert_eq!(tape.gradient(&mut g), Err(TapeError::NoRecording));
    tape.record(&[1.0, 2.0, 3.0], |x| x[0] * x[1] * x[2]).unwrap();
    assert_eq!(tape.gradient(&mut [0.0; 2]), Err(TapeError::Length { what: "out", got: 2, expected: 3 }));
    let mut hs = vec![0.0; 9];
    let err = tape.hessian_product(&Seeds::dense(1..4), &mut g, &mut hs[..6]);
    assert_eq!(err, Err(TapeError::Range { what: "columns", start: 1, end: 4, inputs: 3 }));
    let err = tape.hessian_product(&Seeds::dense(0..3), &mut g, &mut hs[..6]);
    assert_eq!(err, Err(TapeError::Length { what: "hs", got: 6, expected: 9 }));
    let colour = [Some(0), Some(2), None];
    let err = tape.hessian_product(&Seeds::Colours { colour: &colour, directions: 2 }, &mut g, &mut hs[..6]);
    assert_eq!(err, Err(TapeError::Colour { input: 1, colour: 2, directions: 2 }));
    let err = tape.hessian_product(&Seeds::Colours { colour: &colour[..2], directions: 3 }, &mut g, &mut hs);
    assert_eq!(err, Err(TapeError::Length { what: "colour", got: 2, expected: 3 }));
    tape.hessian_product(&Seeds::Colours { colour: &colour, directions: 3 }, &mut g, &mut hs).unwrap();
    assert_eq!(
        Seeds::Colours { colour: &colour, directions: 3 }.recover(&hs, 0..3, &mut [0.0; 9]),
        Err(TapeError::NoPattern)
    );
    let seeds = Seeds::banded(0..3, 1);
    tape.hessian_product(&seeds, &mut g, &mut hs).unwrap();
    assert_eq!(
        seeds.recover(&hs, 0..4, &mut [0.0; 12]),
        Err(TapeError::Range { what: "rows", start: 0, end: 4, inputs: 3 })
    );
    assert_eq!(seeds.recover(&hs, 0..3, &mut [0.0; 8]), Err(TapeError::Length { what: "out", got: 8, expected: 9 }));
}

#[test]
fn constant_and_input_results() {
    let mut tape = Tape::new();
    // A constant result: zero derivatives.
    assert_eq!(tape.record(&[1.0, 2.0], |_| Var::from(4.0)), Ok(4.0));
    let mut g = [9.0; 2];
    let mut hs = [9.0; 4];
    tape.hessian_product(&Seeds::dense(0..2), &mut g, &mut hs).unwrap();
    assert_eq!((g, hs), ([0.0; 2], [0.0; 4]));
    // An input as the result, before the last input.
    tape.record(&[1.0, 2.0], |x| x[0] + 3.0).unwrap();
    tape.hessian_product(&Seeds::dense(0..2), &mut g, &mut hs).unwrap();
    assert_eq!((g, hs), ([1.0, 0.0], [0.0; 4]));
    // No inputs at all.
    assert_eq!(tape.record(&[], |_| Var::from(1.0).exp()), Ok(1.0f64.exp()));
    tape.gradient(&mut []).unwrap();
}

#[test]
fn the_tape_is_reused_without_growing() {
    let mut tape = Tape::new();
    let x: Vec<f64> = (0..50).map(|i| i as f64 * 0.01).collect();
    let mut g = vec![0.0; 50];
    let mut hs = vec![0.0; 150];
    let seeds = Seeds::banded(0..50, 1);
    let mut run = |tape: &mut Tape| {
        tape.record(&x, |v| fpu_slices(0.5, &v[..25], &v[25..])).unwrap();
        tape.hessian_product(&seeds, &mut g, &mut hs).unwrap();
        tape.memory_bytes()
    };
    let warm = run(&mut tape);
    for _ in 0..5 {
        assert_eq!(run(&mut tape), warm);
    }
}

#[test]
fn var_is_small_and_prints_its_value() {
    assert_eq!(size_of::<Var>(), 16);
    assert_eq!(size_of::<Node>(), 48);
    assert_eq!(Var::from(1.5).to_string(), "1.5");
    let (x, y) = (Var::from(2.0), Var::from(3.0));
    assert_eq!(
        (&x * &y, &x + &y, &x - &y, &x / &y, -&x, x.inv()),
        (6.0.into(), 5.0.into(), (-1.0).into(), (2.0 / 3.0).into(), (-2.0).into(), 0.5.into())
    );
    assert!(Var::zero().is_zero() && Var::from(-2.0).is_negative() && Var::from(-2.0) < 1.0 && Var::from(3.0) == 3.0);
}

/// `input_ranges` follows the operations, not the values: a derivative that
/// vanishes at the recorded point (`x₁·0` through `x₁ − x₁`) still counts,
/// a constant output has no range, and a `Var` of another recording is
/// refused.
#[test]
fn input_ranges_are_structural() {
    let mut tape = Tape::new();
    let mut outputs = [Var::constant(0.0); 4];
    tape.record(&[1.0, 2.0, 3.0, 4.0, 5.0], |x: &[Var]| {
        outputs[0] = x[0] * x[1];
        outputs[1] = (x[3] - x[1]).sin() + (x[2] - x[2]) * x[1];
        outputs[2] = Var::constant(7.0) * 2.0;
        outputs[3] = (x[4] * x[4]).sqrt();
        outputs[0]
    })
    .unwrap();
    let mut ranges = [None; 4];
    tape.input_ranges(&outputs, &mut ranges).unwrap();
    assert_eq!(ranges, [Some((0, 1)), Some((1, 3)), None, Some((4, 4))]);
    let mut other = Tape::new();
    let mut stale = Var::constant(0.0);
    other
        .record(&[1.0], |x: &[Var]| {
            stale = x[0] * 2.0;
            stale
        })
        .unwrap();
    assert_eq!(tape.input_ranges(&[stale], &mut [None]), Err(TapeError::Stale));
}
