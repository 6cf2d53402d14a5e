use lagrangian::prelude::*;

pub struct Chain {
    pub n: usize,
}

#[lagrangian]
impl Chain {
    fn dimension(&self) -> usize {
        self.n
    }

    fn lagrangian(&self, q: &[f64], v: &[f32]) -> f64 {
        let kinetic = 0.5 * v[0] * v[0];
        kinetic as f64 - q[0].cos()
    }
}

fn main() {}
