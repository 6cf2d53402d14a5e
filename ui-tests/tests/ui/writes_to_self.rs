use lagrangian::prelude::*;

pub struct Pendulum {
    pub m: f64,
    pub last_q: f64,
}

#[lagrangian]
impl Pendulum {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        self.last_q = q[0];
        0.5 * self.m * v[0] * v[0] - q[0].cos()
    }
}

fn main() {}
