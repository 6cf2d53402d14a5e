use lagrangian::prelude::*;

#[derive(Clone)]
pub struct Springs {
    k: [f32; 3],
}

#[lagrangian(parameters(k: [f32; 3]))]
impl Springs {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] - 0.5 * self.k[0] as f64 * q[0] * q[0]
    }
}

fn main() {}
