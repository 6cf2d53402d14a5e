//! Every operation of the array duals against num-dual's scalar `Dual64` and
//! `HyperDual64` applied to the same function: component `(i, j)` of one array
//! evaluation must be the scalar evaluation seeded with the `i`-th and `j`-th parts.
#![allow(clippy::op_ref)] // the reference forms of the operators are under test

use num_dual::{BesselDual, Dual64, DualNum, HyperDual64};
use num_traits::{FromPrimitive, Inv, Num, One, Signed, Zero};

use super::*;

type Hd = HyperDualArray<[f64; 2], [f64; 3]>;
type HdTimed = HyperDualArray<Timed<f64, 2>, Timed<f64, 1>>;
type Da = DualArray<[f64; 3]>;

/// The unary operations under test, by index, on any scalar.
const UNARY: &[&str] = &[
    "recip",
    "powi0",
    "powi1",
    "powi2",
    "powi3",
    "powi-2",
    "powi7",
    "powf0",
    "powf1",
    "powf2",
    "powf0.5",
    "powf-1.5",
    "powf3.7",
    "sqrt",
    "cbrt",
    "exp",
    "exp2",
    "exp_m1",
    "ln",
    "log3",
    "log2",
    "log10",
    "ln_1p",
    "sin",
    "cos",
    "tan",
    "sin_cos.0",
    "sin_cos.1",
    "asin",
    "acos",
    "atan",
    "sinh",
    "cosh",
    "tanh",
    "asinh",
    "acosh",
    "atanh",
    "sph_j0",
    "sph_j1",
    "sph_j2",
    "bessel_j0",
    "bessel_j1",
    "bessel_j2",
    "abs",
    "signum",
    "neg",
    "inv",
    "scale",
    "mul_add_self",
    "powd_self",
    "add_f64",
    "sub_f64",
    "mul_f64",
    "div_f64",
    "add_assign_f64",
    "sub_assign_f64",
    "mul_assign_f64",
    "div_assign_f64",
    "square",
    "quotient_self",
    "sum",
    "product",
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
        "square" => x * x,
        "quotient_self" => (x + 2.0) / x,
        "sum" => [x, x * 2.0, x.sin()].into_iter().sum::<D>(),
        "product" => [x, x * 2.0, x.sin()].into_iter().product::<D>(),
        _ => unreachable!("{name}"),
    }
}

const BINARY: &[&str] =
    &["add", "sub", "mul", "div", "atan2", "powd", "mul_add", "add_ref", "sub_ref", "div_assign", "abs_sub"];

fn binary<D: DualNum<Primitive = f64, InnerDual = f64> + Copy>(name: &str, x: D, y: D) -> D {
    match name {
        "add" => x + y,
        "sub" => x - y,
        "mul" => x * y,
        "div" => x / y,
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
        "abs_sub" => x.abs_sub(&y) + y.abs_sub(&x),
        _ => unreachable!("{name}"),
    }
}

/// `|a − b| ≤ 1e-15 · max(|a|, |b|)`, or both NaN. (Every comparison in this
/// file is in fact exact: the formulas and operation order are num-dual's.)
fn close(a: f64, b: f64) -> bool {
    (a.is_nan() && b.is_nan()) || a == b || (a - b).abs() <= 1e-15 * a.abs().max(b.abs())
}

/// A hyper-dual with every part non-zero, and its scalar slices.
fn hd(re: f64, k: f64) -> Hd {
    Hd::new(re, [0.3 * k, -1.1], [0.7, 0.2 * k, -0.5], [[0.13, -0.4 * k, 0.25], [0.9, 0.05, -0.6 * k]])
}

fn slice(x: &Hd, i: usize, j: usize) -> HyperDual64 {
    HyperDual64::new(x.re, x.eps1[i], x.eps2[j], x.eps1eps2[i][j])
}

fn check_hd(what: &str, got: &Hd, want: impl Fn(usize, usize) -> HyperDual64) {
    for i in 0..2 {
        for j in 0..3 {
            let w = want(i, j);
            let ok = close(got.re, w.re)
                && close(got.eps1[i], w.eps1)
                && close(got.eps2[j], w.eps2)
                && close(got.eps1eps2[i][j], w.eps1eps2);
            assert!(ok, "{what} ({i}, {j}): got {got}, want {w}");
        }
    }
}

/// Points inside every function's domain (|x| < 1 for asin, acos, atanh), one
/// near zero for the series branches of the spherical Bessel functions, and
/// one above 5 for the asymptotic branch of the Bessel functions.
const POINTS: [f64; 5] = [0.37, -0.62, 1e-17, 0.91, 7.3];

fn in_domain(name: &str, x: f64) -> bool {
    let unit = ["asin", "acos", "atanh"].contains(&name);
    let positive =
        ["sqrt", "ln", "log3", "log2", "log10", "powf0.5", "powf-1.5", "powf3.7", "powd_self", "cbrt"].contains(&name);
    !(unit && x.abs() >= 1.0 || positive && x <= 0.0)
}

