use lagrangian::prelude::*;

pub struct Damped {
    pub c: f64,
}

#[lagrangian]
impl Damped {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] - 0.5 * q[0] * q[0]
    }

    // A Rayleigh function has no time argument: time-dependent forces go in `force`.
    fn dissipation(&self, t: f64, _q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * self.c * t * v[0] * v[0]
    }
}

fn main() {}
