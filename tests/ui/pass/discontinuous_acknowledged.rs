//! A potential step acknowledged with `#[lagrangian(discontinuous)]`: it
//! compiles, and the trait says so.
use lagrangian::Lagrangian;
use lagrangian::prelude::*;

pub struct Step {
    pub h: f64,
}

#[lagrangian(discontinuous)]
impl Step {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        let kinetic = 0.5 * v[0] * v[0];
        if q[0] > 0.0 { kinetic - self.h } else { kinetic }
    }
}

fn main() {
    assert!(<Step as Lagrangian<1>>::DISCONTINUOUS);
    let sim = Integrator::new(Step { h: 0.3 }, Midpoint, 0.01).start(0.0, [-1.0], [1.0]).unwrap();
    assert!((sim.energy().unwrap() - 0.5).abs() < 1e-12);
}
