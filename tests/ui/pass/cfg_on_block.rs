//! `#[cfg]` on the whole block, one block per configuration: the trait
//! implementation follows the block that exists.
use lagrangian::prelude::*;

pub struct Spring {
    pub k: f64,
}

#[lagrangian]
#[cfg(debug_assertions)]
impl Spring {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] - 0.5 * self.k * q[0] * q[0]
    }
}

#[lagrangian]
#[cfg(not(debug_assertions))]
impl Spring {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] - 0.5 * self.k * q[0] * q[0]
    }
}

fn main() {
    let sim = Integrator::new(Spring { k: 4.0 }, Midpoint, 0.01).start(0.0, [1.0], [0.0]).unwrap();
    assert!((sim.energy().unwrap() - 2.0).abs() < 1e-12);
}
