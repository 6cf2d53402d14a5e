use lagrangian::prelude::*;

pub struct Pendulum {
    pub m: f64,
}

#[lagrangian]
impl Pendulum {
    fn lagrangian(&self, q: Vec<f64>, v: [f64; 1]) -> f64 {
        0.5 * self.m * v[0] * v[0] - q[0].cos()
    }
}

fn main() {}
