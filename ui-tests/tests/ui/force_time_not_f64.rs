use lagrangian::prelude::*;

pub struct Driven {
    pub e: f64,
}

#[lagrangian]
impl Driven {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] - 0.5 * q[0] * q[0]
    }

    fn force(&self, t: u32, _q: [f64; 1], _v: [f64; 1]) -> [f64; 1] {
        [self.e * t as f64]
    }
}

fn main() {}
