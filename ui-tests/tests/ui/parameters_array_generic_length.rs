use lagrangian::prelude::*;

#[derive(Clone)]
pub struct Springs<const K: usize> {
    k: [f64; K],
}

#[lagrangian(parameters(k: [f64; K]))]
impl<const K: usize> Springs<K> {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] - 0.5 * self.k[0] * q[0] * q[0]
    }
}

fn main() {}
