//! The chunks of a long Lagrangian reach dual numbers over `f64` through
//! their value, gradient and Hessian in `f64` and the chain rule
//! (`lagrangian::chunk`), and every other scalar through their generic
//! body. Both must give what the same terms give evaluated one by one on
//! that scalar: values bit for bit on `f64`-based numbers, first and second
//! derivatives to round-off, and double-double values to double-double
//! accuracy (a chunk lowered to `f64` would round them to `f64`).
#![allow(missing_docs)]

use lagrangian::__private::hyperdual::{DualArray, HyperDualArray};
use lagrangian::__private::tape::{Seeds, Tape, Var};
use lagrangian::num_dual::{Dual, Dual64, DualStruct, HyperDual, HyperDual64};
use lagrangian::prelude::*;
use lagrangian::{Lagrangian, Scalar};

/// Seven doublings of ten terms reading `t`, both coordinates and both
/// velocities, nonlinearly and in products: 1 280 operands, chunks of
/// eight reading up to five leaves.
macro_rules! mixed_sum {
    ($name:ident) => {
        mixed_sum!(@ $name (self t q v) [
            + 0.5 * self.m * v[0] * v[0]
            - self.k * q[0].cos() * (1.0 + 0.1 * t.sin())
            + 1e-1 * q[1] * v[1] * q[0]
            - (q[0] * q[1]).sin() * 0.3
            + 2.0 * v[1] * v[1] * q[1].cos()
            - 3.0 / (1.0 + q[1] * q[1])
            + self.m * q[0] * v[0] * t
            - 0.25 * v[0] * q[1].exp()
            + (v[0] - v[1]).powi(3) * 0.125
            - (q[1] + 0.5 * v[0]).sqrt() * 1e-1
        ] x x x x x x x);
    };
    (@ $name:ident $names:tt [$($t:tt)*] x $($more:tt)*) => {
        mixed_sum!(@ $name $names [$($t)* $($t)*] $($more)*);
    };
    (@ $name:ident ($s:tt $t:ident $q:ident $v:ident) [$($terms:tt)*]) => {
        #[lagrangian]
        impl $name {
            fn lagrangian(&$s, $t: f64, $q: [f64; 2], $v: [f64; 2]) -> f64 {
                0.0 $($terms)*
            }
        }
    };
}

pub struct Mixed {
    pub m: f64,
    pub k: f64,
}

mixed_sum!(Mixed);

const COPIES: usize = 1 << 7;

/// The same terms accumulated one by one on `D`, in the macro's order.
fn by_loop<D: Scalar>(s: &Mixed, t: D, q: [D; 2], v: [D; 2]) -> D {
    let terms = [
        v[0] * v[0] * (0.5 * s.m),
        -(q[0].cos() * s.k * (t.sin() * 0.1 + 1.0)),
        q[1] * 1e-1 * v[1] * q[0],
        -((q[0] * q[1]).sin() * 0.3),
        v[1] * 2.0 * v[1] * q[1].cos(),
        -((q[1] * q[1] + 1.0).recip() * 3.0),
        q[0] * s.m * v[0] * t,
        -(v[0] * 0.25 * q[1].exp()),
        (v[0] - v[1]).powi(3) * 0.125,
        -((v[0] * 0.5 + q[1]).sqrt() * 1e-1),
    ];
    let mut acc = D::zero();
    for _ in 0..COPIES {
        for term in terms {
            acc += term;
        }
    }
    acc
}

const SYSTEM: Mixed = Mixed { m: 1.3, k: 0.7 };
const T: f64 = 0.4;
const Q: [f64; 2] = [0.3, 0.6];
const V: [f64; 2] = [0.5, -1.1];

/// `|a − b| ≤ tol · (1 + |b|)`.
fn close(a: f64, b: f64, tol: f64, what: &str) {
    assert!((a - b).abs() <= tol * (1.0 + b.abs()), "{what}: {a} vs {b}");
}

/// `(FIRST_ORDER, SECOND_ORDER)` of `D`.
fn order<D: Scalar>() -> (bool, bool) {
    (D::FIRST_ORDER, D::SECOND_ORDER)
}

