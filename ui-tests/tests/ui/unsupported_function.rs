use lagrangian::prelude::*;

pub struct Pendulum {
    pub m: f64,
}

fn potential(angle: f64) -> f64 {
    -angle.cos()
}

#[lagrangian]
impl Pendulum {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * self.m * v[0] * v[0] - potential(q[0])
    }
}

fn main() {}
