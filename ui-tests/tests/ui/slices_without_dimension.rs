use lagrangian::prelude::*;

pub struct Chain {
    pub n: usize,
}

#[lagrangian]
impl Chain {
    fn lagrangian(&self, q: &[f64], v: &[f64]) -> f64 {
        let mut l = 0.0;
        for i in 0..q.len() {
            l += 0.5 * v[i] * v[i] - q[i].cos();
        }
        l
    }
}

fn main() {
    let _ = <Chain as DynLagrangian>::AUTONOMOUS;
}
