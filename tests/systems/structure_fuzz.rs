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
use lagrangian::{Composition, Derivatives, Method};

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
        kinetic - potential - self.b * (q[2] * q[3] * (q[2]).sin()).tanh() + 0.5 * 0.3 * v[4] * v[5]
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
        kinetic - potential - self.a * (0.5 * (q[2] - q[0])).tanh().powi(3) - self.a * (0.5 * (q[3] - q[0])).tanh()
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
            - (self.b * t).cos() * (0.5 * (q[3])).tanh().powi(3)
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
        kinetic - potential - self.b * (q[3] * q[4] * (0.5 * (q[3])).tanh()).tanh() + 0.5 * 0.3 * v[3] * v[4]
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
            - self.b * (q[2] * q[4] * (q[2]).sin()).tanh()
            - self.b * (q[2] * q[2] * (0.5 * (q[2])).tanh()).tanh()
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
            - self.b * (q[0] * q[1] * 0.5 * (q[0]) * (q[0])).tanh()
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
            potential += self.a * (0.5 * (d)).tanh().powi(3);
            kinetic += 0.1 * v[i] * v[i + 2];
        }
        kinetic - potential - self.b * (q[3] * q[3] * (0.5 * (q[3])).tanh().powi(3)).tanh()
            + self.b * v[1] * (0.5 * (q[1])).tanh().powi(3)
            - self.b * (q[1] * q[3] * (0.5 * (q[1])).tanh().powi(3)).tanh()
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
            + 0.5 * (1.5 + ((0.5 * (q[4])).tanh().powi(3))) * v[3] * v[5]
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
            - self.a * (0.5 * (q[3] - q[2])).tanh().powi(3)
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

/// The same system with its structure hidden: the general Newton path.
struct Hidden<S>(S);

impl<S: Lagrangian<N>, const N: usize> Lagrangian<N> for Hidden<S> {
    const AUTONOMOUS: bool = S::AUTONOMOUS;
    const CYCLIC: [bool; N] = S::CYCLIC;
    fn lagrangian<D: Scalar>(&self, t: D, q: [D; N], v: [D; N]) -> D {
        self.0.lagrangian(t, q, v)
    }
}

/// The largest difference in `q` and `p` between two integrators over `n` steps.
fn difference<A: Lagrangian<N>, B: Lagrangian<N>, M: Method<f64>, const N: usize>(
    mut a: Integrator<A, M, N>,
    mut b: Integrator<B, M, N>,
    n: usize,
) -> f64 {
    let mut worst = 0.0f64;
    for _ in 0..n {
        a.step().unwrap();
        b.step().unwrap();
        for i in 0..N {
            worst = worst.max((a.state().q[i] - b.state().q[i]).abs());
            worst = worst.max((a.state().p[i] - b.state().p[i]).abs());
        }
    }
    worst
}

/// Every path a random system can take gives the same steps, to round-off
/// amplified over the run: trapezoid steps (explicit Störmer–Verlet where
/// the mass matrix is proven constant) against Newton on the hidden system;
/// Yoshida 4 likewise (fused explicit sub-steps); midpoint steps in forward
/// mode (hyper-duals, dense solves) against reverse mode (the gradient code
/// on lane duals, banded solves of the proven band).
fn paths_agree<S: Lagrangian<N>, const N: usize>(name: &str, system: impl Fn() -> S) -> [f64; 3] {
    let q0: [f64; N] = core::array::from_fn(|i| 0.3 + 0.2 * (i as f64).sin());
    let v0: [f64; N] = core::array::from_fn(|i| 0.1 * (1.7 * i as f64).cos());
    let h = 0.01;
    let start = |m| (Integrator::new(system(), m, h).start(0.0, q0, v0).unwrap());
    let trapezoid = difference(
        Integrator::new(system(), Trapezoid, h).start(0.0, q0, v0).unwrap(),
        Integrator::new(Hidden(system()), Trapezoid, h).start(0.0, q0, v0).unwrap(),
        300,
    );
    let yoshida = difference(
        Integrator::new(system(), Composition::YOSHIDA4, h).start(0.0, q0, v0).unwrap(),
        Integrator::new(Hidden(system()), Composition::YOSHIDA4, h).start(0.0, q0, v0).unwrap(),
        100,
    );
    let modes = difference(
        start(Midpoint),
        Integrator::new(system(), Midpoint, h).derivatives(Derivatives::Reverse).start(0.0, q0, v0).unwrap(),
        300,
    );
    println!("{name}: trapezoid {trapezoid:.1e}, Yoshida 4 {yoshida:.1e}, forward/reverse midpoint {modes:.1e}");
    for (what, found) in [("trapezoid", trapezoid), ("Yoshida 4", yoshida), ("forward/reverse midpoint", modes)] {
        assert!(found <= TOLERANCE, "{name}: {what} paths differ by {found:e}");
    }
    [trapezoid, yoshida, modes]
}

