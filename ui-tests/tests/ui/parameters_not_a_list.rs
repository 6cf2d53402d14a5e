use lagrangian::prelude::*;

#[derive(Clone)]
pub struct Spring {
    k: f64,
}

#[lagrangian(parameters = k)]
impl Spring {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] - 0.5 * self.k * q[0] * q[0]
    }
}

fn main() {}
