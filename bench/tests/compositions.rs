//! The hand-written compositions have their orders (2, 6, 8), fitted on the
//! pendulum against its exact solution over a short horizon.

use lagrangian_bench::compositions::Composition;
use lagrangian_bench::methods::{Method, Setting};
use lagrangian_bench::problem;

fn fitted_order(n: &[usize], err: &[f64]) -> f64 {
    let x: Vec<f64> = n.iter().map(|&n| (1.0 / n as f64).ln()).collect();
    let y: Vec<f64> = err.iter().map(|e| e.ln()).collect();
    let (mx, my) = (x.iter().sum::<f64>() / x.len() as f64, y.iter().sum::<f64>() / y.len() as f64);
    let sxy: f64 = x.iter().zip(&y).map(|(a, b)| (a - mx) * (b - my)).sum();
    let sxx: f64 = x.iter().map(|a| (a - mx) * (a - mx)).sum();
    sxy / sxx
}

#[test]
fn compositions_have_their_orders() {
    let p = problem::all(0.1).into_iter().find(|p| p.id() == "pendulum").unwrap();
    let t = p.horizon();
    let reference = p.reference(t, 1e-14).unwrap();
    // Step counts where each error is far above round-off and in the asymptotic regime.
    for (method, c, counts) in [
        (Method::Verlet, Composition::Verlet, [400, 566, 800, 1131, 1600]),
        (Method::Yoshida6, Composition::Yoshida6, [100, 119, 141, 168, 200]),
        (Method::KahanLi8, Composition::KahanLi8, [150, 178, 212, 252, 300]),
    ] {
        let err: Vec<f64> = counts
            .iter()
            .map(|&n| {
                let run = p.run(method, Setting::Steps(n), t, 0);
                (run.q[0] - reference.q[0]).abs()
            })
            .collect();
        assert!(err.iter().all(|&e| e > 1e-12), "{method:?}: {err:?}");
        let order = fitted_order(&counts, &err);
        assert!((order - c.order() as f64).abs() < 0.3, "{method:?}: order {order:.3}, errors {err:?}");
    }
}

#[test]
fn weights_are_symmetric_and_consistent() {
    for c in [Composition::Verlet, Composition::Yoshida6, Composition::KahanLi8] {
        let w = c.weights();
        assert_eq!(w.len(), [1, 7, 15][c as usize]);
        assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-14, "{c:?}");
        // Order ≥ 3 of a symmetric composition needs Σγ³ = 0.
        if c != Composition::Verlet {
            assert!(w.iter().map(|g| g * g * g).sum::<f64>().abs() < 1e-13, "{c:?}");
        }
        assert!(w.iter().zip(w.iter().rev()).all(|(a, b)| a == b));
    }
}

/// The compensated steps (`Stepper::step_compensated`, the bench's baseline
/// for the generated steps' bookkeeping) are the same scheme: they follow the
/// plain ones to round-off on the pendulum, for every composition.
#[test]
fn compensated_steps_follow_the_plain_ones() {
    use lagrangian_bench::compositions::Stepper;
    let pendulum = |q: &[f64; 1]| [-q[0].sin()];
    for c in [Composition::Verlet, Composition::Yoshida6, Composition::KahanLi8] {
        let mut plain = Stepper::new(c, [1.0], &pendulum, 0.05, [1.0], [0.0]);
        let mut compensated = plain.clone();
        for _ in 0..2000 {
            plain.step(&pendulum);
            compensated.step_compensated(&pendulum);
        }
        let (dq, dp) = ((plain.q[0] - compensated.q[0]).abs(), (plain.p[0] - compensated.p[0]).abs());
        assert!(dq < 1e-12 && dp < 1e-12, "{c:?}: |Δq| = {dq:e}, |Δp| = {dp:e}");
        // 100 time units: the trajectories have moved, the test compares motion.
        assert!((plain.q[0] - 1.0).abs() > 1e-3, "{c:?}");
    }
}
