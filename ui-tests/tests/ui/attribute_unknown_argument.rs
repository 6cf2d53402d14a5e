use lagrangian::prelude::*;

pub struct Free;

#[lagrangian(symmetries = translation(0))]
impl Free {
    fn lagrangian(&self, _q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0]
    }
}

fn main() {}
