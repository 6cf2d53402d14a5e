//! `signum` of a velocity jumps at rest.
use lagrangian::prelude::*;

pub struct Ratchet {
    pub a: f64,
}

#[lagrangian]
impl Ratchet {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] + self.a * v[0].signum() * q[0]
    }
}

fn main() {}
