//! A hanging chain of planar links in Cartesian coordinates, run-time
//! sized: the large-`N` system of the constraint tests.
#![allow(dead_code, missing_docs, unreachable_pub)]

use lagrangian::prelude::*;
use lagrangian::{Coupling, Pattern, Separability};

/// `links` unit links with unit point masses at the joints, hanging from a
/// pivot at the origin under unit gravity; coordinates
/// `(x₁, y₁, …, x_n, y_n)`. Written against the trait by hand: the
/// structure of the constraint Jacobian is found by `DynConstrained`.
#[derive(Clone, Debug)]
pub struct Links(pub usize);

impl DynLagrangian for Links {
    const AUTONOMOUS: bool = true;
    const SEPARABILITY: Separability = Separability::ConstantMass;
    const COUPLING: Coupling = Coupling { q_q: Pattern::Diagonal, q_v: Pattern::Diagonal, v_v: Pattern::Diagonal };

    fn dimension(&self) -> usize {
        2 * self.0
    }

    fn lagrangian<D: Scalar>(&self, _: D, q: &[D], v: &[D]) -> D {
        let mut l = D::from(0.0);
        for i in 0..self.0 {
            l += (v[2 * i] * v[2 * i] + v[2 * i + 1] * v[2 * i + 1]) * 0.5 - q[2 * i + 1];
        }
        l
    }

    fn constraint_count(&self) -> usize {
        self.0
    }

    fn constraints<D: Scalar>(&self, _: D, q: &[D], g: &mut [D]) {
        let (mut x, mut y) = (D::from(0.0), D::from(0.0));
        for r in 0..self.0 {
            let (dx, dy) = (q[2 * r] - x, q[2 * r + 1] - y);
            g[r] = dx * dx + dy * dy - 1.0;
            x = q[2 * r];
            y = q[2 * r + 1];
        }
    }
}

/// The chain folded: link `r` goes sideways by `±c` and down by `s`, so
/// that the joints stay within `0 ≤ x < 1`, `|y| ≤ s·links`.
pub fn folded(links: usize, s: f64) -> Vec<f64> {
    let c = (1.0 - s * s).sqrt();
    (0..2 * links)
        .map(|i| {
            if i % 2 == 1 {
                -s * (i / 2 + 1) as f64
            } else if (i / 2) % 2 == 0 {
                c
            } else {
                0.0
            }
        })
        .collect()
}

/// `max |xᵢ|`.
pub fn max_abs(x: &[f64]) -> f64 {
    x.iter().fold(0.0f64, |m, v| m.max(v.abs()))
}

/// Steps a chain of `links` links folded with `s = 0.01`, at rest, `steps`
/// midpoint steps of `h` under `DynConstrained` (`rule` with quadrature
/// points): the largest `|g|` and `|G v|/|v|` over the nodes, the largest
/// coordinate, and the saddle-point bandwidth.
pub fn run<R: DiscreteLagrangian>(
    links: usize,
    rule: R,
    h: f64,
    steps: usize,
) -> Result<(f64, f64, f64, usize), Error> {
    let q0 = folded(links, 0.01);
    let mut sim = DynConstrained::start(Links(links), rule, h, 0.0, &q0, &vec![0.0; 2 * links])?;
    let (mut g_worst, mut gv_worst) = (0.0f64, 0.0f64);
    sim.run(steps, |s| {
        g_worst = s.constraint_values().iter().fold(g_worst, |m, x| m.max(x.abs()));
        let speed = max_abs(s.velocity());
        gv_worst = s.constraint_velocities().iter().fold(gv_worst, |m, x| m.max(x.abs() / speed));
    })?;
    Ok((g_worst, gv_worst, max_abs(&sim.state().q), sim.saddle_point_bandwidth()))
}
