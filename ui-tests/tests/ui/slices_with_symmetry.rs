use lagrangian::prelude::*;

pub struct Chain {
    pub n: usize,
}

#[lagrangian(symmetry = translation(0))]
impl Chain {
    fn dimension(&self) -> usize {
        self.n
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        let mut l = 0.0;
        for i in 1..q.len() {
            l += 0.5 * v[i] * v[i] - (q[i] - q[i - 1]).powi(2);
        }
        l
    }
}

fn main() {}
