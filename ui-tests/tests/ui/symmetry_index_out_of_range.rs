use lagrangian::prelude::*;

pub struct Kepler {
    pub mu: f64,
}

#[lagrangian(symmetry = rotation(0, 2))]
impl Kepler {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) + self.mu / (q[0] * q[0] + q[1] * q[1]).sqrt()
    }
}

fn main() {}
