use lagrangian::prelude::*;

pub struct Free;

const X: usize = 0;

#[lagrangian(symmetry = translation(X))]
impl Free {
    fn lagrangian(&self, _q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0]
    }
}

fn main() {}