#[test]
fn unary_functions_agree_with_scalar_hyper_duals() {
    for name in UNARY {
        for &x0 in &POINTS {
            if !in_domain(name, x0) {
                continue;
            }
            let x = hd(x0, 1.0);
            let got = unary(name, x);
            check_hd(&format!("{name}({x0})"), &got, |i, j| unary(name, slice(&x, i, j)));
        }
    }
}

#[test]
fn binary_operations_agree_with_scalar_hyper_duals() {
    for name in BINARY {
        for (x0, y0) in [(0.37, 1.9), (2.3, -0.8), (-1.7, 0.45), (5.5, 2.0)] {
            if *name == "powd" && x0 <= 0.0 {
                continue;
            }
            let (x, y) = (hd(x0, 1.0), hd(y0, -2.0));
            let got = binary(name, x, y);
            check_hd(&format!("{name}({x0}, {y0})"), &got, |i, j| binary(name, slice(&x, i, j), slice(&y, i, j)));
        }
    }
}

#[test]
fn timed_parts_agree_with_scalar_hyper_duals() {
    let x = HdTimed::new(
        0.41,
        Timed { q: [0.3, -1.1], t: 0.8 },
        Timed { q: [0.7], t: -0.2 },
        Timed { q: [Timed { q: [0.1], t: 0.2 }, Timed { q: [-0.3], t: 0.4 }], t: Timed { q: [0.5], t: -0.6 } },
    );
    let slice = |i: usize, j: usize| HyperDual64::new(x.re, x.eps1.get(i), x.eps2.get(j), x.mixed(i, j));
    fn f<D: DualNum<Primitive = f64, InnerDual = f64> + Copy>(name: &str, x: D) -> D {
        if name == "mixed" { binary("div", unary("sin", x), unary("sqrt", x)) } else { unary(name, x) }
    }
    for name in UNARY.iter().chain(["mixed"].iter()) {
        let got = f(name, x);
        for i in 0..3 {
            for j in 0..2 {
                let want = f(name, slice(i, j));
                let ok = close(got.re, want.re)
                    && close(got.eps1.get(i), want.eps1)
                    && close(got.eps2.get(j), want.eps2)
                    && close(got.mixed(i, j), want.eps1eps2);
                assert!(ok, "{name} ({i}, {j}): got {got}, want {want}");
            }
        }
    }
}

fn da(re: f64, k: f64) -> Da {
    Da::new(re, [0.3 * k, -1.1, 0.6])
}

fn check_da(what: &str, got: &Da, want: impl Fn(usize) -> Dual64) {
    for i in 0..3 {
        let w = want(i);
        assert!(close(got.re, w.re) && close(got.eps[i], w.eps), "{what} ({i}): got {got}, want {w}");
    }
}

#[test]
fn dual_arrays_agree_with_scalar_duals() {
    for name in UNARY {
        for &x0 in &POINTS {
            if !in_domain(name, x0) {
                continue;
            }
            let x = da(x0, 1.0);
            check_da(&format!("{name}({x0})"), &unary(name, x), |i| unary(name, Dual64::new(x.re, x.eps[i])));
        }
    }
    for name in BINARY {
        for (x0, y0) in [(0.37, 1.9), (2.3, -0.8), (5.5, 2.0)] {
            let (x, y) = (da(x0, 1.0), da(y0, -2.0));
            check_da(&format!("{name}({x0}, {y0})"), &binary(name, x, y), |i| {
                binary(name, Dual64::new(x.re, x.eps[i]), Dual64::new(y.re, y.eps[i]))
            });
        }
    }
}

/// Independent of num-dual: `f(a, b) = sin(a b) + a² / b` with `ε1` on `a`
/// and `ε2` on `b` against the hand-derived derivatives.
#[test]
fn mixed_derivative_of_a_known_function() {
    let (a0, b0) = (0.7, 1.3);
    let a = HyperDualArray::<[f64; 1], [f64; 1]>::new(a0, [1.0], [0.0], [[0.0]]);
    let b = HyperDualArray::<[f64; 1], [f64; 1]>::new(b0, [0.0], [1.0], [[0.0]]);
    let f = (a * b).sin() + a * a / b;
    let c = (a0 * b0).cos();
    let s = (a0 * b0).sin();
    assert!((f.re - (s + a0 * a0 / b0)).abs() < 1e-15);
    assert!((f.eps1[0] - (b0 * c + 2.0 * a0 / b0)).abs() < 1e-15);
    assert!((f.eps2[0] - (a0 * c - a0 * a0 / (b0 * b0))).abs() < 1e-15);
    assert!((f.eps1eps2[0][0] - (c - a0 * b0 * s - 2.0 * a0 / (b0 * b0))).abs() < 1e-15);
}

