//! Luo, Guo, Li & Wu §V, on the run `examples/perturbed_pendulum.rs` records: the
//! energy-preserving steps follow the pendulum and the slow perturbation.

#[path = "../../examples/support/perturbed.rs"]
mod perturbed;

use perturbed::PERTURBATION;

#[test]
fn steps_follow_the_swing_and_the_slow_perturbation() {
    let nodes = perturbed::record(10_000.0).expect("the run of Luo, Guo, Li & Wu §V completes");
    assert!(nodes.len() > 15_000, "{} steps", nodes.len());
    assert!(nodes.iter().all(|n| n.tau > 0.0));

    // τ smallest near θ = 0 and largest near the extremes of θ, swing by
    // swing (Luo, Guo, Li & Wu Fig. 3; site density ∝ (V''p² + V'²)^{1/3}, (4.8)).
    // Measured: 100% and 100% of ~3100 swings.
    let swing = perturbed::swing_statistics(&nodes);
    assert!(swing.swings > 3000, "{swing:?}");
    assert!(swing.smallest_near_zero >= 0.95 && swing.largest_near_extreme >= 0.95, "{swing:?}");

    // The slow modulation, from the envelope of τ: measured 314.2 s against
    // 2π/0.02 = 314.16 s. Scanned over [157, 628] s, so a wrong period (or
    // none: a flat envelope fits any period equally) would be far off.
    let expected = std::f64::consts::TAU / PERTURBATION;
    let envelope = perturbed::envelope(&nodes);
    let period = perturbed::modulation_period(&envelope, (0.5 * expected, 2.0 * expected));
    assert!((period - expected).abs() <= 0.01 * expected, "period {period} s, expected {expected} s");
    // And the modulation is a real one: the envelope's spread is far above
    // its noise (measured: τ in [0.458, 0.529]).
    let (lo, hi) = envelope.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), p| (lo.min(p.1), hi.max(p.1)));
    assert!(hi - lo > 0.03, "envelope in [{lo}, {hi}]");
}
