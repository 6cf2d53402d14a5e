//! The gradient `∂L/∂q` that `#[lagrangian]` writes out as reverse-mode
//! `f64` code (`Lagrangian::gradient_q`, `HAS_GRADIENT`; with `∂L/∂v`,
//! `gradient_qv`, `HAS_GRADIENT_QV`), checked against
//! the forward-mode dual-number gradient of the same body at random states,
//! on the examples' systems, chains written with `for` loops (also over
//! slices), systems with `self` fields, `powi`, `powf` and most supported
//! methods; which systems get gradient code (and which must not); and the
//! explicit Störmer–Verlet path with and without it. The same code generic
//! over the scalar (`gradient_qv_scalar`): bit for bit the `f64` code at
//! `f64`, and on `Dual64` the Hessian-vector products of hyper-dual
//! evaluations of `L`.
use crate::common::{self, CHARGED, DOUBLE_PENDULUM, PENDULUM};
use lagrangian::num_dual::{Dual64, HyperDual64};
use lagrangian::prelude::*;
use lagrangian::structure::{Coupling, ForceCoupling, Separability};

/// `L = ½|q̇|² + μ/|q|`.
pub struct Kepler {
    pub mu: f64,
}

#[lagrangian]
impl Kepler {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) + self.mu / (q[0] * q[0] + q[1] * q[1]).sqrt()
    }
}

/// `L = ½|q̇|² − ½(x² + y²) − x²y + y³/3`.
pub struct HenonHeiles;

#[lagrangian]
impl HenonHeiles {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let (x, y) = (q[0], q[1]);
        0.5 * (v[0] * v[0] + v[1] * v[1]) - 0.5 * (x * x + y * y) - x * x * y + y * y * y / 3.0
    }
}

/// An FPU-β chain between fixed walls, the bonds in one loop over
/// neighbours (`powi`), the walls outside it.
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
        let (a, b) = (q[0], q[N - 1]);
        let mut potential = 0.5 * (a * a + b * b) + 0.25 * self.beta * (a.powi(4) + b.powi(4));
        for i in 0..N - 1 {
            let d = q[i + 1] - q[i];
            potential += 0.5 * d * d + 0.25 * self.beta * d.powi(4);
        }
        kinetic - potential
    }
}

/// An FPU-β chain with its terms written as products (`0.25 * β * d * d *
/// d * d`, as users write it), which the adjoint stage folds into one rule
/// per distinct factor.
pub struct FpuProducts<const N: usize> {
    pub beta: f64,
}

#[lagrangian]
impl<const N: usize> FpuProducts<N> {
    fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
        let mut kinetic = 0.0;
        for i in 0..N {
            kinetic += 0.5 * v[i] * v[i];
        }
        let (a, b) = (q[0], q[N - 1]);
        let mut potential = 0.5 * (a * a + b * b) + 0.25 * self.beta * (a * a * a * a + b * b * b * b);
        for i in 0..N - 1 {
            let d = q[i + 1] - q[i];
            potential += 0.5 * d * d + 0.25 * self.beta * d * d * d * d;
        }
        kinetic - potential
    }
}

/// Product chains of every shape the folding reads: constants first, last
/// and between active factors, repeated factors among distinct ones
/// (locals, `q[i]` and `v[i]` read directly, sums), divisions by constants,
/// a seventh power, `powi` with a literal exponent among the factors.
pub struct Products {
    pub c: f64,
}

#[lagrangian]
impl Products {
    fn lagrangian(&self, t: f64, q: [f64; 3], v: [f64; 3]) -> f64 {
        let (x, y) = (q[0], q[1]);
        let d = q[2] - q[0];
        let l = 0.5 * v[0] * v[0] + self.c * d * d * d * d + d * d * self.c - x * y * x + d * d / self.c;
        l + q[1] * q[1] * q[1] * 3.0 / 7.0 - x * v[1] * x * v[2] + (x + y) * (x + y) * 2.0
            - x * 0.5 * y * self.c * x * d / 3.0
            + t * q[2] * t
            + (y * y * y * y * y * y * y) / (2.0 * self.c)
            + 0.3 * y.powi(3) * x * y
            - self.c * d.powi(4) * 0.25
    }
}

/// Pendula hanging from a line, neighbours joined by torsion springs:
/// separable, banded, nonlinear in every coordinate.
pub struct CoupledPendula<const N: usize> {
    pub m: f64,
    pub g: f64,
    pub l: f64,
    pub k: f64,
}

#[lagrangian]
impl<const N: usize> CoupledPendula<N> {
    fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
        let ml = self.m * self.l;
        let mut l = 0.0;
        for i in 0..N {
            l += 0.5 * ml * self.l * v[i] * v[i] + ml * self.g * q[i].cos();
        }
        for i in 1..N {
            l -= 0.5 * self.k * (q[i] - q[i - 1]).powi(2);
        }
        l
    }
}

/// Many methods, `self` fields, an integer loop over a constant, a time
/// dependence, velocity–position products and nested loops.
pub struct Zoo {
    pub a: f64,
    pub p: f64,
    pub w: [f64; 3],
}

