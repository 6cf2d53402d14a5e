//! Random Lagrangians for the structure analysis, written by
//! `scripts/gradient_fuzz.py structure` (fixed seed; regenerate with
//! `python3 scripts/gradient_fuzz.py structure > tests/systems/structure_fuzz.rs && cargo fmt`):
//! bodies made of terms with chosen couplings (potentials in one or two
//! coordinates at distances 0 to 3, kinetic terms with constant, position-
//! or time-dependent coefficients, terms linear or quartic in `v`, loops
//! over neighbours at distance 1 or 2). What the macro claims for each
//! (`SEPARABILITY`, `COUPLING`, `AUTONOMOUS`, `CYCLIC`) is checked against
//! derivatives at random points (`structure_analysis::check`), never
//! compared with an expected answer: an overstated claim fails.
#![allow(clippy::all, dead_code, unused_mut, unused_parens, unused_variables)]
use super::structure_analysis::{check, check_autonomy_and_cyclic};
use lagrangian::prelude::*;

pub struct Random0<const N: usize> {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl<const N: usize> Random0<N> {
    fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
        let mut kinetic = 0.0;
        for i in 0..N {
            kinetic += 0.5 * v[i] * v[i];
        }
        let mut potential = 0.0;
        kinetic - potential + 0.5 * (1.5 + ((1.0 + (q[0]) * (q[0])).sqrt())) * v[0] * v[3]
            - self.a * (1.0 + (q[2] - q[1]) * (q[2] - q[1])).sqrt()
            + 0.2 * q[4] * v[1] * v[1]
    }
}

