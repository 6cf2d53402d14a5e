//! Time-transformed (Sundman–Poincaré) adaptive steps on Kepler e = 0.9 and
//! e = 0.99 (docs/time-transformation.md).
use lagrangian::prelude::*;
use lagrangian::time_transform::SStepper;
use std::f64::consts::PI;

/// Planar Kepler, μ = 1, Cartesian.
#[derive(Debug, Clone, Copy)]
pub struct Kepler;

#[lagrangian]
impl Kepler {
    fn lagrangian(&self, q: [f64; 2], v: [f64; 2]) -> f64 {
        0.5 * (v[0] * v[0] + v[1] * v[1]) + 1.0 / (q[0] * q[0] + q[1] * q[1]).sqrt()
    }
}

/// `E − e sin E = m` by Newton safeguarded with bisection on `[m − e, m + e]`.
fn eccentric_anomaly(e: f64, m: f64) -> f64 {
    let (mut lo, mut hi) = (m - e, m + e);
    let mut ea = m + e * m.sin();
    for _ in 0..100 {
        let f = ea - e * ea.sin() - m;
        if f > 0.0 {
            hi = ea;
        } else {
            lo = ea;
        }
        let mut next = ea - f / (1.0 - e * ea.cos());
        if !(next > lo && next < hi) {
            next = 0.5 * (lo + hi);
        }
        let d = (next - ea).abs();
        ea = next;
        if d <= f64::EPSILON * ea.abs().max(1.0) {
            break;
        }
    }
    ea
}

/// Position on the orbit with a = 1, pericentre on +x at t = 0.
fn kepler_position(e: f64, t: f64) -> [f64; 2] {
    let ea = eccentric_anomaly(e, t);
    [ea.cos() - e, (1.0 - e * e).sqrt() * ea.sin()]
}

fn kepler_start(e: f64) -> ([f64; 2], [f64; 2]) {
    ([1.0 - e, 0.0], [0.0, ((1.0 + e) / (1.0 - e)).sqrt()])
}

fn r32() -> RadiusPower<2> {
    RadiusPower::new([0, 1], 1.5).unwrap()
}

#[test]
fn explore() {
    for e in [0.9, 0.99] {
        let (q0, v0) = kepler_start(e);
        for sigma in [0.04, 0.02, 0.01] {
            let mut sim = TimeTransformed::new(Kepler, r32()).rule(Midpoint, sigma).start::<3>(0.0, q0, v0).unwrap();
            let e0 = sim.energy().unwrap();
            let pt0 = sim.time_momentum();
            let mut worst = 0.0f64;
            let mut worst_pt = 0.0f64;
            let t_end = 10.0 * 2.0 * PI;
            sim.run_until(t_end, |s| {
                worst = worst.max(((s.energy().unwrap() - e0) / e0).abs());
                worst_pt = worst_pt.max((s.time_momentum() - pt0).abs());
            })
            .unwrap();
            let q = sim.state().q;
            let x = kepler_position(e, t_end);
            let err = ((q[0] - x[0]).powi(2) + (q[1] - x[1]).powi(2)).sqrt();
            let d = sim.inner().s_tangent_map().map(|m| m.symplecticity_defect());
            println!(
                "e {e} sigma {sigma}: steps {} newton {} err {err:.3e} dE {worst:.3e} dpt {worst_pt:.3e} t {} defect {d:?}",
                sim.stats().steps,
                sim.stats().newton_iterations,
                sim.state().t
            );
        }
    }
}
