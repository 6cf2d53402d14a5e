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

    fn force(&self, t: f64, _q: &[f64], _v: &[f64], f: &[f64]) {
        let _ = f[0] * t;
    }
}

fn main() {
    let _ = DynLagrangian::dimension(&Chain { n: 2 });
}
