//! Random Lagrangians for the macro's gradient code, written by
//! `scripts/gradient_fuzz.py` (fixed seed; regenerate with
//! `python3 scripts/gradient_fuzz.py > tests/verification/gradient_fuzz.rs && cargo fmt`):
//! bodies of the subset the adjoint stage transforms, nobody's hand-picked
//! case. Each one's `gradient_q`, `gradient_qv` and generic gradient are
//! checked against dual numbers at random states (`gradient_code.rs`).
#![allow(clippy::all, dead_code, unused_parens)]
use super::gradient_code::{scalar_difference, worst_difference};
use lagrangian::prelude::*;

pub struct Straight0 {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl Straight0 {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let x0 = (q[0] + self.a) * ((3.0) / 3.0);
        let x1 = 2.0 * v[1] * v[1] * v[1];
        0.5 * v[0] * v[0] + 0.5 * v[1] * v[1] + v[0] * (((q[1]) / 3.0) * ((self.b) / (1.5 + (q[1]) * (q[1]))))
            - ((1.0 + ((1.0 + (q[0]) * (q[0])).powf(self.b)) * ((1.0 + (q[0]) * (q[0])).powf(self.b))).powf(0.5)
                + q[1] * (v[0]) * (v[0]) * q[1])
            + ((q[0]).atan()) / (self.b + 1.0)
            + 0.1 * x0 * q[1]
            + 0.1 * x1 * q[0]
    }
}

