use lagrangian::prelude::*;

pub struct Pendulum {
    pub m: f64,
}

#[lagrangian]
impl Pendulum {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        let square = |x: f64| x * x;
        println!("q = {}", q[0]);
        0.5 * self.m * square(v[0]) - q[0].cos()
    }
}

fn main() {}
