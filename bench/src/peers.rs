//! The peers: ode_solvers' DOP853, differential-equations' DOP853 and its
//! adaptive Gauss–Legendre IRK, on the first-order form `y = (q, q̇)`.

use nalgebra034::SVector;

use crate::invariants::Invariants;
use crate::methods::Method;
use crate::problems::Model;
use crate::run::Run;

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

/// `(energy, angular momentum)` error samples `(t, error)`, and constraint
/// error samples `(t, errors)` of a model with constraints.
type Samples = (Vec<(f64, f64)>, Vec<(f64, f64)>, Vec<(f64, [f64; 2])>);

/// Runs a peer with `rtol = atol = tol` to `t_end`; `samples > 0` records the
/// relative energy error at the accepted step at or after each of that many
/// evenly spaced times (no dense output: see the comments below).
pub(crate) fn run<M: Model<N>, const N: usize, const D: usize>(
    model: &M,
    (q0, v0): ([f64; N], [f64; N]),
    method: Method,
    tol: f64,
    t_end: f64,
    samples: usize,
) -> Run {
    let y0 = SVector::<f64, D>::from_fn(|i, _| if i < N { q0[i] } else { v0[i - N] });
    let invariants = Invariants::new(model, &q0, &v0);
    let split = |y: &SVector<f64, D>| -> ([f64; N], [f64; N]) {
        (core::array::from_fn(|i| y[i]), core::array::from_fn(|i| y[N + i]))
    };
    // `(energy, momentum, constraints)` samples at the accepted steps `ks`.
    let sample = |t: &[f64], y: &[SVector<f64, D>], ks: Vec<usize>| -> Samples {
        let mut energy = Vec::with_capacity(ks.len());
        let mut momentum = Vec::new();
        let mut constraints = Vec::new();
        for k in ks {
            let (q, v) = split(&y[k]);
            energy.push((t[k], invariants.energy(&q, &v)));
            if let Some(l) = invariants.momentum(&q, &v) {
                momentum.push((t[k], l));
            }
            if let Some(c) = invariants.constraints(&q, &v) {
                constraints.push((t[k], c));
            }
        }
        (energy, momentum, constraints)
    };
    // The final state from the last output; `energy` the samples.
    let finish =
        |y: &[SVector<f64, D>], steps: usize, evaluations: usize, (energy, momentum, constraints): Samples| -> Run {
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
                energy,
                momentum,
                constraints,
                ..Run::default()
            }
        };
    match method {
        Method::OdeSolversDop853 => {
            // Always sparse output (the accepted steps), also when energy samples are asked for:
            // ode_solvers 0.6's dense output appends `x_end` as soon as the next output time is
            // within 1e-9 of it, which happens one step early when `x_end` is a multiple of `dx`;
            // it then extrapolates that step's interpolant to `x_end` (`θ > 1`), and that value is
            // also the last output, taken here as `q(T)` (Kepler e = 0.9, 1000 orbits: energy
            // error 0.85 at T and a wrong final position, against 4e-11 at the accepted steps).
            // Samples at accepted steps measure the integrator's own error, not its interpolant's.
            let mut s = ode_solvers::Dop853::from_param(
                Ode(model),
                0.0,
                t_end,
                t_end,
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
                ode_solvers::OutputType::Sparse,
            );
            match s.integrate() {
                Ok(stats) => {
                    let (t, y) = (s.x_out(), s.y_out());
                    let samples = sample(t, y, sample_indices(t, t_end, samples));
                    let run = finish(y, stats.accepted_steps as usize, stats.num_eval as usize, samples);
                    // Sparse output ends at the last accepted step, which is t_end.
                    match t.last() {
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
            let problem = ODEProblem::new(&ode, 0.0, t_end, y0);
            // Samples at accepted steps too (the default output: every step); only the final
            // state otherwise. Its dense output at `t_eval` is sound, but on Kepler e = 0.9 it
            // adds an interpolation error of 2e-7 in the energy where the steps have 1e-10.
            let solution = match (method, samples > 0) {
                (Method::DiffEqDop853, true) => {
                    problem.solve(&mut ExplicitRungeKutta::dop853().rtol(tol).atol(tol).max_steps(MAX_STEPS))
                }
                (Method::DiffEqDop853, false) => problem
                    .t_eval([t_end])
                    .solve(&mut ExplicitRungeKutta::dop853().rtol(tol).atol(tol).max_steps(MAX_STEPS)),
                (_, true) => {
                    problem.solve(&mut ImplicitRungeKutta::gauss_legendre_6().rtol(tol).atol(tol).max_steps(MAX_STEPS))
                }
                (_, false) => problem
                    .t_eval([t_end])
                    .solve(&mut ImplicitRungeKutta::gauss_legendre_6().rtol(tol).atol(tol).max_steps(MAX_STEPS)),
            };
            match solution {
                Ok(sol) => {
                    let samples = sample(&sol.t, &sol.y, sample_indices(&sol.t, t_end, samples));
                    let run = finish(&sol.y, sol.steps.accepted, sol.evals.function, samples);
                    match sol.t.last() {
                        Some(&t) if (t - t_end).abs() <= 1e-9 * t_end.abs().max(1.0) => run,
                        t => Run { failure: Some(format!("stopped at t = {t:?} before {t_end}")), ..run },
                    }
                }
                Err(e) => Run { failure: Some(format!("{e:?}")), ..Run::default() },
            }
        }
        m => Run { failure: Some(format!("{} is not a peer", m.name())), ..Run::default() },
    }
}

/// Indices of the accepted steps `t` to sample: the first step at or after
/// each of `samples` evenly spaced times in `(0, t_end]`, and the initial
/// state, each once (none when `samples == 0`). The same rule as the
/// project's and the compositions' samples, which also fall on steps.
pub(crate) fn sample_indices(t: &[f64], t_end: f64, samples: usize) -> Vec<usize> {
    if samples == 0 || t.is_empty() {
        return Vec::new();
    }
    let every = t_end / samples as f64;
    let mut next = every;
    let mut keep = vec![0];
    for (k, &tk) in t.iter().enumerate().skip(1) {
        if tk >= next * (1.0 - 1e-12) {
            keep.push(k);
            while next <= tk * (1.0 + 1e-12) {
                next += every;
            }
        }
    }
    keep
}
