use lagrangian::prelude::*;

pub struct Driven {
    pub e: f64,
}

#[lagrangian]
impl Driven {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) - 0.5 * q[0] * q[0]
    }

    // One force per coordinate.
    fn force(&self, t: f64, _q: [f64; 2], _v: [f64; 2]) -> f64 {
        self.e * t.cos()
    }
}

fn main() {}
