use lagrangian::prelude::*;

pub struct Pendulum {
    pub m: f64,
    pub sine: bool,
}

#[lagrangian]
impl Pendulum {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        let c = f64::cos;
        let trig = if self.sine { f64::sin } else { f64::cos };
        0.5 * self.m * v[0] * v[0] + c(q[0]) + trig(q[0])
    }
}

fn main() {
    let _ = Integrator::new(Pendulum { m: 1.0, sine: false }, Midpoint, 0.01).start(0.0, [1.0], [0.0]);
}