#[lagrangian]
impl Zoo {
    fn lagrangian(&self, t: f64, q: [f64; 3], v: [f64; 3]) -> f64 {
        let r2 = q[0] * q[0] + q[1] * q[1] + 1.0;
        let mut l = 0.5 * r2 * v[2] * v[2] - self.a * r2.ln() + q[2].exp() * (t * 0.3).sin();
        l += q[0].tanh() * v[0] + q[1].atan2(q[0] + 3.0) - (q[2] * q[2] + 2.0).powf(self.p);
        l -= q[0].mul_add(q[1], 0.5).abs() + (1.5 + q[1]).recip() + q[2].asinh() - q[1].sinh() * q[0].cosh();
        for i in 0..3 {
            let x = self.w[i] * q[i];
            l += x.sin() * x.cbrt() - (2.0 + x.cos()).log(3.0) + x.exp_m1() / (1.0 + x * x).sqrt();
            for j in 0..i {
                l -= (q[i] - q[j]).atan() * (i as f64 + 1.0) + (0.5 * (q[i] + q[j])).tan();
            }
        }
        l + (q[0] * 0.1).asin() + (q[1] * 0.1).acos() + (q[2] * 0.1).atanh() + (2.0 + q[0] * q[0]).acosh()
            - (1.0 + q[1] * q[1]).log2() * (1.0 + q[2] * q[2]).log10()
            + q[0].exp2()
            - (q[1] * 0.2).ln_1p()
    }
}

/// A loop's sum read through a local (`let r = s`) before a use whose
/// derivative reads its value, beside a loop whose sum `L` only adds.
pub struct SumThroughLocal {
    pub c: f64,
}

#[lagrangian]
impl SumThroughLocal {
    fn lagrangian(&self, q: [f64; 3], v: [f64; 3]) -> f64 {
        let mut kinetic = 0.0;
        for i in 0..3 {
            kinetic += 0.5 * v[i] * v[i];
        }
        let mut s = 0.0;
        for i in 0..3 {
            s += q[i] * q[i];
        }
        let r = s;
        let mut potential = 0.0;
        for i in 0..2 {
            let d = q[i + 1] - q[i];
            potential += self.c * d * d;
        }
        kinetic - (1.0 + r).ln() - potential
    }
}

/// The chain of `dyn_lagrangian` over slices, with scratch variables
/// reassigned in the loop (`d = ...`) before they are read.
pub struct DynChain {
    pub n: usize,
    pub beta: f64,
}

#[lagrangian]
impl DynChain {
    fn dimension(&self) -> usize {
        self.n
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        let n = q.len();
        let mut kinetic = 0.0;
        for i in 0..n {
            kinetic += 0.5 * v[i] * v[i];
        }
        let mut d = q[0];
        let mut potential = 0.5 * d * d + 0.25 * self.beta * d.powi(4);
        for i in 0..n - 1 {
            d = q[i + 1] - q[i];
            potential += 0.5 * d * d + 0.25 * self.beta * d.powi(4);
        }
        d = q[n - 1];
        potential += 0.5 * d * d + 0.25 * self.beta * d.powi(4);
        kinetic - potential
    }
}

/// A value carried from one iteration to the next (`left = q[i]`): outside
/// what the adjoint stage transforms, so the dual path stays.
pub struct CarriedChain<const N: usize>;

#[lagrangian]
impl<const N: usize> CarriedChain<N> {
    fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
        let mut l = 0.0;
        let mut left = 0.0;
        for i in 0..N {
            let d = q[i] - left;
            l += 0.5 * v[i] * v[i] - 0.5 * d * d;
            left = q[i];
        }
        l
    }
}

/// A branch on a constant: outside the subset too.
pub struct Switched {
    pub soft: bool,
}

#[lagrangian]
impl Switched {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        let k = if self.soft { 0.5 } else { 2.0 };
        0.5 * v[0] * v[0] - k * q[0] * q[0]
    }
}

/// A small deterministic generator (splitmix64) for the random states.
struct Rng(u64);

impl Rng {
    fn uniform(&mut self, a: f64, b: f64) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        a + (b - a) * ((z >> 11) as f64 / (1u64 << 53) as f64)
    }
}

/// `∂L/∂q` from forward-mode dual numbers, one direction at a time: an
/// independent evaluation of the same body.
fn dual_gradient<S: Lagrangian<N>, const N: usize>(system: &S, t: f64, q: &[f64; N], v: &[f64; N]) -> [f64; N] {
    core::array::from_fn(|i| {
        let qd: [Dual64; N] =
            core::array::from_fn(|j| if i == j { Dual64::new(q[j], 1.0) } else { Dual64::from(q[j]) });
        system.lagrangian(Dual64::from(t), qd, v.map(Dual64::from)).eps
    })
}

/// `∂L/∂v` from forward-mode dual numbers, one direction at a time.
fn dual_velocity_gradient<S: Lagrangian<N>, const N: usize>(
    system: &S,
    t: f64,
    q: &[f64; N],
    v: &[f64; N],
) -> [f64; N] {
    core::array::from_fn(|i| {
        let vd: [Dual64; N] =
            core::array::from_fn(|j| if i == j { Dual64::new(v[j], 1.0) } else { Dual64::from(v[j]) });
        system.lagrangian(Dual64::from(t), q.map(Dual64::from), vd).eps
    })
}

