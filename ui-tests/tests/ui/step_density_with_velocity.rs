use lagrangian::lagrangian;

struct Kepler;

#[lagrangian]
impl Kepler {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) + 1.0 / (q[0] * q[0] + q[1] * q[1]).sqrt()
    }

    fn step_density(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        (q[0] * q[0] + q[1] * q[1]).powf(0.75) + 0.0 * v[0]
    }
}

fn main() {
    // The block's error is the only one: the type is still a system and a
    // monitor (stub implementations), so this line adds none.
    let _ = lagrangian::TimeTransformed::with_own_density(Kepler);
}