pub struct Random1<const N: usize> {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl<const N: usize> Random1<N> {
    fn lagrangian(&self, t: f64, q: [f64; N], v: [f64; N]) -> f64 {
        let mut kinetic = 0.0;
        for i in 0..N {
            kinetic += 0.5 * v[i] * v[i];
        }
        let mut potential = 0.0;
        for i in 0..N - 1 {
            let d = q[i + 1] - q[i];
            potential += self.a * (d).cos();
        }
        kinetic - potential - self.b * q[2] * q[3] * (q[2]).sin() + 0.5 * 0.3 * v[4] * v[5]
            - (self.b * t).cos() * (1.0 + (q[4]) * (q[4])).sqrt()
    }
}

pub struct Random2<const N: usize> {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl<const N: usize> Random2<N> {
    fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
        let mut kinetic = 0.0;
        for i in 0..N {
            kinetic += 0.5 * v[i] * v[i];
        }
        let mut potential = 0.0;
        kinetic - potential + 0.1 * v[1] * v[2] * v[1] * v[2] + 0.5 * 0.3 * v[2] * v[3]
    }
}

pub struct Random3<const N: usize> {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl<const N: usize> Random3<N> {
    fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
        let mut kinetic = 0.0;
        for i in 0..N {
            kinetic += 0.5 * v[i] * v[i];
        }
        let mut potential = 0.0;
        kinetic - potential - self.a * (q[2] - q[0]).powi(3) - self.a * (0.5 * (q[3] - q[0])).tanh()
            + 0.5 * 0.3 * v[0] * v[2]
    }
}

pub struct Random4<const N: usize> {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl<const N: usize> Random4<N> {
    fn lagrangian(&self, t: f64, q: [f64; N], v: [f64; N]) -> f64 {
        let mut kinetic = 0.0;
        for i in 0..N {
            kinetic += 0.5 * v[i] * v[i];
        }
        let mut potential = 0.0;
        for i in 0..N - 2 {
            let d = q[i + 2] - q[i];
            potential += self.a * 0.5 * (d) * (d);
        }
        kinetic
            - potential
            - self.a * (0.5 * (q[4] - q[3])).tanh()
            - self.a * (q[1] - q[0]).cos()
            - (self.b * t).cos() * (q[3]).powi(3)
            - self.a * (1.0 + (q[4]) * (q[4])).sqrt()
    }
}

pub struct Random5<const N: usize> {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl<const N: usize> Random5<N> {
    fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
        let mut kinetic = 0.0;
        for i in 0..N {
            kinetic += 0.5 * v[i] * v[i];
        }
        let mut potential = 0.0;
        kinetic - potential - self.b * q[3] * q[4] * (0.5 * (q[3])).tanh() + 0.5 * 0.3 * v[3] * v[4]
    }
}

pub struct Random6<const N: usize> {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl<const N: usize> Random6<N> {
    fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
        let mut kinetic = 0.0;
        for i in 0..N {
            kinetic += 0.5 * v[i] * v[i];
        }
        let mut potential = 0.0;
        kinetic - potential - self.a * (q[3] - q[1]).sin()
            + self.b * v[1] * (q[2]).sin()
            + self.b * v[0] * 0.5 * (q[0]) * (q[0])
    }
}

pub struct Random7<const N: usize> {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl<const N: usize> Random7<N> {
    fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
        let mut kinetic = 0.0;
        for i in 0..N {
            kinetic += 0.5 * v[i] * v[i];
        }
        let mut potential = 0.0;
        kinetic - potential - self.a * (q[3] - q[1]).cos() + 0.1 * v[0] * v[2] * v[0] * v[2]
            - self.a * (q[3] - q[2]).sin()
    }
}

pub struct Random8<const N: usize> {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl<const N: usize> Random8<N> {
    fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
        let mut kinetic = 0.0;
        for i in 0..N {
            kinetic += 0.5 * v[i] * v[i];
        }
        let mut potential = 0.0;
        kinetic - potential + 0.5 * self.a * v[2] * v[3]
            - self.b * q[2] * q[4] * (q[2]).sin()
            - self.b * q[2] * q[2] * (0.5 * (q[2])).tanh()
    }
}

pub struct Random9<const N: usize> {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl<const N: usize> Random9<N> {
    fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
        let mut kinetic = 0.0;
        for i in 0..N {
            kinetic += 0.5 * v[i] * v[i];
        }
        let mut potential = 0.0;
        kinetic - potential + 0.5 * (1.5 + ((0.5 * (q[4])).tanh())) * v[0] * v[2]
            - self.b * q[0] * q[1] * 0.5 * (q[0]) * (q[0])
            + 0.1 * v[2] * v[4] * v[2] * v[4]
            - self.a * 0.5 * (q[4]) * (q[4])
    }
}

pub struct Random10<const N: usize> {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl<const N: usize> Random10<N> {
    fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
        let mut kinetic = 0.0;
        for i in 0..N {
            kinetic += 0.5 * v[i] * v[i];
        }
        let mut potential = 0.0;
        for i in 0..N - 1 {
            let d = q[i + 1] - q[i];
            potential += self.a * (d).cos();
            kinetic += 0.1 * v[i] * v[i + 1];
        }
        kinetic - potential
            + 0.5 * self.a * v[4] * v[5]
            + 0.1 * v[1] * v[4] * v[1] * v[4]
            + self.b * v[3] * (1.0 + (q[5]) * (q[5])).sqrt()
    }
}

pub struct Random11<const N: usize> {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl<const N: usize> Random11<N> {
    fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
        let mut kinetic = 0.0;
        for i in 0..N {
            kinetic += 0.5 * v[i] * v[i];
        }
        let mut potential = 0.0;
        kinetic - potential - self.a * (q[4] - q[3]).cos() + 0.5 * 0.3 * v[0] * v[0] + 0.5 * 0.3 * v[0] * v[2]
    }
}

pub struct Random12<const N: usize> {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl<const N: usize> Random12<N> {
    fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
        let mut kinetic = 0.0;
        for i in 0..N {
            kinetic += 0.5 * v[i] * v[i];
        }
        let mut potential = 0.0;
        for i in 0..N - 2 {
            let d = q[i + 2] - q[i];
            potential += self.a * (d).powi(3);
            kinetic += 0.1 * v[i] * v[i + 2];
        }
        kinetic - potential - self.b * q[3] * q[3] * (q[3]).powi(3) + self.b * v[1] * (q[1]).powi(3)
            - self.b * q[1] * q[3] * (q[1]).powi(3)
    }
}

pub struct Random13<const N: usize> {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl<const N: usize> Random13<N> {
    fn lagrangian(&self, t: f64, q: [f64; N], v: [f64; N]) -> f64 {
        let mut kinetic = 0.0;
        for i in 0..N {
            kinetic += 0.5 * v[i] * v[i];
        }
        let mut potential = 0.0;
        for i in 0..N - 2 {
            let d = q[i + 2] - q[i];
            potential += self.a * (d).sin();
            kinetic += 0.1 * v[i] * v[i + 2];
        }
        kinetic - potential + 0.5 * 0.3 * v[5] * v[5] - (self.b * t).cos() * (0.5 * (q[5])).tanh()
            + 0.5 * (1.5 + ((q[4]).powi(3))) * v[3] * v[5]
            - self.a * (q[3]).cos()
    }
}

pub struct Random14<const N: usize> {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl<const N: usize> Random14<N> {
    fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
        let mut kinetic = 0.0;
        for i in 0..N {
            kinetic += 0.5 * v[i] * v[i];
        }
        let mut potential = 0.0;
        kinetic - potential + 0.5 * 0.3 * v[0] * v[2]
            - self.a * (q[3] - q[2]).powi(3)
            - self.a * 0.5 * (q[2] - q[1]) * (q[2] - q[1])
    }
}

pub struct Random15<const N: usize> {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl<const N: usize> Random15<N> {
    fn lagrangian(&self, t: f64, q: [f64; N], v: [f64; N]) -> f64 {
        let mut kinetic = 0.0;
        for i in 0..N {
            kinetic += 0.5 * v[i] * v[i];
        }
        let mut potential = 0.0;
        kinetic - potential - (self.b * t).cos() * 0.5 * (q[3]) * (q[3]) + 0.5 * self.a * v[3] * v[3]
    }
}

#[test]
fn random_bodies_claim_no_more_structure_than_they_have() {
    check("random 0", &Random0::<5> { a: 1.2, b: 1.1 }, 100);
    check_autonomy_and_cyclic("random 0", &Random0::<5> { a: 1.2, b: 1.1 }, 200);
    check("random 1", &Random1::<6> { a: 1.2, b: 1.1 }, 101);
    check_autonomy_and_cyclic("random 1", &Random1::<6> { a: 1.2, b: 1.1 }, 201);
    check("random 2", &Random2::<4> { a: 1.2, b: 1.1 }, 102);
    check_autonomy_and_cyclic("random 2", &Random2::<4> { a: 1.2, b: 1.1 }, 202);
    check("random 3", &Random3::<4> { a: 1.2, b: 0.4 }, 103);
    check_autonomy_and_cyclic("random 3", &Random3::<4> { a: 1.2, b: 0.4 }, 203);
    check("random 4", &Random4::<5> { a: 1.2, b: 0.4 }, 104);
    check_autonomy_and_cyclic("random 4", &Random4::<5> { a: 1.2, b: 0.4 }, 204);
    check("random 5", &Random5::<5> { a: 0.7, b: 1.1 }, 105);
    check_autonomy_and_cyclic("random 5", &Random5::<5> { a: 0.7, b: 1.1 }, 205);
    check("random 6", &Random6::<4> { a: 0.7, b: 0.4 }, 106);
    check_autonomy_and_cyclic("random 6", &Random6::<4> { a: 0.7, b: 0.4 }, 206);
    check("random 7", &Random7::<4> { a: 1.2, b: 0.4 }, 107);
    check_autonomy_and_cyclic("random 7", &Random7::<4> { a: 1.2, b: 0.4 }, 207);
    check("random 8", &Random8::<6> { a: 0.7, b: 0.4 }, 108);
    check_autonomy_and_cyclic("random 8", &Random8::<6> { a: 0.7, b: 0.4 }, 208);
    check("random 9", &Random9::<5> { a: 1.2, b: 0.4 }, 109);
    check_autonomy_and_cyclic("random 9", &Random9::<5> { a: 1.2, b: 0.4 }, 209);
    check("random 10", &Random10::<6> { a: 0.7, b: 0.4 }, 110);
    check_autonomy_and_cyclic("random 10", &Random10::<6> { a: 0.7, b: 0.4 }, 210);
    check("random 11", &Random11::<5> { a: 0.7, b: 1.1 }, 111);
    check_autonomy_and_cyclic("random 11", &Random11::<5> { a: 0.7, b: 1.1 }, 211);
    check("random 12", &Random12::<4> { a: 0.7, b: 1.1 }, 112);
    check_autonomy_and_cyclic("random 12", &Random12::<4> { a: 0.7, b: 1.1 }, 212);
    check("random 13", &Random13::<6> { a: 0.7, b: 0.4 }, 113);
    check_autonomy_and_cyclic("random 13", &Random13::<6> { a: 0.7, b: 0.4 }, 213);
    check("random 14", &Random14::<4> { a: 0.7, b: 1.1 }, 114);
    check_autonomy_and_cyclic("random 14", &Random14::<4> { a: 0.7, b: 1.1 }, 214);
    check("random 15", &Random15::<4> { a: 0.7, b: 0.4 }, 115);
    check_autonomy_and_cyclic("random 15", &Random15::<4> { a: 0.7, b: 0.4 }, 215);
}