/// The largest relative difference of `gradient_qv`'s two halves from the
/// dual gradients in `q` and in `v`, each against its own largest component
/// (a zero `∂L/∂v` must come out exactly zero).
fn qv_difference<S: Lagrangian<N>, const N: usize>(system: &S, t: f64, q: &[f64; N], v: &[f64; N]) -> f64 {
    let (mut gq, mut gv) = ([f64::NAN; N], [f64::NAN; N]);
    system.gradient_qv(t, q, v, &mut gq, &mut gv);
    let mut worst = 0.0f64;
    for (generated, dual) in [(gq, dual_gradient(system, t, q, v)), (gv, dual_velocity_gradient(system, t, q, v))] {
        let scale = dual.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        for i in 0..N {
            let difference = (generated[i] - dual[i]).abs();
            let difference = if scale > 0.0 { difference / scale } else { difference };
            assert!(difference.is_finite(), "component {i}: {} against {}", generated[i], dual[i]);
            worst = worst.max(difference);
        }
    }
    worst
}

/// The largest relative difference, over `samples` random states in
/// `[lo, hi]ⁿ`, between the generated and the dual gradient, measured
/// against the largest component of the dual one; `gradient_qv` (both
/// halves) checked at the same states.
pub(crate) fn worst_difference<S: Lagrangian<N>, const N: usize>(system: &S, lo: f64, hi: f64, samples: usize) -> f64 {
    assert!(S::HAS_GRADIENT, "no gradient code was generated");
    assert!(S::HAS_GRADIENT_QV, "no gradient code in (q, v) was generated");
    let mut rng = Rng(0x5eed ^ N as u64);
    let mut worst = 0.0f64;
    for _ in 0..samples {
        let t = rng.uniform(-3.0, 3.0);
        let q: [f64; N] = core::array::from_fn(|_| rng.uniform(lo, hi));
        let v: [f64; N] = core::array::from_fn(|_| rng.uniform(-2.0, 2.0));
        let mut generated = [f64::NAN; N];
        system.gradient_q(t, &q, &v, &mut generated);
        check_value(system, t, &q, &v, &generated);
        let dual = dual_gradient(system, t, &q, &v);
        let scale = dual.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        assert!(scale.is_finite() && scale > 0.0, "a degenerate sample: {dual:?}");
        for i in 0..N {
            let difference = (generated[i] - dual[i]).abs() / scale;
            assert!(difference.is_finite(), "component {i}: {} against {}", generated[i], dual[i]);
            worst = worst.max(difference);
        }
        worst = worst.max(qv_difference(system, t, &q, &v));
    }
    worst
}

/// How far `value_gradient_q`'s value may be from `L`, relative to
/// `max(|L|, 1)`: its forward sweep performs the body's operations in the
/// body's order, so a few ulps at most (a constant moved to the other side
/// of `+` or `*` is exact).
const VALUE_TOLERANCE: f64 = 1e-14;

/// `value_gradient_q` against `gradient_q` (`gradient`: the same bits) and
/// `L` (within [`VALUE_TOLERANCE`]); `add_gradient_q_at_rest` against
/// both at `v = 0` (see [`check_added`]).
fn check_value<S: Lagrangian<N>, const N: usize>(system: &S, t: f64, q: &[f64; N], v: &[f64; N], gradient: &[f64; N]) {
    let mut out = [f64::NAN; N];
    let value = system.value_gradient_q(t, q, v, &mut out);
    assert_eq!(out.map(f64::to_bits), gradient.map(f64::to_bits), "value_gradient_q's gradient is gradient_q's");
    let l = system.lagrangian(t, *q, *v);
    let difference = (value - l).abs() / l.abs().max(1.0);
    assert!(difference <= VALUE_TOLERANCE, "value {value} against L = {l}");
    let mut at_rest = [f64::NAN; N];
    let value_at_rest = system.value_gradient_q(t, q, &[0.0; N], &mut at_rest);
    let mut added = [0.0; N];
    let finite = system.add_gradient_q_at_rest(t, q, &mut added);
    let mut onto = core::array::from_fn(|i| 1.0 + i as f64);
    system.add_gradient_q_at_rest(t, q, &mut onto);
    check_added(&added, &onto, &at_rest, finite, value_at_rest);
}

/// `add_gradient_q_at_rest` added to zeros (`added`): the gradient's values
/// at `v = 0` (the same additions to a cleared `out`; a first term assigned
/// instead can differ only in the sign of a zero); added to `1 + i`
/// (`onto`): that plus the gradient up to the round-off of the few
/// additions of its terms (within [`TOLERANCE`] of the sum and the largest
/// component); its finiteness that of `value`, the value of `L` at `v = 0`
/// computed in order.
fn check_added(added: &[f64], onto: &[f64], gradient: &[f64], finite: bool, value: f64) {
    for (i, (&a, &g)) in added.iter().zip(gradient).enumerate() {
        assert!(a == g || (a.is_nan() && g.is_nan()), "{i}: {a} onto zero against the gradient {g}");
    }
    let scale = gradient.iter().fold(0.0f64, |m, g| m.max(g.abs()));
    for (i, (&x, &g)) in onto.iter().zip(gradient).enumerate() {
        let expected = 1.0 + i as f64 + g;
        let close = (x - expected).abs() <= TOLERANCE * (expected.abs() + scale);
        assert!(close || (x.is_nan() && g.is_nan()), "{i}: {x} against {expected}");
    }
    assert_eq!(finite, value.is_finite(), "finite: {finite}, value {value}");
}

