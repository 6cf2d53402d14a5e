use lagrangian::prelude::*;

pub struct Damped {
    pub c: f64,
}

#[lagrangian]
impl Damped {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) - q[1]
    }

    // The dissipation function is a scalar; its force −∂R/∂v is derived.
    fn dissipation(&self, _q: [f64; 2], v: [f64; 2]) -> [f64; 2] {
        [-self.c * v[0], -self.c * v[1]]
    }
}

fn main() {}
