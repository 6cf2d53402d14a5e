use lagrangian::lagrangian;

struct Driven;

#[lagrangian]
impl Driven {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * v[0] * v[0] - 0.5 * q[0] * q[0]
    }

    fn step_density(&self, t: f32, q: [f64; 1]) -> f64 {
        1.0 + q[0] * q[0] + t as f64
    }
}

fn main() {}
