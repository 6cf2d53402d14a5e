use lagrangian::prelude::*;

pub struct Chain {
    pub n: u32,
}

#[lagrangian]
impl Chain {
    fn dimension(&self, scale: u32) -> u32 {
        self.n * scale
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        0.5 * v[0] * v[0] - q[0].cos()
    }
}

fn main() {}
