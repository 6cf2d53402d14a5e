use lagrangian::prelude::*;

pub struct Chain {
    pub n: usize,
    pub c: f64,
}

#[lagrangian]
impl Chain {
    fn dimension(&self) -> usize {
        self.n
    }

    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        0.5 * v[0] * v[0] - q[0].cos()
    }

    fn force(&self, q: &[f64], v: &[f64]) -> Vec<f64> {
        q.iter().zip(v).map(|(_, v)| -self.c * v).collect()
    }
}

fn main() {
    let _ = DynLagrangian::dimension(&Chain { n: 2, c: 0.1 });
}
