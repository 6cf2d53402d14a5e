use lagrangian::prelude::*;

pub struct Friction {
    pub mu: f64,
}

// A type error in the `f64` method is rustc's to report, once: the macro sees
// the mismatch too and generates no code that would repeat it.
#[lagrangian]
impl Friction {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        let sign = if v[0] { 1.0 } else { -1.0 };
        0.5 * v[0] * v[0] - self.mu * sign * q[0]
    }
}

fn main() {}