/// Sums in a different order than the dual path round differently: a few
/// ulps of the largest component.
const TOLERANCE: f64 = 1e-14;

#[test]
fn generated_gradients_agree_with_dual_numbers_at_random_states() {
    let cases: Vec<(&str, f64)> = vec![
        ("pendulum", worst_difference(&PENDULUM, -3.0, 3.0, 200)),
        ("double pendulum", worst_difference(&DOUBLE_PENDULUM, -3.0, 3.0, 200)),
        ("oscillator", worst_difference(&common::Oscillator { m: 1.5, k: 2.5 }, -3.0, 3.0, 200)),
        ("Kepler (polar)", worst_difference(&common::KeplerPolar { mu: 1.3 }, 0.5, 3.0, 200)),
        ("Kepler (Cartesian)", worst_difference(&Kepler { mu: 1.3 }, 0.2, 3.0, 200)),
        ("Hénon–Heiles", worst_difference(&HenonHeiles, -1.0, 1.0, 200)),
        ("charged particle", worst_difference(&CHARGED, -2.0, 2.0, 200)),
        ("slow oscillator (t)", worst_difference(&common::SlowOscillator { eps: 0.1 }, -3.0, 3.0, 200)),
        ("FPU-β N = 16", worst_difference(&Fpu::<16> { beta: 1.0 }, -1.0, 1.0, 50)),
        ("FPU-β N = 2", worst_difference(&Fpu::<2> { beta: 0.7 }, -1.0, 1.0, 50)),
        (
            "coupled pendula N = 12",
            worst_difference(&CoupledPendula::<12> { m: 1.1, g: 9.81, l: 0.7, k: 3.0 }, -2.0, 2.0, 50),
        ),
        ("method zoo", worst_difference(&Zoo { a: 0.7, p: 1.7, w: [0.3, -1.2, 0.8] }, -1.0, 1.0, 300)),
        ("a sum read through a local", worst_difference(&SumThroughLocal { c: 0.8 }, -1.5, 1.5, 200)),
    ];
    for (name, worst) in &cases {
        println!("{name}: largest relative difference {worst:.1e}");
    }
    for (name, worst) in cases {
        assert!(worst <= TOLERANCE, "{name}: generated and dual gradients differ by {worst:e}");
    }
}

/// Folded product chains (`c * d * d * d * d`, `d * d * c`, `x * y * x`,
/// `d * d / c`) round the derivative differently from the dual path's
/// product rule by a few ulps of the gradient's magnitude.
const PRODUCT_TOLERANCE: f64 = 8.0 * f64::EPSILON;

#[test]
fn folded_product_chains_agree_with_dual_numbers_to_a_few_ulps() {
    let cases: Vec<(&str, f64)> = vec![
        ("products", worst_difference(&Products { c: 1.3 }, -1.5, 1.5, 500)),
        ("products, c < 0", worst_difference(&Products { c: -0.45 }, -1.5, 1.5, 500)),
        ("FPU-β N = 16 as products", worst_difference(&FpuProducts::<16> { beta: 1.0 }, -1.0, 1.0, 100)),
        ("FPU-β N = 3 as products", worst_difference(&FpuProducts::<3> { beta: 0.7 }, -1.0, 1.0, 100)),
    ];
    for (name, worst) in &cases {
        println!("{name}: largest relative difference {worst:.1e}");
    }
    for (name, worst) in cases {
        assert!(worst <= PRODUCT_TOLERANCE, "{name}: generated and dual gradients differ by {worst:e}");
    }
}

/// `HAS_GRADIENT` of a const-size system (and `HAS_GRADIENT_QV`, which
/// the macro sets with it for a system of known size).
fn has_gradient<S: Lagrangian<N>, const N: usize>() -> bool {
    assert_eq!(S::HAS_GRADIENT, S::HAS_GRADIENT_QV);
    S::HAS_GRADIENT
}

#[test]
fn the_macro_says_which_systems_got_gradient_code() {
    let systems = [
        ("pendulum", has_gradient::<common::Pendulum, 1>(), true),
        ("FPU-β", has_gradient::<Fpu<16>, 16>(), true),
        ("FPU-β as products", has_gradient::<FpuProducts<16>, 16>(), true),
        ("products", has_gradient::<Products, 3>(), true),
        ("coupled pendula", has_gradient::<CoupledPendula<4>, 4>(), true),
        ("method zoo", has_gradient::<Zoo, 3>(), true),
        ("run-time-sized chain", <DynChain as DynLagrangian>::HAS_GRADIENT, true),
        // A borrowed system forwards it.
        ("&Kepler", has_gradient::<&Kepler, 2>(), true),
        // Outside the subset: no gradient code, the dual path stays.
        ("value carried across iterations", has_gradient::<CarriedChain<4>, 4>(), false),
        ("branch", has_gradient::<Switched, 1>(), false),
    ];
    for (name, got, expected) in systems {
        println!("{name}: gradient code {got}");
        assert_eq!(got, expected, "{name}");
    }
    // The default `gradient_q` evaluates dual numbers, one direction at a time.
    let (q, v) = ([0.3, -0.2, 0.9, 0.1], [0.5, 0.1, -0.4, 0.2]);
    let mut out = [0.0; 4];
    CarriedChain::<4>.gradient_q(0.0, &q, &v, &mut out);
    assert_eq!(out, dual_gradient(&CarriedChain::<4>, 0.0, &q, &v));
    // So does the default `gradient_qv`.
    let mut out_v = [0.0; 4];
    CarriedChain::<4>.gradient_qv(0.0, &q, &v, &mut out, &mut out_v);
    assert_eq!(out, dual_gradient(&CarriedChain::<4>, 0.0, &q, &v));
    assert_eq!(out_v, dual_velocity_gradient(&CarriedChain::<4>, 0.0, &q, &v));
}

