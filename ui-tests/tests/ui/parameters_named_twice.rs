use lagrangian::prelude::*;

#[derive(Clone)]
pub struct Spring {
    m: f64,
    k: f64,
}

#[lagrangian(parameters(k, m, k))]
impl Spring {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * self.m * v[0] * v[0] - 0.5 * self.k * q[0] * q[0]
    }
}

fn main() {}
