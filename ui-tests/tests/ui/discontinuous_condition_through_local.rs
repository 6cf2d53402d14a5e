//! A mass jump: the condition is a `bool` computed from `q` and `t` earlier
//! and combined with a constant flag; the error is at the condition.
use lagrangian::prelude::*;

pub struct Loaded {
    pub m: [f64; 2],
    pub on: bool,
}

#[lagrangian]
impl Loaded {
    fn lagrangian(&self, t: f64, q: [f64; 1], v: [f64; 1]) -> f64 {
        let inside = q[0] * q[0] < 1.0 + t;
        let heavy = inside && self.on;
        let m = if heavy { self.m[1] } else { self.m[0] };
        0.5 * m * v[0] * v[0]
    }
}

fn main() {}
