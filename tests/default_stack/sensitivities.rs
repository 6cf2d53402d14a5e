//! Derivatives of the trajectories of large systems in a thread with the
//! default 2 MiB stack: the forward sensitivities' size limit and its
//! refusal, and the adjoint of a chain of 1000 masses. Optimised, as the
//! rest of this binary: unoptimised frames of these sizes overflow it.
//! The values of the sensitivities and the adjoint are checked on small
//! systems by the verification tests (`tests/verification/sensitivities.rs`).

use lagrangian::SolveError;
use lagrangian::prelude::*;

use crate::parametric_chain::Chain;

/// `max |a − b| / max |b|`.
fn relative(a: &[f64], b: &[f64]) -> f64 {
    let scale = b.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    a.iter().zip(b).fold(0.0f64, |m, (x, y)| m.max((x - y).abs())) / scale
}

/// `Σ_k 10⁻³ |q_k|² + q_n·p_n`.
struct ChainLoss;

impl<const N: usize> Loss<N, 2> for ChainLoss {
    fn running<D: Scalar>(&self, _k: u64, _t: D, q: [D; N], _p: [D; N], _theta: &[D; 2]) -> D {
        q.iter().fold(D::zero(), |s, &x| s + x * x) * 1e-3
    }
    fn terminal<D: Scalar>(&self, _t: D, q: [D; N], p: [D; N], _theta: &[D; 2]) -> D {
        q.iter().zip(&p).fold(D::zero(), |s, (&x, &y)| s + x * y)
    }
}

/// Forward sensitivities of a system larger than
/// `FORWARD_SENSITIVITIES_MAX_N` are refused with a typed error that points
/// to the adjoint, in a thread with a 2 MiB stack (the refusal enters no
/// frame sized for the dense `N × N` tangent), and the largest size still
/// runs in that thread (the values are checked by the tests above on
/// smaller systems).
#[test]
fn forward_sensitivities_above_their_size_limit_are_refused_in_a_default_thread() {
    use lagrangian::problem::FORWARD_SENSITIVITIES_MAX_N;
    let run = || {
        let q0 = |i: usize| 0.1 * ((i as f64 + 1.0) * 0.7).sin();
        let large = Problem::new(Chain::<64> { theta: [1.0, 0.5] }, 0.0, core::array::from_fn(q0), [0.0; 64]);
        let refused = large.solve_with_sensitivities(&Scheme::MIDPOINT, 0.05, Plan::until(0.5));
        let message = match refused {
            Err(SolveError::Step(Error::Unsupported { what })) => what.to_string(),
            other => panic!("{:?}", other.map(|s| s.jacobians.len())),
        };
        const LIMIT: usize = FORWARD_SENSITIVITIES_MAX_N;
        let largest = Problem::new(Chain::<LIMIT> { theta: [1.0, 0.5] }, 0.0, core::array::from_fn(q0), [0.0; LIMIT]);
        let run = largest.solve_with_sensitivities(&Scheme::MIDPOINT, 0.05, Plan::until(0.5)).unwrap();
        let last = run.jacobians.last().unwrap();
        (message, last.rows, last.cols, last.data.iter().all(|x| x.is_finite()))
    };
    let (message, rows, cols, finite) =
        std::thread::Builder::new().stack_size(2 << 20).spawn(run).unwrap().join().unwrap();
    assert!(message.contains("Problem::gradient"), "{message}");
    // `2N` rows, `2N + P` columns (`P = 2`).
    let n = lagrangian::problem::FORWARD_SENSITIVITIES_MAX_N;
    assert_eq!((rows, cols, finite), (2 * n, 2 * n + 2, true));
}

/// The gradient of a loss of 10 midpoint steps of an FPU-β chain of 1000
/// masses (the stepper and the adjoint in reverse mode, on the tape), in a
/// thread with a 2 MiB stack: against central differences of plain solves
/// in `θ` and in some of the initial data. No frame on the way holds an
/// `N × N` matrix or several copies of the stepper.
#[test]
fn the_adjoint_of_a_thousand_masses_runs_in_a_two_mebibyte_thread() {
    const N: usize = 1000;
    const THETA: [f64; 2] = [1.0, 0.5];
    let (h, t_end) = (0.05, 0.5);
    let q0: [f64; N] = core::array::from_fn(|i| 0.1 * ((i as f64 + 1.0) * 0.7).sin());
    let v0: [f64; N] = core::array::from_fn(|i| 0.05 * ((i as f64 + 1.0) * 0.3).cos());
    let run = move || {
        // The loss of a plain run, stepped node by node.
        let value = |q0: &[f64; N], v0: &[f64; N], theta: [f64; 2]| -> f64 {
            let mut sim = Problem::new(Chain::<N> { theta }, 0.0, *q0, *v0).stepper(&Scheme::MIDPOINT, h).unwrap();
            let (mut j, mut last_h) = (0.0, None);
            loop {
                let s = sim.state();
                j += ChainLoss.running(s.step, s.t, s.q, s.p, &theta);
                if s.t >= t_end {
                    return j + ChainLoss.terminal(s.t, s.q, s.p, &theta);
                }
                sim.step_toward(t_end, last_h).unwrap();
                last_h = Some(sim.state().t - s.t);
            }
        };
        let problem = Problem::new(Chain::<N> { theta: THETA }, 0.0, q0, v0);
        let g = problem.gradient(&Scheme::MIDPOINT, h, t_end, &ChainLoss, Checkpoints::Budget(3)).unwrap();
        assert!((g.value - value(&q0, &v0, THETA)).abs() <= 1e-13 * g.value.abs());
        // (adjoint, central difference) of θ_0, θ_1, q0_0, q0_499, v0_999.
        let mut pairs = Vec::new();
        for j in 0..2 {
            let e = 1e-5 * THETA[j];
            let (mut up, mut down) = (THETA, THETA);
            up[j] += e;
            down[j] -= e;
            pairs.push((g.theta[j], (value(&q0, &v0, up) - value(&q0, &v0, down)) / (2.0 * e)));
        }
        let e = 1e-6;
        for (i, of_v) in [(0, false), (499, false), (999, true)] {
            let (mut up, mut down) = if of_v { (v0, v0) } else { (q0, q0) };
            up[i] += e;
            down[i] -= e;
            let fd = if of_v {
                (value(&q0, &up, THETA) - value(&q0, &down, THETA)) / (2.0 * e)
            } else {
                (value(&up, &v0, THETA) - value(&down, &v0, THETA)) / (2.0 * e)
            };
            pairs.push((if of_v { g.v0[i] } else { g.q0[i] }, fd));
        }
        pairs
    };
    let pairs = std::thread::Builder::new().stack_size(2 << 20).spawn(run).unwrap().join().unwrap();
    let (adjoint, fd): (Vec<f64>, Vec<f64>) = pairs.into_iter().unzip();
    let gap = relative(&adjoint, &fd);
    eprintln!("FPU-β N = 1000, 10 midpoint steps: adjoint {adjoint:?}, against central differences {gap:.1e}");
    assert!(gap <= 1e-7, "{gap:e}");
}
