use lagrangian::prelude::*;

pub struct Particle {
    pub m: f64,
}

#[lagrangian]
impl Particle {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * self.m * (v[0] * v[0] + v[1] * v[1]) - q[2]
    }
}

fn main() {}
