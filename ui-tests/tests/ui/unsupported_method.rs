use lagrangian::prelude::*;

pub struct Lattice {
    pub k: f64,
}

impl Lattice {
    fn kinetic(&self, v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0]
    }
}

#[lagrangian]
impl Lattice {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        self.kinetic(v) - self.k * (q[0] - q[0].floor())
    }
}

fn main() {}