pub struct Straight1 {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl Straight1 {
    fn lagrangian(&self, q: [f64; 3], v: [f64; 3]) -> f64 {
        let x0 = (0.5 * ((2.0 + (q[1]).sin()).ln())).tanh().powi(4);
        let x1 = ((q[0]) / 3.0).abs() * q[1];
        let mut s = (1.0 + (q[2]) * (q[2])).powf(0.5);
        s += ((1.0 + (q[0]) * (q[0])).powf(1.5)) / (self.b + 1.0);
        s -= (q[1]) * (q[2]);
        0.75 * v[0] * v[0] + 0.5 * v[1] * v[1] + 0.5 * v[2] * v[2] + v[2] * (self.a * (q[1]).sin() * self.a)
            - (-((2.0 + (q[0]).sin()).ln())
                + (q[1] + q[0]) / (1.5 + ((1.0 + (q[0]) * (q[0])).sqrt()) * ((1.0 + (q[0]) * (q[0])).sqrt())))
            + (1.0 + (s) * (s)).powf(1.5)
            + (2.0 + (q[1]).sin()).ln()
            + 0.1 * x0 * q[2]
            + 0.1 * x1 * q[0]
            + 0.1 * s * q[2]
    }
}

pub struct Straight2 {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl Straight2 {
    fn lagrangian(&self, q: [f64; 3], v: [f64; 3]) -> f64 {
        0.75 * v[0] * v[0]
            + 0.5 * v[1] * v[1]
            + 0.5 * self.a * v[2] * v[2]
            + v[1] * ((2.0 + (1.3 * q[2] * 1.3).sin()).ln())
            - (((2.0 + ((-0.7) / (1.5 + (v[0]) * (v[0]))).sin()).ln())
                / (1.5 + ((0.5 * (-(v[2]))).tanh().powi(3)) * ((0.5 * (-(v[2]))).tanh().powi(3))))
            + (1.0 + (self.a - (q[1])) * (self.a - (q[1]))).sqrt()
    }
}

pub struct Straight3 {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl Straight3 {
    fn lagrangian(&self, q: [f64; 3], v: [f64; 3]) -> f64 {
        let x0 = ((0.3 * (q[0])).tanh().exp()).abs() * v[2];
        0.5 * self.a * v[0] * v[0]
            + 0.5 * self.a * v[1] * v[1]
            + 0.75 * v[2] * v[2]
            + v[0] * (((0.3 * (q[1])).tanh().exp()) * ((q[2]) / (self.b + 1.0)))
            - ((2.0 + (-((1.0 + (q[1]) * (q[1])).sqrt())).sin()).ln())
            + (0.5 * ((1.0 + (q[1]) * (q[1])).powf(0.5))).tanh().powi(4)
            + 0.1 * x0 * q[2]
    }
}

pub struct Straight4 {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl Straight4 {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let x0 = (q[0] + v[1]).tanh();
        0.5 * self.a * v[0] * v[0]
            + 0.75 * v[1] * v[1]
            + v[0] * ((1.0 + (q[1]) * (q[1])).sqrt() + (q[1]) / (1.5 + (v[0]) * (v[0])))
            - ((0.5 * ((2.0 + ((q[0]) * (self.b)).sin()).ln())).tanh().powi(2))
            + (0.3 * (q[1] - (q[0]))).tanh().exp()
            + 0.1 * x0 * q[0]
    }
}

pub struct Straight5 {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl Straight5 {
    fn lagrangian(&self, t: f64, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * v[0] * v[0] + 0.5 * v[1] * v[1] + v[1] * (self.a * q[0] * q[0] * q[0])
            - ((0.5 * (-((1.0 + (q[1]) * (q[1])).powf(self.b)))).tanh().powi(2))
            + (q[1] - (q[1])).abs() * q[0]
            + 0.1 * t * q[1]
    }
}

pub struct Straight6 {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl Straight6 {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let x0 = (2.0 + q[1]) * (v[0] + 3.0);
        let x1 = (v[1] - (self.a)) / (1.5 + (v[0] + x0) * (v[0] + x0));
        0.75 * v[0] * v[0] + 0.5 * self.a * v[1] * v[1] + v[0] * ((2.0 + ((q[1]) / (1.5 + (q[0]) * (q[0]))).sin()).ln())
            - (((1.0 + (q[0]) * (q[0])).sqrt() + q[0] + q[0]) * (((1.0 + (v[1]) * (v[1])).powf(1.5)) / (self.b + 1.0)))
            + (2.0 + ((1.0 + (q[0]) * (q[0])).powf(self.b)).sin()).ln()
            + 0.1 * x0 * q[0]
            + 0.1 * x1 * q[1]
    }
}

pub struct Straight7 {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl Straight7 {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let x0 = self.a * q[0] * q[0] * q[0];
        let x1 = (q[0] + x0) / (1.5 + (0.25 * self.b * self.b * self.b) * (0.25 * self.b * self.b * self.b));
        0.75 * v[0] * v[0]
            + 0.75 * v[1] * v[1]
            + v[1] * ((1.0 + ((v[0]) / (self.b + 1.0)) * ((v[0]) / (self.b + 1.0))).powf(0.5))
            - (q[0] * ((q[0]).abs() * self.b) / (1.5 + (-(q[1])) * (-(q[1]))) * q[0])
            + (-(v[1])) / self.a
            + 0.1 * x0 * q[1]
            + 0.1 * x1 * q[1]
    }
}

pub struct Straight8 {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl Straight8 {
    fn lagrangian(&self, q: [f64; 3], v: [f64; 3]) -> f64 {
        0.75 * v[0] * v[0]
            + 0.5 * self.a * v[1] * v[1]
            + 0.5 * v[2] * v[2]
            + v[0] * (((self.a) / 3.0) / (1.5 + ((2.0 + (q[0]).sin()).ln()) * ((2.0 + (q[0]).sin()).ln())))
            - (((q[0] + self.b).cos()) / 3.0)
            + (0.5 * ((1.0 + (q[1]) * (q[1])).sqrt())).tanh().powi(2)
    }
}

pub struct Straight9 {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl Straight9 {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let mut s = q[0] * q[0] * q[0];
        s += ((q[0]).atan()) / self.a;
        s -= (1.0 + (v[0]) * (v[0])).powf(0.5);
        0.5 * self.a * v[0] * v[0] + 0.75 * v[1] * v[1] + v[1] * (self.a * s * s * s) - (q[0] * -(q[0] + q[1]) * q[0])
            + ((q[1]).cos()) / 3.0
            + 0.1 * s * q[0]
    }
}

pub struct Straight10 {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl Straight10 {
    fn lagrangian(&self, q: [f64; 3], v: [f64; 3]) -> f64 {
        let x0 = q[0] * (1.0 + (q[0]) * (q[0])).powf(0.5) * q[0];
        let x1 = (0.5 * ((1.0 + (q[2]) * (q[2])).powf(0.5))).tanh().powi(3);
        0.5 * self.a * v[0] * v[0]
            + 0.75 * v[1] * v[1]
            + 0.5 * self.a * v[2] * v[2]
            + v[1] * ((2.0 * self.b * self.b * self.b) / (1.5 + ((q[1]) * (q[0])) * ((q[1]) * (q[0]))))
            - ((1.0
                + ((0.3 * ((1.0 + (v[1]) * (v[1])).sqrt())).tanh().exp())
                    * ((0.3 * ((1.0 + (v[1]) * (v[1])).sqrt())).tanh().exp()))
            .sqrt())
            + (2.0 * q[1] * q[1] * q[1]).abs() * q[1]
            + 0.1 * x0 * q[2]
            + 0.1 * x1 * q[1]
    }
}

pub struct Straight11 {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl Straight11 {
    fn lagrangian(&self, t: f64, q: [f64; 2], v: [f64; 2]) -> f64 {
        let x0 = (q[1] + 2.0).tanh();
        0.75 * v[0] * v[0] + 0.75 * v[1] * v[1] + v[0] * ((2.0 + (-(q[0])).sin()).ln())
            - ((0.25 * q[1] * q[1] * q[1]) / (1.5 + (((q[0]) / 3.0).cos()) * (((q[0]) / 3.0).cos())))
            + (0.5 * ((0.5 * (x0)).tanh().powi(2))).tanh().powi(2)
            + 0.1 * x0 * q[0]
            + 0.1 * t * q[1]
    }
}

pub struct Straight12 {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl Straight12 {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * self.a * v[0] * v[0] + 0.5 * self.a * v[1] * v[1] + v[0] * ((2.0 + ((q[0]).abs() * q[1]).sin()).ln())
            - (0.25 * self.a * self.a * self.a)
            + (0.3 * (-(q[1]))).tanh().exp()
    }
}

pub struct Straight13 {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl Straight13 {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let x0 = (2.0 + ((q[0]) * (q[0])).sin()).ln();
        0.5 * self.a * v[0] * v[0] + 0.5 * v[1] * v[1] + v[0] * ((-(q[1])) * ((q[0]) / (self.b + 1.0)))
            - ((0.5 * (q[0] * self.b * q[1] * self.b * q[0])).tanh().powi(3))
            + (1.0 + (q[1] * q[0] * q[1]) * (q[1] * q[0] * q[1])).powf(1.5)
            + 0.1 * x0 * q[1]
    }
}

pub struct Straight14 {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl Straight14 {
    fn lagrangian(&self, t: f64, q: [f64; 3], v: [f64; 3]) -> f64 {
        let x0 = q[0] * (2.0 + (q[1]).sin()).ln() * q[0];
        0.5 * self.a * v[0] * v[0]
            + 0.5 * v[1] * v[1]
            + 0.75 * v[2] * v[2]
            + v[1] * ((1.0 + ((1.0 + (x0) * (x0)).powf(0.5)) * ((1.0 + (x0) * (x0)).powf(0.5))).powf(0.5))
            - ((1.0
                + ((0.3 * ((1.0 + (q[2]) * (q[2])).sqrt())).tanh().exp())
                    * ((0.3 * ((1.0 + (q[2]) * (q[2])).sqrt())).tanh().exp()))
            .powf(0.5))
            + q[0]
            - (q[2])
            + (q[0]) * (q[1])
            + 0.1 * x0 * q[0]
            + 0.1 * t * q[0]
    }
}

pub struct Straight15 {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl Straight15 {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let x0 = ((q[0]).cos()) / self.a;
        let x1 = (q[1] - (q[1])).abs() * q[0];
        0.5 * v[0] * v[0]
            + 0.75 * v[1] * v[1]
            + v[0] * (((2.0) / 3.0) / (1.5 + ((0.5 * (q[0])).tanh().powi(4)) * ((0.5 * (q[0])).tanh().powi(4))))
            - ((1.0 + (((q[0]).cos()).abs() * q[0]) * (((q[0]).cos()).abs() * q[0])).powf(1.5))
            + ((0.3 * (q[1])).tanh().exp()) / (1.5 + (q[1] - (q[1])) * (q[1] - (q[1])))
            + 0.1 * x0 * q[1]
            + 0.1 * x1 * q[0]
    }
}

pub struct Straight16 {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl Straight16 {
    fn lagrangian(&self, q: [f64; 3], v: [f64; 3]) -> f64 {
        let x0 = (2.0 + ((1.0 + (q[0]) * (q[0])).sqrt()).sin()).ln();
        let x1 = -((1.0 + (x0) * (x0)).powf(0.5));
        0.5 * v[0] * v[0]
            + 0.5 * self.a * v[1] * v[1]
            + 0.75 * v[2] * v[2]
            + v[2] * ((1.0 + (q[1] - (q[1])) * (q[1] - (q[1]))).powf(self.b))
            - (self.a * self.b * self.b * self.b + (0.5 * (v[0])).tanh().powi(3) + (q[2]) * (1.3))
            + (0.3 * (self.a * q[1] * q[1] * q[1])).tanh().exp()
            + 0.1 * x0 * q[2]
            + 0.1 * x1 * q[0]
    }
}

pub struct Straight17 {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl Straight17 {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let x0 = ((v[0]) * (q[0])).abs() * self.a;
        0.75 * v[0] * v[0] + 0.5 * self.a * v[1] * v[1] + v[0] * ((2.0 + (q[1]).sin()).ln() - ((q[0]) / (self.b + 1.0)))
            - ((self.a * (0.5 * (x0)).tanh().powi(2) * self.a).atan())
            + (0.5 * ((0.5 * (v[0])).tanh().powi(3))).tanh().powi(3)
            + 0.1 * x0 * q[0]
    }
}

pub struct Straight18 {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl Straight18 {
    fn lagrangian(&self, q: [f64; 3], v: [f64; 3]) -> f64 {
        let x0 = ((0.5 * (q[0])).tanh().powi(2)) / (1.5 + ((q[2]).abs() * v[2]) * ((q[2]).abs() * v[2]));
        let x1 = -((q[2]).abs() * q[1]);
        let mut s = self.b * q[2] * self.b;
        s += (1.0 + ((2.0 + (x1).sin()).ln()) * ((2.0 + (x1).sin()).ln())).sqrt();
        s -= -(q[2]);
        0.5 * self.a * v[0] * v[0] + 0.75 * v[1] * v[1] + 0.75 * v[2] * v[2] + v[0] * (-((0.3 * (q[2])).tanh().exp()))
            - (q[2] * (0.5 * ((1.0 + (q[2]) * (q[2])).sqrt())).tanh().powi(3) * q[2])
            + (2.0 + (-(v[0])).sin()).ln()
            + 0.1 * x0 * q[0]
            + 0.1 * x1 * q[0]
            + 0.1 * s * q[2]
    }
}

pub struct Straight19 {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl Straight19 {
    fn lagrangian(&self, q: [f64; 3], v: [f64; 3]) -> f64 {
        0.5 * v[0] * v[0] + 0.75 * v[1] * v[1] + 0.75 * v[2] * v[2] + v[2] * (-(q[0]) + (q[0]).abs() * q[2])
            - (-((-0.7) * (0.5)) + ((q[1]) / (self.b + 1.0)).abs() * 2.0)
            + (0.3 * (q[2])).tanh().exp()
            + (q[2]) / 3.0
    }
}

pub struct Looped0<const N: usize> {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl<const N: usize> Looped0<N> {
    fn lagrangian(&self, t: f64, q: [f64; N], v: [f64; N]) -> f64 {
        let mut kinetic = 0.0;
        let mut potential = 0.0;
        for i in 0..N - 1 {
            let d = q[i + 1] - q[i];
            potential += 0.5 * d * d + ((0.3 * (d)).tanh().exp()).sin();
            kinetic += 0.5 * v[i] * v[i] + 0.25 * v[i] * v[i + 1] * (self.b - (v[i]));
        }
        kinetic += 0.5 * v[N - 1] * v[N - 1];
        for i in 0..N {
            potential -= (v[i]).abs() * q[i];
        }
        kinetic - potential + (2.0 + ((q[0]) / (1.5 + (q[1]) * (q[1]))).sin()).ln() + 0.1 * t * q[0]
    }
}

pub struct Looped1<const N: usize> {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl<const N: usize> Looped1<N> {
    fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
        let mut kinetic = 0.0;
        let mut potential = 0.0;
        for i in 0..N - 1 {
            let d = q[i + 1] - q[i];
            potential += 0.5 * d * d + (0.5 * ((q[i]) / (self.b + 1.0))).tanh().powi(3);
            kinetic += 0.5 * v[i] * v[i] + 0.25 * v[i] * v[i + 1] * ((0.3 * (v[i])).tanh().exp());
        }
        kinetic += 0.5 * v[N - 1] * v[N - 1];
        kinetic - potential + v[1] * (0.5 * (q[1])).tanh().powi(2) * v[1]
    }
}

pub struct Looped2<const N: usize> {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl<const N: usize> Looped2<N> {
    fn lagrangian(&self, t: f64, q: [f64; N], v: [f64; N]) -> f64 {
        let mut kinetic = 0.0;
        let mut potential = 0.0;
        for i in 0..N - 1 {
            let d = q[i + 1] - q[i];
            potential += 0.5 * d * d + (q[i + 1]).abs() * 2.0 - ((-0.7) / 3.0);
            kinetic += 0.5 * v[i] * v[i] + 0.25 * v[i] * v[i + 1] * ((v[i]).abs() * d);
        }
        kinetic += 0.5 * v[N - 1] * v[N - 1];
        kinetic - potential + q[0] - (-0.7) - ((0.5 * (q[1])).tanh().powi(3)) + 0.1 * t * q[0]
    }
}

pub struct Looped3<const N: usize> {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl<const N: usize> Looped3<N> {
    fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
        let mut kinetic = 0.0;
        let mut potential = 0.0;
        for i in 0..N - 1 {
            let d = q[i + 1] - q[i];
            potential += 0.5 * d * d + 2.0 * self.b * self.b * self.b;
            kinetic += 0.5 * v[i] * v[i] + 0.25 * v[i] * v[i + 1] * ((1.0 + (q[i + 1]) * (q[i + 1])).powf(0.5));
        }
        kinetic += 0.5 * v[N - 1] * v[N - 1];
        kinetic - potential + ((v[0]) * (q[1])).abs() * q[0]
    }
}

pub struct Looped4<const N: usize> {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl<const N: usize> Looped4<N> {
    fn lagrangian(&self, t: f64, q: [f64; N], v: [f64; N]) -> f64 {
        let mut kinetic = 0.0;
        let mut potential = 0.0;
        for i in 0..N - 1 {
            let d = q[i + 1] - q[i];
            potential += 0.5 * d * d + -((2.0 + (q[i]).sin()).ln());
            kinetic += 0.5 * v[i] * v[i] + 0.25 * v[i] * v[i + 1] * (self.a * d * d * d);
        }
        kinetic += 0.5 * v[N - 1] * v[N - 1];
        for i in 0..N {
            potential -= (v[i]).cos();
        }
        kinetic - potential + (0.3 * ((2.0 + (q[1]).sin()).ln())).tanh().exp() + 0.1 * t * q[0]
            - 0.1 * potential * potential
    }
}

pub struct Looped5<const N: usize> {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl<const N: usize> Looped5<N> {
    fn lagrangian(&self, t: f64, q: [f64; N], v: [f64; N]) -> f64 {
        let mut kinetic = 0.0;
        let mut potential = 0.0;
        for i in 0..N - 1 {
            let d = q[i + 1] - q[i];
            potential += 0.5 * d * d + ((q[i]) / (self.b + 1.0)).tanh();
            kinetic += 0.5 * v[i] * v[i] + 0.25 * v[i] * v[i + 1] * ((self.a) / 3.0);
        }
        kinetic += 0.5 * v[N - 1] * v[N - 1];
        kinetic - potential + self.a * q[0] * q[0] * q[0] + 0.1 * t * q[0] - 0.1 * potential * potential
    }
}

pub struct Looped6<const N: usize> {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl<const N: usize> Looped6<N> {
    fn lagrangian(&self, t: f64, q: [f64; N], v: [f64; N]) -> f64 {
        let mut kinetic = 0.0;
        let mut potential = 0.0;
        for i in 0..N - 1 {
            let d = q[i + 1] - q[i];
            potential += 0.5 * d * d + (q[i] - (q[i])) / (1.5 + (q[i] * 1.3 * q[i]) * (q[i] * 1.3 * q[i]));
            kinetic += 0.5 * v[i] * v[i] + 0.25 * v[i] * v[i + 1] * ((0.5 * (t)).tanh().powi(3));
        }
        kinetic += 0.5 * v[N - 1] * v[N - 1];
        for i in 0..N {
            potential -= (0.3 * (q[i])).tanh().exp();
        }
        kinetic - potential + (self.a - (2.0)) / 3.0 + 0.1 * t * q[0] - 0.1 * potential * potential
    }
}

pub struct Looped7<const N: usize> {
    pub a: f64,
    pub b: f64,
}

#[lagrangian]
impl<const N: usize> Looped7<N> {
    fn lagrangian(&self, q: [f64; N], v: [f64; N]) -> f64 {
        let mut kinetic = 0.0;
        let mut potential = 0.0;
        for i in 0..N - 1 {
            let d = q[i + 1] - q[i];
            potential += 0.5 * d * d + -((v[i]).abs() * v[1]);
            kinetic += 0.5 * v[i] * v[i] + 0.25 * v[i] * v[i + 1] * ((d) / 3.0);
        }
        kinetic += 0.5 * v[N - 1] * v[N - 1];
        for i in 0..N {
            potential -= (q[i]).tanh();
        }
        kinetic - potential + (1.0 + ((v[0]) * (q[0])) * ((v[0]) * (q[0]))).powf(0.5) - 0.1 * potential * potential
    }
}

/// Reordered sums and folded products round differently from the dual
/// path: a few ulps, relative to the largest component of the gradient
/// (and of the Hessian-vector product), with room for the cancellation
/// a random expression can have (the worst seen: 1.1e-14).
const TOLERANCE: f64 = 1e-13;

#[test]
fn random_bodies_have_gradient_code_that_agrees_with_dual_numbers() {
    let cases: Vec<(&str, f64, f64)> = vec![
        (
            "Straight0",
            worst_difference(&Straight0 { a: 1.9, b: 0.4 }, -1.5, 1.5, 60),
            scalar_difference(&Straight0 { a: 1.9, b: 0.4 }, -1.5, 1.5, 30),
        ),
        (
            "Straight1",
            worst_difference(&Straight1 { a: 1.9, b: 1.1 }, -1.5, 1.5, 60),
            scalar_difference(&Straight1 { a: 1.9, b: 1.1 }, -1.5, 1.5, 30),
        ),
        (
            "Straight2",
            worst_difference(&Straight2 { a: 1.9, b: 0.4 }, -1.5, 1.5, 60),
            scalar_difference(&Straight2 { a: 1.9, b: 0.4 }, -1.5, 1.5, 30),
        ),
        (
            "Straight3",
            worst_difference(&Straight3 { a: 1.9, b: 2.3 }, -1.5, 1.5, 60),
            scalar_difference(&Straight3 { a: 1.9, b: 2.3 }, -1.5, 1.5, 30),
        ),
        (
            "Straight4",
            worst_difference(&Straight4 { a: 1.9, b: 0.4 }, -1.5, 1.5, 60),
            scalar_difference(&Straight4 { a: 1.9, b: 0.4 }, -1.5, 1.5, 30),
        ),
        (
            "Straight5",
            worst_difference(&Straight5 { a: 1.9, b: 0.4 }, -1.5, 1.5, 60),
            scalar_difference(&Straight5 { a: 1.9, b: 0.4 }, -1.5, 1.5, 30),
        ),
        (
            "Straight6",
            worst_difference(&Straight6 { a: 1.9, b: 0.4 }, -1.5, 1.5, 60),
            scalar_difference(&Straight6 { a: 1.9, b: 0.4 }, -1.5, 1.5, 30),
        ),
        (
            "Straight7",
            worst_difference(&Straight7 { a: 1.9, b: 1.1 }, -1.5, 1.5, 60),
            scalar_difference(&Straight7 { a: 1.9, b: 1.1 }, -1.5, 1.5, 30),
        ),
        (
            "Straight8",
            worst_difference(&Straight8 { a: 0.7, b: 2.3 }, -1.5, 1.5, 60),
            scalar_difference(&Straight8 { a: 0.7, b: 2.3 }, -1.5, 1.5, 30),
        ),
        (
            "Straight9",
            worst_difference(&Straight9 { a: 1.9, b: 0.4 }, -1.5, 1.5, 60),
            scalar_difference(&Straight9 { a: 1.9, b: 0.4 }, -1.5, 1.5, 30),
        ),
        (
            "Straight10",
            worst_difference(&Straight10 { a: 1.9, b: 1.1 }, -1.5, 1.5, 60),
            scalar_difference(&Straight10 { a: 1.9, b: 1.1 }, -1.5, 1.5, 30),
        ),
        (
            "Straight11",
            worst_difference(&Straight11 { a: 1.9, b: 1.1 }, -1.5, 1.5, 60),
            scalar_difference(&Straight11 { a: 1.9, b: 1.1 }, -1.5, 1.5, 30),
        ),
        (
            "Straight12",
            worst_difference(&Straight12 { a: 0.7, b: 1.1 }, -1.5, 1.5, 60),
            scalar_difference(&Straight12 { a: 0.7, b: 1.1 }, -1.5, 1.5, 30),
        ),
        (
            "Straight13",
            worst_difference(&Straight13 { a: 1.9, b: 0.4 }, -1.5, 1.5, 60),
            scalar_difference(&Straight13 { a: 1.9, b: 0.4 }, -1.5, 1.5, 30),
        ),
        (
            "Straight14",
            worst_difference(&Straight14 { a: 0.7, b: 2.3 }, -1.5, 1.5, 60),
            scalar_difference(&Straight14 { a: 0.7, b: 2.3 }, -1.5, 1.5, 30),
        ),
        (
            "Straight15",
            worst_difference(&Straight15 { a: 1.2, b: 2.3 }, -1.5, 1.5, 60),
            scalar_difference(&Straight15 { a: 1.2, b: 2.3 }, -1.5, 1.5, 30),
        ),
        (
            "Straight16",
            worst_difference(&Straight16 { a: 1.9, b: 0.4 }, -1.5, 1.5, 60),
            scalar_difference(&Straight16 { a: 1.9, b: 0.4 }, -1.5, 1.5, 30),
        ),
        (
            "Straight17",
            worst_difference(&Straight17 { a: 1.9, b: 2.3 }, -1.5, 1.5, 60),
            scalar_difference(&Straight17 { a: 1.9, b: 2.3 }, -1.5, 1.5, 30),
        ),
        (
            "Straight18",
            worst_difference(&Straight18 { a: 1.9, b: 2.3 }, -1.5, 1.5, 60),
            scalar_difference(&Straight18 { a: 1.9, b: 2.3 }, -1.5, 1.5, 30),
        ),
        (
            "Straight19",
            worst_difference(&Straight19 { a: 0.7, b: 0.4 }, -1.5, 1.5, 60),
            scalar_difference(&Straight19 { a: 0.7, b: 0.4 }, -1.5, 1.5, 30),
        ),
        (
            "Looped0",
            worst_difference(&Looped0::<5> { a: 1.9, b: 2.3 }, -1.5, 1.5, 60),
            scalar_difference(&Looped0::<5> { a: 1.9, b: 2.3 }, -1.5, 1.5, 30),
        ),
        (
            "Looped1",
            worst_difference(&Looped1::<5> { a: 1.2, b: 2.3 }, -1.5, 1.5, 60),
            scalar_difference(&Looped1::<5> { a: 1.2, b: 2.3 }, -1.5, 1.5, 30),
        ),
        (
            "Looped2",
            worst_difference(&Looped2::<5> { a: 1.2, b: 1.1 }, -1.5, 1.5, 60),
            scalar_difference(&Looped2::<5> { a: 1.2, b: 1.1 }, -1.5, 1.5, 30),
        ),
        (
            "Looped3",
            worst_difference(&Looped3::<5> { a: 0.7, b: 1.1 }, -1.5, 1.5, 60),
            scalar_difference(&Looped3::<5> { a: 0.7, b: 1.1 }, -1.5, 1.5, 30),
        ),
        (
            "Looped4",
            worst_difference(&Looped4::<5> { a: 1.9, b: 2.3 }, -1.5, 1.5, 60),
            scalar_difference(&Looped4::<5> { a: 1.9, b: 2.3 }, -1.5, 1.5, 30),
        ),
        (
            "Looped5",
            worst_difference(&Looped5::<5> { a: 1.9, b: 0.4 }, -1.5, 1.5, 60),
            scalar_difference(&Looped5::<5> { a: 1.9, b: 0.4 }, -1.5, 1.5, 30),
        ),
        (
            "Looped6",
            worst_difference(&Looped6::<5> { a: 1.9, b: 2.3 }, -1.5, 1.5, 60),
            scalar_difference(&Looped6::<5> { a: 1.9, b: 2.3 }, -1.5, 1.5, 30),
        ),
        (
            "Looped7",
            worst_difference(&Looped7::<5> { a: 1.2, b: 1.1 }, -1.5, 1.5, 60),
            scalar_difference(&Looped7::<5> { a: 1.2, b: 1.1 }, -1.5, 1.5, 30),
        ),
    ];
    for (name, gradient, products) in &cases {
        println!("{name}: gradient {gradient:.1e}, Hessian-vector products {products:.1e}");
    }
    for (name, gradient, products) in cases {
        assert!(gradient <= TOLERANCE && products <= TOLERANCE, "{name}: {gradient:e}, {products:e}");
    }
}
