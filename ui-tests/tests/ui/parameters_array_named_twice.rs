use lagrangian::prelude::*;

#[derive(Clone)]
pub struct Springs {
    m: f64,
    k: [f64; 3],
}

#[lagrangian(parameters(k: [f64; 3], m, k))]
impl Springs {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * self.m * v[0] * v[0] - 0.5 * self.k[0] * q[0] * q[0]
    }
}

fn main() {}
