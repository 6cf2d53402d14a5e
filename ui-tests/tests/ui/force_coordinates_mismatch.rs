use lagrangian::prelude::*;

pub struct Driven {
    pub e: f64,
}

#[lagrangian]
impl Driven {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) - 0.5 * q[0] * q[0]
    }

    fn force(&self, _q: [f64; 3], _v: [f64; 2]) -> [f64; 2] {
        [self.e, 0.0]
    }
}

fn main() {}
