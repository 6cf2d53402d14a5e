//! A potential step: the `if` on `q` makes the Lagrangian jump.
use lagrangian::prelude::*;

pub struct Step {
    pub h: f64,
}

#[lagrangian]
impl Step {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        let kinetic = 0.5 * v[0] * v[0];
        if q[0] > 0.0 { kinetic - self.h } else { kinetic }
    }
}

fn main() {}