#[test]
fn the_run_time_sized_chain_agrees_with_its_tape_gradient() {
    let chain = DynChain { n: 40, beta: 0.8 };
    let mut rng = Rng(7);
    let mut worst = 0.0f64;
    for _ in 0..20 {
        let q: Vec<f64> = (0..40).map(|_| rng.uniform(-1.0, 1.0)).collect();
        let v: Vec<f64> = (0..40).map(|_| rng.uniform(-1.0, 1.0)).collect();
        let mut generated = vec![f64::NAN; 40];
        chain.gradient_q(0.0, &q, &v, &mut generated);
        // With the value: the same gradient, and `L`.
        let mut valued = vec![f64::NAN; 40];
        let value = chain.value_gradient_q(0.0, &q, &v, &mut valued);
        assert_eq!(valued, generated);
        let l = DynLagrangian::lagrangian(&chain, 0.0, &q, &v);
        assert!((value - l).abs() <= VALUE_TOLERANCE * l.abs().max(1.0), "value {value} against L = {l}");
        // At rest, added: the gradient at `v = 0` and the finiteness of its value.
        let mut at_rest = vec![f64::NAN; 40];
        let value_at_rest = chain.value_gradient_q(0.0, &q, &[0.0; 40], &mut at_rest);
        let mut added = vec![0.0; 40];
        let finite = chain.add_gradient_q_at_rest(0.0, &q, &mut added);
        let mut onto: Vec<f64> = (0..40).map(|i| 1.0 + i as f64).collect();
        chain.add_gradient_q_at_rest(0.0, &q, &mut onto);
        check_added(&added, &onto, &at_rest, finite, value_at_rest);
        // Forward-mode duals, one direction at a time.
        let vd: Vec<Dual64> = v.iter().map(|&x| Dual64::from(x)).collect();
        let scale = generated.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        for i in 0..40 {
            let qd: Vec<Dual64> =
                (0..40).map(|j| if i == j { Dual64::new(q[j], 1.0) } else { Dual64::from(q[j]) }).collect();
            let dual = DynLagrangian::lagrangian(&chain, Dual64::from(0.0), &qd, &vd).eps;
            worst = worst.max((generated[i] - dual).abs() / scale);
        }
    }
    println!("run-time-sized FPU-β N = 40: largest relative difference {worst:.1e}");
    assert!(worst <= TOLERANCE, "generated and dual gradients differ by {worst:e}");
}

/// The system with its generated gradient hidden: the explicit path then
/// takes the dual one (the structure constants are kept).
struct DualOnly<S>(S);

impl<S: Lagrangian<N>, const N: usize> Lagrangian<N> for DualOnly<S> {
    const AUTONOMOUS: bool = S::AUTONOMOUS;
    const CYCLIC: [bool; N] = S::CYCLIC;
    const SEPARABILITY: Separability = S::SEPARABILITY;
    const COUPLING: Coupling = S::COUPLING;
    const FORCE_COUPLING: ForceCoupling = S::FORCE_COUPLING;
    fn lagrangian<D: Scalar>(&self, t: D, q: [D; N], v: [D; N]) -> D {
        self.0.lagrangian(t, q, v)
    }
}

/// Largest difference of `q` and `p` over `n` explicit trapezoid steps with
/// the generated and with the dual gradient.
fn compare<S: Lagrangian<N>, const N: usize>(system: impl Fn() -> S, q0: [f64; N], h: f64, n: usize) -> f64 {
    assert!(S::HAS_GRADIENT && S::SEPARABILITY == Separability::ConstantMass);
    let mut generated = Integrator::new(system(), Trapezoid, h).start(0.0, q0, [0.0; N]).unwrap();
    let mut dual = Integrator::new(DualOnly(system()), Trapezoid, h).start(0.0, q0, [0.0; N]).unwrap();
    let mut worst = 0.0f64;
    for _ in 0..n {
        generated.step().unwrap();
        dual.step().unwrap();
        for i in 0..N {
            worst = worst.max((generated.state().q[i] - dual.state().q[i]).abs());
            worst = worst.max((generated.state().p[i] - dual.state().p[i]).abs());
        }
    }
    assert_eq!(generated.stats().newton_iterations + dual.stats().newton_iterations, 0);
    worst
}

