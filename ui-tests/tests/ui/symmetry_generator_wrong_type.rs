use lagrangian::prelude::*;

pub struct Pair;

// The generator maps `&[f64; 2]` to `[f64; 2]`; rustc checks the closure.
#[lagrangian(symmetry = generator(|_| [1.0, 1.0, 1.0]))]
impl Pair {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) - (q[1] - q[0]).cos()
    }
}

fn main() {}
