use lagrangian::lagrangian;

struct Pendulum;

#[lagrangian]
impl Pendulum {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) - q[1]
    }

    fn constraints(&self, q: [f64; 2]) -> [f64; 0] {
        []
    }
}

fn main() {}