#[test]
fn explicit_trajectories_with_and_without_gradient_code_agree_to_round_off() {
    // The two gradients differ by an ulp here and there; on the pendulum the
    // phase error this seeds grows linearly (as between the explicit and the
    // Newton paths), hence 1e-13 after 1e4 steps.
    let pendulum = compare(|| PENDULUM, [1.0], 0.01, 10_000);
    let q0: [f64; 16] = core::array::from_fn(|i| 0.3 * ((i + 1) as f64 * std::f64::consts::PI / 17.0).sin());
    let fpu = compare(|| Fpu::<16> { beta: 1.0 }, q0, 0.05, 10_000);
    println!("1e4 explicit steps, generated against dual gradient: pendulum {pendulum:.1e}, FPU-β N = 16 {fpu:.1e}");
    assert!(pendulum < 1e-13, "pendulum: {pendulum:e}");
    assert!(fpu < 1e-13, "FPU-β: {fpu:e}");
}

/// `∇²L·(δq, δv)` in its `q` and `v` halves from hyper-dual numbers: `ε₁`
/// on one coordinate, `ε₂` along the direction, `N` evaluations per half.
fn hyperdual_products<S: Lagrangian<N>, const N: usize>(
    system: &S,
    t: f64,
    (q, v): (&[f64; N], &[f64; N]),
    (dq, dv): (&[f64; N], &[f64; N]),
) -> ([f64; N], [f64; N]) {
    let seeded = |x: &[f64; N], d: &[f64; N], one: Option<usize>| -> [HyperDual64; N] {
        core::array::from_fn(|j| HyperDual64::new(x[j], if one == Some(j) { 1.0 } else { 0.0 }, d[j], 0.0))
    };
    let t = HyperDual64::from(t);
    let in_q = core::array::from_fn(|i| system.lagrangian(t, seeded(q, dq, Some(i)), seeded(v, dv, None)).eps1eps2);
    let in_v = core::array::from_fn(|i| system.lagrangian(t, seeded(q, dq, None), seeded(v, dv, Some(i))).eps1eps2);
    (in_q, in_v)
}

/// Over `samples` random states and directions: `gradient_qv_scalar` at
/// `f64` must equal `gradient_qv` bit for bit; at `Dual64` its real parts
/// must be the gradient and its derivative parts the Hessian-vector
/// products. Returns the largest relative difference of the products from
/// the hyper-dual ones (each half against its own largest component).
pub(crate) fn scalar_difference<S: Lagrangian<N>, const N: usize>(system: &S, lo: f64, hi: f64, samples: usize) -> f64 {
    assert!(S::HAS_GRADIENT_QV, "no generic gradient code was generated");
    let mut rng = Rng(0xd0a1 ^ N as u64);
    let mut worst = 0.0f64;
    for _ in 0..samples {
        let t = rng.uniform(-3.0, 3.0);
        let q: [f64; N] = core::array::from_fn(|_| rng.uniform(lo, hi));
        let v: [f64; N] = core::array::from_fn(|_| rng.uniform(-2.0, 2.0));
        let dq: [f64; N] = core::array::from_fn(|_| rng.uniform(-1.0, 1.0));
        let dv: [f64; N] = core::array::from_fn(|_| rng.uniform(-1.0, 1.0));
        let (mut gq, mut gv) = ([f64::NAN; N], [f64::NAN; N]);
        system.gradient_qv(t, &q, &v, &mut gq, &mut gv);
        let (mut sq, mut sv) = ([f64::NAN; N], [f64::NAN; N]);
        system.gradient_qv_scalar(t, &q, &v, &mut sq, &mut sv);
        for i in 0..N {
            assert_eq!(sq[i].to_bits(), gq[i].to_bits(), "∂L/∂q[{i}] at f64: {} against {}", sq[i], gq[i]);
            assert_eq!(sv[i].to_bits(), gv[i].to_bits(), "∂L/∂v[{i}] at f64: {} against {}", sv[i], gv[i]);
        }
        let qd: [Dual64; N] = core::array::from_fn(|i| Dual64::new(q[i], dq[i]));
        let vd: [Dual64; N] = core::array::from_fn(|i| Dual64::new(v[i], dv[i]));
        let (mut hq, mut hv) = ([Dual64::from(f64::NAN); N], [Dual64::from(f64::NAN); N]);
        system.gradient_qv_scalar(Dual64::from(t), &qd, &vd, &mut hq, &mut hv);
        let (rq, rv) = hyperdual_products(system, t, (&q, &v), (&dq, &dv));
        for (dual, gradient, reference) in [(&hq, &gq, &rq), (&hv, &gv, &rv)] {
            let scale = |x: &mut dyn Iterator<Item = f64>| x.fold(0.0f64, |m, x| m.max(x.abs()));
            let (g_scale, h_scale) = (scale(&mut gradient.iter().copied()), scale(&mut reference.iter().copied()));
            for i in 0..N {
                let re = (dual[i].re - gradient[i]).abs();
                assert!(
                    re <= 1e-14 * g_scale.max(f64::MIN_POSITIVE),
                    "real part {i}: {} against {}",
                    dual[i].re,
                    gradient[i]
                );
                let difference = (dual[i].eps - reference[i]).abs();
                let difference = if h_scale > 0.0 { difference / h_scale } else { difference };
                assert!(difference.is_finite(), "product {i}: {} against {}", dual[i].eps, reference[i]);
                worst = worst.max(difference);
            }
        }
    }
    worst
}

