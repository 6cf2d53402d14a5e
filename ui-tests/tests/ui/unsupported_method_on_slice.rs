use lagrangian::prelude::*;

pub struct Chain {
    pub n: usize,
}

#[lagrangian]
impl Chain {
    fn dimension(&self) -> usize {
        self.n
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        let mut l = 0.0;
        for i in 0..q.len() {
            l += 0.5 * v[i] * v[i];
        }
        l - q.iter().map(|x| x.cos()).sum::<f64>()
    }
}

fn main() {}
