use lagrangian::prelude::*;

pub struct Particle {
    pub m: f64,
    pub c: f64,
}

#[lagrangian]
impl Particle {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * self.m * (v[0] * v[0] + v[1] * v[1]) - q[1]
    }

    fn force(&self, _q: [f64; 2], v: [f64; 2]) -> [f64; 3] {
        [-self.c * v[0], -self.c * v[1], 0.0]
    }
}

fn main() {}
