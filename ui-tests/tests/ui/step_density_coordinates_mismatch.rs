use lagrangian::lagrangian;

struct Kepler;

#[lagrangian]
impl Kepler {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) + 1.0 / (q[0] * q[0] + q[1] * q[1]).sqrt()
    }

    fn step_density(&self, q: [f64; 3]) -> f64 {
        q[0]
    }
}

fn main() {}
