use lagrangian::prelude::*;

pub struct Particle {
    pub m: f64,
}

#[lagrangian]
impl Particle {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        let r = q[0].hypot(q[1]);
        let bump = match r > 1.0 {
            true => 1.0,
            false => 0.0,
        };
        0.5 * self.m * (v[0] * v[0] + v[5] * v[1]) - r - bump
    }

    fn dissipation(&self, _q: [f64; 3], v: [f64; 2]) -> f64 {
        0.1 * v[0] * v[0]
    }
}

fn main() {}
