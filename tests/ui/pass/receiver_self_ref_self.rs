//! `self: &Self` is `&self` written out; it is accepted, and the system runs.
use lagrangian::prelude::*;

pub struct Pendulum {
    pub m: f64,
}

#[lagrangian]
impl Pendulum {
    fn lagrangian(self: &Self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * self.m * v[0] * v[0] + q[0].cos()
    }
}

fn main() {
    let mut sim = Integrator::new(Pendulum { m: 1.0 }, Midpoint, 0.01).start(0.0, [1.0], [0.0]).unwrap();
    sim.run(10, |_| {}).unwrap();
    assert!(sim.state().q[0] < 1.0);
}
