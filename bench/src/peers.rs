//! The peers: ode_solvers' DOP853, differential-equations' DOP853 and its
//! adaptive Gauss–Legendre IRK, on the first-order form `y = (q, q̇)`.

use nalgebra034::SVector;

use crate::methods::{Method, Run};
use crate::problems::Model;

/// The first-order form of a model, as both crates want it.
struct Ode<'a, M, const N: usize>(&'a M);

impl<M: Model<N>, const N: usize> Ode<'_, M, N> {
    fn rhs<const D: usize>(&self, t: f64, y: &SVector<f64, D>, dy: &mut SVector<f64, D>) {
        let q: [f64; N] = core::array::from_fn(|i| y[i]);
        let v: [f64; N] = core::array::from_fn(|i| y[N + i]);
        let a = self.0.accel_at(t, &q, &v);
        for i in 0..N {
            dy[i] = v[i];
            dy[N + i] = a[i];
        }
    }
}

impl<M: Model<N>, const N: usize, const D: usize> ode_solvers::System<f64, SVector<f64, D>> for Ode<'_, M, N> {
    fn system(&self, t: f64, y: &SVector<f64, D>, dy: &mut SVector<f64, D>) {
        self.rhs(t, y, dy);
    }
}

impl<M: Model<N>, const N: usize, const D: usize> differential_equations::ode::ODE<f64, SVector<f64, D>>
    for Ode<'_, M, N>
{
    fn diff(&self, t: f64, y: &SVector<f64, D>, dydt: &mut SVector<f64, D>) {
        self.rhs(t, y, dydt);
    }
}

/// Largest number of steps a peer may take (then it reports its failure).
const MAX_STEPS: usize = 20_000_000;

/// Runs a peer with `rtol = atol = tol` to `t_end`; `samples > 0` records the
/// relative energy error at that many evenly spaced times (dense output).
pub(crate) fn run<M: Model<N>, const N: usize, const D: usize>(
    model: &M,
    (q0, v0): ([f64; N], [f64; N]),
    method: Method,
    tol: f64,
    t_end: f64,
    samples: usize,
) -> Run {
    let y0 = SVector::<f64, D>::from_fn(|i, _| if i < N { q0[i] } else { v0[i - N] });
    let e0 = model.energy(&q0, &v0);
    let energy_of = |y: &SVector<f64, D>| {
        let q: [f64; N] = core::array::from_fn(|i| y[i]);
        let v: [f64; N] = core::array::from_fn(|i| y[N + i]);
        (model.energy(&q, &v) - e0) / e0.abs().max(f64::MIN_POSITIVE)
    };
    let finish = |t: &[f64], y: &[SVector<f64, D>], steps: usize, evaluations: usize| -> Run {
        let Some(last) = y.last() else {
            return Run { failure: Some("no output".into()), ..Run::default() };
        };
        let q: Vec<f64> = (0..N).map(|i| last[i]).collect();
        let finite = q.iter().all(|x| x.is_finite());
        Run {
            q: if finite { q } else { Vec::new() },
            failure: (!finite).then(|| "non-finite state".to_string()),
            steps: steps as u64,
            evaluations: Some(evaluations as u64),
            energy: if samples > 0 { t.iter().zip(y).map(|(&t, y)| (t, energy_of(y))).collect() } else { Vec::new() },
            ..Run::default()
        }
    };
    match method {
        Method::OdeSolversDop853 => {
            let (dx, output) = if samples > 0 {
                (t_end / samples as f64, ode_solvers::OutputType::Dense)
            } else {
                // Sparse: the accepted steps only, without the extra stages of dense output.
                (t_end, ode_solvers::OutputType::Sparse)
            };
            let mut s = ode_solvers::Dop853::from_param(
                Ode(model),
                0.0,
                t_end,
                dx,
                y0,
                tol,
                tol,
                0.9,
                0.0,
                0.333,
                6.0,
                t_end,
                0.0,
                MAX_STEPS as u32,
                1000,
                output,
            );
            match s.integrate() {
                Ok(stats) => {
                    let run = finish(s.x_out(), s.y_out(), stats.accepted_steps as usize, stats.num_eval as usize);
                    // Sparse output ends at the last accepted step, which is t_end.
                    match s.x_out().last() {
                        Some(&t) if (t - t_end).abs() <= 1e-9 * t_end.abs().max(1.0) => run,
                        t => Run { failure: Some(format!("stopped at t = {t:?} before {t_end}")), ..run },
                    }
                }
                Err(e) => Run { failure: Some(e.to_string()), ..Run::default() },
            }
        }
        Method::DiffEqDop853 | Method::DiffEqGauss6 => {
            use differential_equations::prelude::*;
            let ode = Ode(model);
            let times: Vec<f64> = if samples > 0 {
                (0..=samples).map(|k| t_end * k as f64 / samples as f64).collect()
            } else {
                vec![t_end]
            };
            let problem = ODEProblem::new(&ode, 0.0, t_end, y0);
            let solution = if method == Method::DiffEqDop853 {
                let mut m = ExplicitRungeKutta::dop853().rtol(tol).atol(tol).max_steps(MAX_STEPS);
                problem.t_eval(times).solve(&mut m)
            } else {
                let mut m = ImplicitRungeKutta::gauss_legendre_6().rtol(tol).atol(tol).max_steps(MAX_STEPS);
                problem.t_eval(times).solve(&mut m)
            };
            match solution {
                Ok(sol) => finish(&sol.t, &sol.y, sol.steps.accepted, sol.evals.function),
                Err(e) => Run { failure: Some(format!("{e:?}")), ..Run::default() },
            }
        }
        m => Run { failure: Some(format!("{} is not a peer", m.name())), ..Run::default() },
    }
}
