use lagrangian::lagrangian;

struct Oscillator;

#[lagrangian]
impl Oscillator {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] - 0.5 * q[0] * q[0]
    }

    fn step_density(&self) -> f64 {
        1.0
    }
}

fn main() {}
