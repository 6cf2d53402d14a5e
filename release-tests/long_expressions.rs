//! Lagrangians written as one very long expression, compiled as a user's
//! release build compiles them (this package's test profile is opt-level 3
//! without debug assertions). A sum of 10 240 terms and a product of 16 384
//! factors go through `#[lagrangian]`, compile, and evaluate exactly as the
//! same terms accumulated in a loop, both as the user's method and as the
//! generated trait method; a pendulum written as 256 terms steps as the
//! two-term pendulum does, in forward and in reverse mode, which
//! evaluates its chunks on every scalar type the steps use (through their
//! `f64` lowering on dual numbers, see `chunk_derivatives.rs`).
//!
//! The bodies are built by `macro_rules!` doubling a list of terms, so the
//! source stays short while the macro sees one flat chain.
#![allow(missing_docs)]

use lagrangian::prelude::*;
use lagrangian::{Derivatives, Lagrangian};

// The two longest evaluated on `f64` only, through the generated generic method (the same
// code every scalar type gets): optimising a 10 240-term body on dual
// numbers at the tests' opt-level takes LLVM over ten minutes.

/// Ten doublings of the terms of a sum (`+ x` and `- x`).
macro_rules! long_sum {
    ($name:ident) => {
        long_sum!(@ $name (self q v) [
            + 0.5 * self.m * v[0] * v[0]
            - self.k * q[0].cos()
            + 1e-3 * q[1] * v[1]
            - (q[0] * q[1]).sin() * 1e-4
            + 2.0 * v[1] * v[1]
            - 3.0 / (1.0 + q[1] * q[1])
            + self.m * q[0] * 1e-2
            - 0.25 * v[0] * q[1]
            + (v[0] - v[1]).powi(2) * 0.125
            - q[1].exp() * 1e-3
        ] x x x x x x x x x x);
    };
    (@ $name:ident $names:tt [$($t:tt)*] x $($more:tt)*) => {
        long_sum!(@ $name $names [$($t)* $($t)*] $($more)*);
    };
    // The parameter names come from the first rule, like the terms, so that
    // macro hygiene lets the terms see them.
    (@ $name:ident ($s:tt $q:ident $v:ident) [$($t:tt)*]) => {
        #[lagrangian]
        impl $name {
            fn lagrangian(&$s, $q: [f64; 2], $v: [f64; 2]) -> f64 {
                0.0 $($t)*
            }
        }
    };
}

/// A product of `1 + 1e-5 q[0]` ten doublings long, times `½ v²`.
macro_rules! long_product {
    ($name:ident) => {
        long_product!(@ $name (self q v) [* (1.0 + 1e-5 * q[0])] x x x x x x x x x x x x x x);
    };
    (@ $name:ident $names:tt [$($t:tt)*] x $($more:tt)*) => {
        long_product!(@ $name $names [$($t)* $($t)*] $($more)*);
    };
    (@ $name:ident ($s:tt $q:ident $v:ident) [$($t:tt)*]) => {
        #[lagrangian]
        impl $name {
            fn lagrangian(&$s, $q: [f64; 1], $v: [f64; 1]) -> f64 {
                $s.m * 0.5 * $v[0] * $v[0] $($t)*
            }
        }
    };
}

pub struct LongSum {
    pub m: f64,
    pub k: f64,
}

long_sum!(LongSum);

pub struct LongProduct {
    pub m: f64,
}

long_product!(LongProduct);

const COPIES: usize = 1 << 10;
const FACTORS: i32 = 1 << 14;

/// The sum accumulated term by term in a loop, in the macro's order.
fn sum_by_loop(s: &LongSum, q: [f64; 2], v: [f64; 2]) -> f64 {
    let terms = [
        0.5 * s.m * v[0] * v[0],
        -(s.k * q[0].cos()),
        1e-3 * q[1] * v[1],
        -((q[0] * q[1]).sin() * 1e-4),
        2.0 * v[1] * v[1],
        -(3.0 / (1.0 + q[1] * q[1])),
        s.m * q[0] * 1e-2,
        -(0.25 * v[0] * q[1]),
        (v[0] - v[1]).powi(2) * 0.125,
        -(q[1].exp() * 1e-3),
    ];
    let mut acc = 0.0;
    for _ in 0..COPIES {
        for term in terms {
            acc += term;
        }
    }
    acc
}