#[test]
fn the_generic_gradient_gives_hessian_vector_products_on_dual_numbers() {
    let cases: Vec<(&str, f64)> = vec![
        ("pendulum", scalar_difference(&PENDULUM, -3.0, 3.0, 100)),
        ("double pendulum", scalar_difference(&DOUBLE_PENDULUM, -3.0, 3.0, 100)),
        ("oscillator", scalar_difference(&common::Oscillator { m: 1.5, k: 2.5 }, -3.0, 3.0, 100)),
        ("Kepler (polar)", scalar_difference(&common::KeplerPolar { mu: 1.3 }, 0.5, 3.0, 100)),
        ("Kepler (Cartesian)", scalar_difference(&Kepler { mu: 1.3 }, 0.2, 3.0, 100)),
        ("Hénon–Heiles", scalar_difference(&HenonHeiles, -1.0, 1.0, 100)),
        ("charged particle", scalar_difference(&CHARGED, -2.0, 2.0, 100)),
        ("slow oscillator (t)", scalar_difference(&common::SlowOscillator { eps: 0.1 }, -3.0, 3.0, 100)),
        ("FPU-β N = 16", scalar_difference(&Fpu::<16> { beta: 1.0 }, -1.0, 1.0, 30)),
        ("FPU-β N = 2", scalar_difference(&Fpu::<2> { beta: 0.7 }, -1.0, 1.0, 30)),
        (
            "coupled pendula N = 12",
            scalar_difference(&CoupledPendula::<12> { m: 1.1, g: 9.81, l: 0.7, k: 3.0 }, -2.0, 2.0, 30),
        ),
        ("method zoo", scalar_difference(&Zoo { a: 0.7, p: 1.7, w: [0.3, -1.2, 0.8] }, -1.0, 1.0, 200)),
        ("products", scalar_difference(&Products { c: 1.3 }, -1.5, 1.5, 200)),
        ("FPU-β N = 16 as products", scalar_difference(&FpuProducts::<16> { beta: 1.0 }, -1.0, 1.0, 30)),
    ];
    for (name, worst) in &cases {
        println!("{name}: Hessian-vector products, largest relative difference {worst:.1e}");
    }
    for (name, worst) in cases {
        assert!(worst <= TOLERANCE, "{name}: dual and hyper-dual products differ by {worst:e}");
    }
}

#[test]
fn the_generic_gradient_of_a_run_time_sized_chain_gives_hessian_vector_products() {
    let n = 40;
    let chain = DynChain { n, beta: 0.8 };
    const { assert!(<DynChain as DynLagrangian>::HAS_GRADIENT_QV) };
    let mut rng = Rng(11);
    let mut worst = 0.0f64;
    for _ in 0..10 {
        let draw = |rng: &mut Rng| -> Vec<f64> { (0..n).map(|_| rng.uniform(-1.0, 1.0)).collect() };
        let (q, v, dq, dv) = (draw(&mut rng), draw(&mut rng), draw(&mut rng), draw(&mut rng));
        // At `f64`: the `f64` gradient in `q`, to round-off (the two
        // transformations may accumulate in different orders).
        let (mut sq, mut sv) = (vec![f64::NAN; n], vec![f64::NAN; n]);
        chain.gradient_qv_scalar(0.0, &q, &v, &mut sq, &mut sv);
        let mut gq = vec![f64::NAN; n];
        chain.gradient_q(0.0, &q, &v, &mut gq);
        let g_scale = gq.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        for i in 0..n {
            assert!((sq[i] - gq[i]).abs() <= 1e-14 * g_scale, "∂L/∂q[{i}]: {} against {}", sq[i], gq[i]);
            assert_eq!(sv[i], v[i], "∂L/∂v[{i}] of ½v²");
        }
        let qd: Vec<Dual64> = (0..n).map(|i| Dual64::new(q[i], dq[i])).collect();
        let vd: Vec<Dual64> = (0..n).map(|i| Dual64::new(v[i], dv[i])).collect();
        let (mut hq, mut hv) = (vec![Dual64::from(f64::NAN); n], vec![Dual64::from(f64::NAN); n]);
        chain.gradient_qv_scalar(Dual64::from(0.0), &qd, &vd, &mut hq, &mut hv);
        let seeded = |x: &[f64], d: &[f64], one: Option<usize>| -> Vec<HyperDual64> {
            (0..n).map(|j| HyperDual64::new(x[j], if one == Some(j) { 1.0 } else { 0.0 }, d[j], 0.0)).collect()
        };
        let t = HyperDual64::from(0.0);
        let rq: Vec<f64> = (0..n)
            .map(|i| DynLagrangian::lagrangian(&chain, t, &seeded(&q, &dq, Some(i)), &seeded(&v, &dv, None)).eps1eps2)
            .collect();
        let rv: Vec<f64> = (0..n)
            .map(|i| DynLagrangian::lagrangian(&chain, t, &seeded(&q, &dq, None), &seeded(&v, &dv, Some(i))).eps1eps2)
            .collect();
        for (dual, reference) in [(&hq, &rq), (&hv, &rv)] {
            let scale = reference.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            for i in 0..n {
                worst = worst.max((dual[i].eps - reference[i]).abs() / scale);
            }
        }
        // `∂²(½v²)/∂v² · δv = δv` exactly.
        assert!((0..n).all(|i| hv[i].eps == dv[i]));
    }
    println!("run-time-sized FPU-β N = 40: Hessian-vector products, largest relative difference {worst:.1e}");
    assert!(worst <= TOLERANCE, "dual and hyper-dual products differ by {worst:e}");
}

