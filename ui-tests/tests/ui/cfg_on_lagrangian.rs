use lagrangian::prelude::*;

pub struct Spring {
    pub k: f64,
}

#[lagrangian]
impl Spring {
    #[cfg(debug_assertions)]
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] - 0.5 * self.k * q[0] * q[0]
    }

    #[cfg(not(debug_assertions))]
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] - self.k * q[0] * q[0]
    }
}

fn main() {}