#[test]
fn a_sum_of_10240_terms_evaluates_as_the_loop() {
    let s = LongSum { m: 1.3, k: 0.7 };
    for (q, v) in [([0.3, -0.2], [0.5, 1.1]), ([-1.7, 0.9], [-0.4, 0.05])] {
        let expected = sum_by_loop(&s, q, v);
        // Bit for bit: the same operations in the same order (`a - b` and
        // `a + -b` are the same IEEE operation).
        assert_eq!(s.lagrangian(q, v).to_bits(), expected.to_bits());
        assert_eq!(Lagrangian::<2>::lagrangian(&s, 0.0, q, v).to_bits(), expected.to_bits());
    }
    assert_eq!(<LongSum as Lagrangian<2>>::CYCLIC, [false, false]);
}

#[test]
fn a_product_of_16384_factors_evaluates_as_the_loop() {
    let s = LongProduct { m: 2.0 };
    let (q, v) = ([0.8], [1.5]);
    let mut expected = s.m * 0.5 * v[0] * v[0];
    for _ in 0..FACTORS {
        expected *= 1.0 + 1e-5 * q[0];
    }
    assert_eq!(s.lagrangian(q, v).to_bits(), expected.to_bits());
    assert_eq!(Lagrangian::<1>::lagrangian(&s, 0.0, q, v).to_bits(), expected.to_bits());
}

/// `½ v² + cos q` split into 128 copies of `2⁻⁷ · ½ v²` and of `2⁻⁷ cos q`
/// (seven doublings of the pair): 256 operands, well past the length at
/// which the macro splits a chain into chunks.
macro_rules! long_pendulum {
    ($name:ident) => {
        long_pendulum!(@ $name (self q v) [
            + 0.0078125 * 0.5 * v[0] * v[0]
            + 0.0078125 * q[0].cos()
        ] x x x x x x x);
    };
    (@ $name:ident $names:tt [$($t:tt)*] x $($more:tt)*) => {
        long_pendulum!(@ $name $names [$($t)* $($t)*] $($more)*);
    };
    (@ $name:ident ($s:tt $q:ident $v:ident) [$($t:tt)*]) => {
        #[lagrangian]
        impl $name {
            fn lagrangian(&$s, $q: [f64; 1], $v: [f64; 1]) -> f64 {
                0.0 $($t)*
            }
        }
    };
}

pub struct LongPendulum;

long_pendulum!(LongPendulum);

pub struct Pendulum;

#[lagrangian]
impl Pendulum {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] + q[0].cos()
    }
}

#[test]
fn a_pendulum_of_256_terms_steps_as_the_pendulum() {
    for derivatives in [Derivatives::Forward, Derivatives::Reverse] {
        let (q0, v0, h) = ([1.2], [0.3], 0.05);
        let mut long = Integrator::new(LongPendulum, Midpoint, h).derivatives(derivatives).start(0.0, q0, v0).unwrap();
        let mut short = Integrator::new(Pendulum, Midpoint, h).derivatives(derivatives).start(0.0, q0, v0).unwrap();
        let (e_long, e_short) = (long.energy().unwrap(), short.energy().unwrap());
        long.run(400, |_| {}).unwrap();
        short.run(400, |_| {}).unwrap();
        // The two Lagrangians differ by the rounding of the long sum (a few
        // ulps of `L`), so the trajectories and the energies' oscillation
        // agree to a few ulps per step.
        let (a, b) = (long.state(), short.state());
        assert!((a.q[0] - b.q[0]).abs() < 1e-12, "{derivatives:?}: q {} vs {}", a.q[0], b.q[0]);
        assert!((a.p[0] - b.p[0]).abs() < 1e-12, "{derivatives:?}: p {} vs {}", a.p[0], b.p[0]);
        let (de_long, de_short) = (long.energy().unwrap() - e_long, short.energy().unwrap() - e_short);
        assert!((de_long - de_short).abs() < 1e-12, "{derivatives:?}: energy change {de_long} vs {de_short}");
    }
}