#[test]
fn scalars_are_sorted_by_what_their_parts_hold() {
    let (none, first, second) = ((false, false), (true, false), (false, true));
    assert_eq!(order::<f64>(), none);
    assert_eq!(order::<Dual64>(), first);
    assert_eq!(order::<DualArray<[f64; 3]>>(), first);
    assert_eq!(order::<HyperDual64>(), second);
    assert_eq!(order::<Var>(), second);
    assert_eq!(order::<HyperDualArray<[f64; 2], [f64; 3]>>(), second);
    // First order over first order: the mixed second derivatives of the
    // runtime's forward-over-forward Hessian products.
    assert_eq!(order::<Dual<Dual64>>(), second);
    assert_eq!(order::<Dual<DualArray<[f64; 3]>>>(), second);
    // Third derivatives are not in a second-order Taylor polynomial.
    assert_eq!(order::<Dual<HyperDual64>>(), none);
    assert_eq!(order::<Dual<Dual<Dual64>>>(), none);
    // Double-double values, with or without derivatives, need the body.
    assert_eq!(order::<DoubleDouble>(), none);
    assert_eq!(order::<HyperDual<DoubleDouble>>(), none);
    assert_eq!(order::<Dual<Dual<DoubleDouble>>>(), none);
}

#[test]
fn values_are_those_of_f64_bit_for_bit() {
    let s = &SYSTEM;
    let value = Lagrangian::<2>::lagrangian(s, T, Q, V);
    // A sum of 1 280 terms rounds differently in a different order only.
    close(value, by_loop(s, T, Q, V), 1e-12, "value");
    let dual = Lagrangian::<2>::lagrangian(s, Dual64::from_re(T), Q.map(Dual64::from_re), V.map(Dual64::from_re));
    assert_eq!(dual.re.to_bits(), value.to_bits());
    let x = |x: f64, i: usize| HyperDualArray::<[f64; 5], [f64; 5]>::from_re(x).seeded(i);
    let hyper = Lagrangian::<2>::lagrangian(s, x(T, 0), [x(Q[0], 1), x(Q[1], 2)], [x(V[0], 3), x(V[1], 4)]);
    assert_eq!(hyper.re.to_bits(), value.to_bits());
}

/// Seeds of all five inputs `(t, q0, q1, v0, v1)` in both directions.
trait Seeded {
    fn seeded(self, i: usize) -> Self;
}

impl Seeded for HyperDualArray<[f64; 5], [f64; 5]> {
    fn seeded(mut self, i: usize) -> Self {
        self.eps1[i] = 1.0;
        self.eps2[i] = 1.0;
        self
    }
}

#[test]
fn gradients_and_hessians_match_the_terms_on_every_dual_number() {
    let s = &SYSTEM;
    type H = HyperDualArray<[f64; 5], [f64; 5]>;
    let x = |x: f64, i: usize| H::from_re(x).seeded(i);
    let (t, q, v) = (x(T, 0), [x(Q[0], 1), x(Q[1], 2)], [x(V[0], 3), x(V[1], 4)]);
    let (chunked, direct) = (Lagrangian::<2>::lagrangian(s, t, q, v), by_loop(s, t, q, v));
    for i in 0..5 {
        close(chunked.eps1[i], direct.eps1[i], 1e-12, "gradient");
        for j in 0..5 {
            close(chunked.eps1eps2[i][j], direct.eps1eps2[i][j], 1e-12, "hessian");
        }
    }
    // Scalar hyper-duals on one pair, first-order arrays, scalar duals.
    let h = |x: f64, a: bool, b: bool| HyperDual64::new(x, f64::from(u8::from(a)), f64::from(u8::from(b)), 0.0);
    let (t, q, v) = (
        h(T, false, false),
        [h(Q[0], true, false), h(Q[1], false, true)],
        [h(V[0], false, false), h(V[1], true, true)],
    );
    let (a, b) = (Lagrangian::<2>::lagrangian(s, t, q, v), by_loop(s, t, q, v));
    close(a.eps1eps2, b.eps1eps2, 1e-12, "mixed second derivative");
    let d = |x: f64, i: usize| DualArray::<[f64; 5]>::variable(x, i);
    let (t, q, v) = (d(T, 0), [d(Q[0], 1), d(Q[1], 2)], [d(V[0], 3), d(V[1], 4)]);
    let (a, b) = (Lagrangian::<2>::lagrangian(s, t, q, v), by_loop(s, t, q, v));
    for i in 0..5 {
        close(a.eps[i], b.eps[i], 1e-12, "array gradient");
    }
    let (t, q, v) = (Dual64::from_re(T), [Dual64::new(Q[0], 1.0), Dual64::from_re(Q[1])], V.map(Dual64::from_re));
    close(Lagrangian::<2>::lagrangian(s, t, q, v).eps, by_loop(s, t, q, v).eps, 1e-12, "dual");
    // Forward over forward, as `gradient_qv_scalar` differentiates `L`: the
    // outer `ε` on `v[1]`, the inner directions on all five inputs. The
    // values stay those of `f64` bit for bit.
    type N = Dual<DualArray<[f64; 5]>>;
    let n = |x: f64, i: usize, outer: bool| {
        let inner = DualArray::<[f64; 5]>::variable(x, i);
        N::new(inner, if outer { DualArray::from_re(1.0) } else { DualArray::from_re(0.0) })
    };
    let (t, q, v) = (n(T, 0, false), [n(Q[0], 1, false), n(Q[1], 2, false)], [n(V[0], 3, false), n(V[1], 4, true)]);
    let (a, b) = (Lagrangian::<2>::lagrangian(s, t, q, v), by_loop(s, t, q, v));
    assert_eq!(a.re.re.to_bits(), Lagrangian::<2>::lagrangian(s, T, Q, V).to_bits());
    close(a.eps.re, b.eps.re, 1e-12, "nested first derivative");
    for i in 0..5 {
        close(a.re.eps[i], b.re.eps[i], 1e-12, "nested gradient");
        close(a.eps.eps[i], b.eps.eps[i], 1e-12, "nested mixed second derivative");
    }
    let n = |x: f64, inner: bool, outer: bool| {
        Dual::new(Dual64::new(x, f64::from(u8::from(inner))), Dual64::from_re(f64::from(u8::from(outer))))
    };
    let (t, q, v) = (n(T, true, false), [n(Q[0], false, true), n(Q[1], true, true)], V.map(|x| n(x, false, false)));
    let (a, b) = (Lagrangian::<2>::lagrangian(s, t, q, v), by_loop(s, t, q, v));
    assert_eq!(a.re.re.to_bits(), Lagrangian::<2>::lagrangian(s, T, Q, V).to_bits());
    close(a.eps.eps, b.eps.eps, 1e-12, "nested scalar mixed second derivative");
}

