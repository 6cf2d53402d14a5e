//! Run-time-sized forms: a generic block, `self: &Self`, a typed slice
//! local, `v.len()` bounds, a time argument and an acknowledged jump.
use lagrangian::prelude::*;

pub struct Chain<T> {
    pub masses: Vec<f64>,
    pub tag: T,
}

#[lagrangian(discontinuous)]
impl<T> Chain<T> {
    fn dimension(self: &Self) -> usize {
        self.masses.len()
    }

    fn lagrangian(&self, t: f64, q: &[f64], v: &[f64]) -> f64 {
        let x: &[f64] = q;
        let mut l = 0.0;
        for i in 0..v.len() {
            l += 0.5 * self.masses[i] * v[i] * v[i];
        }
        for i in 1..x.len() {
            l -= (x[i] - x[i - 1]).powi(2);
        }
        if q[0] > 1.0 { l - t } else { l }
    }
}

fn main() {
    let chain = Chain { masses: vec![1.0, 2.0], tag: () };
    let _ = &chain.tag;
    assert!(<Chain<()> as DynLagrangian>::DISCONTINUOUS && !<Chain<()> as DynLagrangian>::AUTONOMOUS);
    let l = DynLagrangian::lagrangian(&chain, 0.5, &[0.0, 1.0], &[1.0, 1.0]);
    assert_eq!(l, 0.5 + 1.0 - 1.0);
    assert_eq!(DynLagrangian::dimension(&chain), 2);
    let l = DynLagrangian::lagrangian(&chain, 0.5, &[2.0, 2.0], &[0.0, 0.0]);
    assert_eq!(l, -0.5);
}