/// Round-off, amplified over at most three time units of smooth motion
/// (measured: at most 1.8e-15); a wrong step (a wrong mass matrix, a wrong
/// gradient, a wrong band) shows at `O(h²)`.
const TOLERANCE: f64 = 1e-13;

#[test]
fn random_bodies_step_the_same_on_every_path() {
    let mut worst = [0.0f64; 3];
    let found = paths_agree("random 0", || Random0::<5> { a: 1.2, b: 1.1 });
    for k in 0..3 {
        worst[k] = worst[k].max(found[k]);
    }
    let found = paths_agree("random 1", || Random1::<6> { a: 1.2, b: 1.1 });
    for k in 0..3 {
        worst[k] = worst[k].max(found[k]);
    }
    let found = paths_agree("random 2", || Random2::<4> { a: 1.2, b: 1.1 });
    for k in 0..3 {
        worst[k] = worst[k].max(found[k]);
    }
    let found = paths_agree("random 3", || Random3::<4> { a: 1.2, b: 0.4 });
    for k in 0..3 {
        worst[k] = worst[k].max(found[k]);
    }
    let found = paths_agree("random 4", || Random4::<5> { a: 1.2, b: 0.4 });
    for k in 0..3 {
        worst[k] = worst[k].max(found[k]);
    }
    let found = paths_agree("random 5", || Random5::<5> { a: 0.7, b: 1.1 });
    for k in 0..3 {
        worst[k] = worst[k].max(found[k]);
    }
    let found = paths_agree("random 6", || Random6::<4> { a: 0.7, b: 0.4 });
    for k in 0..3 {
        worst[k] = worst[k].max(found[k]);
    }
    let found = paths_agree("random 7", || Random7::<4> { a: 1.2, b: 0.4 });
    for k in 0..3 {
        worst[k] = worst[k].max(found[k]);
    }
    let found = paths_agree("random 8", || Random8::<6> { a: 0.7, b: 0.4 });
    for k in 0..3 {
        worst[k] = worst[k].max(found[k]);
    }
    let found = paths_agree("random 9", || Random9::<5> { a: 1.2, b: 0.4 });
    for k in 0..3 {
        worst[k] = worst[k].max(found[k]);
    }
    let found = paths_agree("random 10", || Random10::<6> { a: 0.7, b: 0.4 });
    for k in 0..3 {
        worst[k] = worst[k].max(found[k]);
    }
    let found = paths_agree("random 11", || Random11::<5> { a: 0.7, b: 1.1 });
    for k in 0..3 {
        worst[k] = worst[k].max(found[k]);
    }
    let found = paths_agree("random 12", || Random12::<4> { a: 0.7, b: 1.1 });
    for k in 0..3 {
        worst[k] = worst[k].max(found[k]);
    }
    let found = paths_agree("random 13", || Random13::<6> { a: 0.7, b: 0.4 });
    for k in 0..3 {
        worst[k] = worst[k].max(found[k]);
    }
    let found = paths_agree("random 14", || Random14::<4> { a: 0.7, b: 1.1 });
    for k in 0..3 {
        worst[k] = worst[k].max(found[k]);
    }
    let found = paths_agree("random 15", || Random15::<4> { a: 0.7, b: 0.4 });
    for k in 0..3 {
        worst[k] = worst[k].max(found[k]);
    }
    println!(
        "largest differences: trapezoid {:.1e}, Yoshida 4 {:.1e}, forward/reverse midpoint {:.1e}",
        worst[0], worst[1], worst[2]
    );
}
