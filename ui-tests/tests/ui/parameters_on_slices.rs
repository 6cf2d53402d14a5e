use lagrangian::prelude::*;

#[derive(Clone)]
pub struct Chain {
    n: usize,
    k: f64,
}

#[lagrangian(parameters(k))]
impl Chain {
    fn dimension(&self) -> usize {
        self.n
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        0.5 * v[0] * v[0] - 0.5 * self.k * q[0] * q[0]
    }
}

fn main() {}
