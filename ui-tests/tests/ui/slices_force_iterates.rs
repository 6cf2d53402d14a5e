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
        0.5 * v[0] * v[0] - q[0].cos()
    }

    fn force(&self, _q: &[f64], v: &[f64], f: &mut [f64]) {
        f.copy_from_slice(v);
    }
}

fn main() {
    let _ = DynLagrangian::dimension(&Chain { n: 2 });
}