/// The default `gradient_qv_scalar` (dual numbers over the scalar) of a
/// system without gradient code agrees with the generated one of the same
/// body written inside the subset.
#[test]
fn the_default_generic_gradient_is_correct_too() {
    let (q, v) = ([0.3, -0.2, 0.9, 0.1], [0.5, 0.1, -0.4, 0.2]);
    const { assert!(!<CarriedChain<4> as Lagrangian<4>>::HAS_GRADIENT_QV) };
    let qd: [Dual64; 4] = core::array::from_fn(|i| Dual64::new(q[i], 0.1 * i as f64 - 0.2));
    let vd: [Dual64; 4] = core::array::from_fn(|i| Dual64::new(v[i], 0.3 - 0.05 * i as f64));
    let (mut hq, mut hv) = ([Dual64::from(0.0); 4], [Dual64::from(0.0); 4]);
    CarriedChain::<4>.gradient_qv_scalar(Dual64::from(0.0), &qd, &vd, &mut hq, &mut hv);
    let dq: [f64; 4] = core::array::from_fn(|i| qd[i].eps);
    let dv: [f64; 4] = core::array::from_fn(|i| vd[i].eps);
    let (rq, rv) = hyperdual_products(&CarriedChain::<4>, 0.0, (&q, &v), (&dq, &dv));
    for i in 0..4 {
        assert!((hq[i].eps - rq[i]).abs() <= 1e-14, "{i}: {} against {}", hq[i].eps, rq[i]);
        assert!((hv[i].eps - rv[i]).abs() <= 1e-14, "{i}: {} against {}", hv[i].eps, rv[i]);
    }
}

/// `∂²L/∂v²` as `DiscreteMechanics::velocity_hessian` takes it for systems
/// with gradient code (forward over the generated reverse code, one lane per
/// velocity) against hyper-dual evaluations of the body, one pair of
/// directions at a time, at random states: the largest difference relative
/// to the largest entry. Position-dependent masses included (double
/// pendulum, charged particle, coupled pendula), and the momentum
/// `DiscreteMechanics::momentum` against dual numbers at the same states.
fn worst_hessian_difference<S: Lagrangian<N>, const N: usize>(system: &S, lo: f64, hi: f64, samples: usize) -> f64 {
    assert!(S::HAS_GRADIENT_QV, "no gradient code in (q, v) was generated");
    let mut rng = Rng(0xc0ffee ^ N as u64);
    let mut worst = 0.0f64;
    for _ in 0..samples {
        let t = rng.uniform(-3.0, 3.0);
        let q: [f64; N] = core::array::from_fn(|_| rng.uniform(lo, hi));
        let v: [f64; N] = core::array::from_fn(|_| rng.uniform(-2.0, 2.0));
        let m = system.velocity_hessian(t, q, v);
        let reference: Vec<f64> = (0..N * N)
            .map(|ij| {
                let (i, j) = (ij / N, ij % N);
                let vd: [HyperDual64; N] = core::array::from_fn(|k| {
                    HyperDual64::new(v[k], f64::from(u8::from(k == i)), f64::from(u8::from(k == j)), 0.0)
                });
                system.lagrangian(HyperDual64::from(t), q.map(HyperDual64::from), vd).eps1eps2
            })
            .collect();
        let scale = reference.iter().fold(0.0f64, |s, x| s.max(x.abs()));
        assert!(scale.is_finite() && scale > 0.0, "a degenerate sample: {reference:?}");
        for ij in 0..N * N {
            let difference = (m[(ij / N, ij % N)] - reference[ij]).abs() / scale;
            assert!(difference.is_finite(), "entry {ij}: {} against {}", m[(ij / N, ij % N)], reference[ij]);
            worst = worst.max(difference);
        }
        let (p, dual) = (system.momentum(t, q, v), dual_velocity_gradient(system, t, &q, &v));
        let p_scale = dual.iter().fold(0.0f64, |s, x| s.max(x.abs())).max(f64::MIN_POSITIVE);
        for i in 0..N {
            worst = worst.max((p[i] - dual[i]).abs() / p_scale);
        }
    }
    worst
}

#[test]
fn velocity_hessians_from_gradient_code_agree_with_hyper_dual_numbers() {
    let cases: Vec<(&str, f64)> = vec![
        ("pendulum", worst_hessian_difference(&PENDULUM, -3.0, 3.0, 50)),
        ("double pendulum", worst_hessian_difference(&DOUBLE_PENDULUM, -3.0, 3.0, 50)),
        ("charged particle", worst_hessian_difference(&CHARGED, -2.0, 2.0, 50)),
        ("Kepler (Cartesian)", worst_hessian_difference(&Kepler { mu: 1.3 }, 0.2, 3.0, 50)),
        ("FPU-β N = 16", worst_hessian_difference(&Fpu::<16> { beta: 1.0 }, -1.0, 1.0, 10)),
        (
            "coupled pendula N = 12",
            worst_hessian_difference(&CoupledPendula::<12> { m: 1.1, g: 9.81, l: 0.7, k: 3.0 }, -2.0, 2.0, 10),
        ),
    ];
    for (name, worst) in &cases {
        println!("{name}: {worst:.1e}");
        assert!(*worst <= TOLERANCE, "{name}: {worst:e}");
    }
}