/// num-dual panics on `%`; here `x % y = x − n·y` with `n` constant, checked
/// against that expression on scalar hyper-duals.
#[test]
fn remainder_is_x_minus_n_y() {
    for (x0, y0, n) in [(7.3, 2.0, 3.0), (-7.3, 2.0, -3.0), (0.37, 1.9, 0.0), (5.5, -0.8, -6.0)] {
        let (x, y) = (hd(x0, 1.0), hd(y0, -2.0));
        let mut want_re = x0 % y0;
        check_hd("rem", &(x % y), |i, j| {
            let mut w = slice(&x, i, j) - slice(&y, i, j) * n;
            w.re = want_re;
            w
        });
        let mut z = x;
        z %= y;
        assert_eq!(z.eps1eps2, (x % y).eps1eps2);
        want_re = x0 % 0.25;
        check_hd("rem_f64", &(x % 0.25), |i, j| {
            let mut w = slice(&x, i, j);
            w.re = want_re;
            w
        });
        let mut z = x;
        z %= 0.25;
        assert_eq!(z.re, want_re);
    }
}

#[test]
fn seeding_a_variable_and_remainder_derivatives() {
    let x = DualArray::<[f64; 2]>::variable(7.5, 1);
    assert_eq!(x.eps, [0.0, 1.0]);
    // x % 2 = x − 3·2: derivative 1 in x; y % x = y − n x: derivative −n in x.
    let r = x % DualArray::from_re(2.0);
    assert_eq!((r.re, r.eps), (1.5, [0.0, 1.0]));
    let r = DualArray::<[f64; 2]>::from_re(16.0) % x;
    assert_eq!((r.re, r.eps), (1.0, [0.0, -2.0]));
    let r = DualArray::<[f64; 2]>::from_re(1.0) % DualArray::from_re(0.0);
    assert!(r.re.is_nan() && r.eps.iter().all(|e| e.is_nan()));
}

#[test]
fn operators_on_references() {
    let (x, y) = (hd(0.37, 1.0), hd(1.9, -2.0));
    for (got, want) in
        [(&x * &y, x * y), (&x / y, x / y), (&x + &y, x + y), (-&x, -x), (&x % &y, x % y), (x.inv(), x.recip())]
    {
        assert_eq!((got.re, got.eps1, got.eps2, got.eps1eps2), (want.re, want.eps1, want.eps2, want.eps1eps2));
    }
    let s: Hd = [x, y].iter().sum();
    let p: Hd = [x, y].iter().product();
    assert_eq!((s.eps1eps2, p.eps1eps2), ((x + y).eps1eps2, (x * y).eps1eps2));
}

#[test]
fn comparisons_look_at_the_real_part() {
    let (x, y) = (hd(0.5, 1.0), hd(0.5, -3.0));
    assert!(x == y && x <= y && x >= y && x.partial_cmp(&y) == Some(core::cmp::Ordering::Equal));
    assert!(x < hd(0.6, 1.0) && hd(0.6, 1.0) > x);
    assert!(x == 0.5 && x < 0.7 && x > 0.2 && x != 0.4);
    assert!(hd(f64::NAN, 1.0).partial_cmp(&x).is_none());
    let d = da(-1.0, 1.0);
    assert!(d < 0.0 && d.is_negative() && !d.is_positive() && d.abs().re == 1.0 && d.abs().eps == [-0.3, 1.1, -0.6]);
    assert!(Hd::zero().is_zero() && Hd::one().is_one() && !x.is_zero());
}

#[test]
fn conversions_and_display() {
    assert_eq!(Hd::from(2.5).re, 2.5);
    assert_eq!(<Hd as DualNum>::from_re(2.5).eps1eps2, [[0.0; 3]; 2]);
    assert_eq!(Hd::from_f64(0.3).unwrap().re, 0.3);
    assert_eq!(Hd::from_f32(0.25).unwrap().re, 0.25);
    assert_eq!(Hd::from_i64(-7).unwrap().re, -7.0);
    assert_eq!(Hd::from_u128(9).unwrap().re, 9.0);
    assert_eq!(Da::from_str_radix("1.5", 10).unwrap().re, 1.5);
    assert!(Da::from_str_radix("x", 10).is_err());
    assert_eq!(Hd::from_inner(&4.0).re, 4.0);
    assert_eq!(DualStruct::re(&hd(0.5, 1.0)), 0.5);
    assert_eq!(hd(0.5, 1.0).map_dual(|x| x.re * 2.0), 1.0);
    assert_eq!(format!("{}", Da::new(1.0, [2.0, 3.0, 4.0])), "1 + [2.0, 3.0, 4.0]ε");
    assert_eq!(
        format!("{}", HyperDualArray::<[f64; 1], [f64; 1]>::new(1.0, [2.0], [3.0], [[4.0]])),
        "1 + [2.0]ε1 + [3.0]ε2 + [[4.0]]ε1ε2"
    );
    assert_eq!(<Hd as DualNum>::NDERIV, 2);
    assert_eq!(<Da as DualNum>::NDERIV, 1);
}