#[test]
fn the_tape_records_the_chunks_exact_derivatives() {
    let s = &SYSTEM;
    let inputs = [T, Q[0], Q[1], V[0], V[1]];
    let mut results = Vec::new();
    for chunked in [true, false] {
        let mut tape = Tape::new();
        let value = tape
            .record(&inputs, |x| {
                let (t, q, v) = (x[0], [x[1], x[2]], [x[3], x[4]]);
                if chunked { Lagrangian::<2>::lagrangian(s, t, q, v) } else { by_loop(s, t, q, v) }
            })
            .unwrap();
        let mut gradient = [0.0; 5];
        let mut hs = [0.0; 25];
        let seeds = Seeds::dense(0..5);
        tape.hessian_product(&seeds, &mut gradient, &mut hs).unwrap();
        let mut hessian = [0.0; 25];
        seeds.recover(&hs, 0..5, &mut hessian).unwrap();
        results.push((value, gradient, hessian));
    }
    let ((value, gradient, hessian), (value_loop, gradient_loop, hessian_loop)) = (results[0], results[1]);
    assert_eq!(value.to_bits(), Lagrangian::<2>::lagrangian(s, T, Q, V).to_bits());
    close(value, value_loop, 1e-12, "tape value");
    for i in 0..5 {
        close(gradient[i], gradient_loop[i], 1e-12, "tape gradient");
    }
    for i in 0..25 {
        close(hessian[i], hessian_loop[i], 1e-12, "tape hessian");
    }
}

#[test]
fn double_double_values_keep_their_precision() {
    let s = &SYSTEM;
    let dd = DoubleDouble::from;
    let (t, q, v) = (dd(T), Q.map(dd), V.map(dd));
    let (chunked, direct) = (Lagrangian::<2>::lagrangian(s, t, q, v), by_loop(s, t, q, v));
    // Summed in a different order, 1 280 terms agree to double-double
    // round-off; in `f64` they would differ near 1e-16 of their size.
    let error = (chunked - direct).abs().re();
    assert!(error <= 1e-25 * direct.abs().re(), "{chunked} vs {direct}: {error:e}");
    let h = |x: f64, a: f64| HyperDual::<DoubleDouble>::new(dd(x), dd(a), dd(a), dd(0.0));
    let (t, q, v) = (h(T, 0.0), [h(Q[0], 1.0), h(Q[1], 0.0)], V.map(|x| h(x, 0.0)));
    let (chunked, direct) = (Lagrangian::<2>::lagrangian(s, t, q, v), by_loop(s, t, q, v));
    let error = (chunked.eps1eps2 - direct.eps1eps2).abs().re();
    assert!(error <= 1e-25 * (1.0 + direct.eps1eps2.abs().re()), "{} vs {}", chunked.eps1eps2, direct.eps1eps2);
}
