//! `solve(Plan)` of a Galerkin rule on a run-time-sized system: the same
//! driver as the other run-time methods, with the step polynomial as the
//! rule's own dense output, as at a compile-time size
//! ([`GalerkinPolynomial`](crate::dense::GalerkinPolynomial)).

use crate::dense::{HermiteRows, Interpolant, Point};
use crate::error::Error;
use crate::integrator::{DynIntegrator, RunTimeGalerkin, Stats};
use crate::solution::{Plan, Solution, Solvable, SolveError, solve};
use crate::system::DynLagrangian;

/// A Galerkin step's polynomial `q(t_0 + τh) = q_0 + Σ_m ℓ_m(τ) D_m`
/// through its `s + 1` control nodes, at a run-time size.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct StepPolynomial {
    t0: f64,
    h: f64,
    /// `τ_0 = 0, τ_1, …, τ_s`.
    tau: Vec<f64>,
    q0: Vec<f64>,
    /// `D_m = Q_m − q_0`, coordinate `i`'s at `i·s + m − 1`.
    d: Vec<f64>,
}

impl Interpolant<Vec<f64>> for StepPolynomial {
    fn eval(&self, t: f64) -> (Vec<f64>, Vec<f64>) {
        let s = self.tau.len() - 1;
        let x = (t - self.t0) / self.h;
        let mut q = self.q0.clone();
        let mut v = vec![0.0; q.len()];
        // ℓ_m and ℓ_m' for m = 1 … s (ℓ_0 multiplies Q_0 − Q_0 = 0), in the
        // order of the compile-time size's polynomial.
        for m in 1..=s {
            let (mut value, mut slope) = (1.0, 0.0);
            for k in (0..=s).filter(|&k| k != m) {
                let w = 1.0 / (self.tau[m] - self.tau[k]);
                slope = slope * (x - self.tau[k]) * w + value * w;
                value *= (x - self.tau[k]) * w;
            }
            for (i, (q, v)) in q.iter_mut().zip(v.iter_mut()).enumerate() {
                let d = self.d[i * s + m - 1];
                *q += value * d;
                *v += slope * d / self.h;
            }
        }
        (q, v)
    }
}

/// [`Solvable`] for a Galerkin rule at a run-time size: as for the
/// one-point rules (cubic or no Hermite, no acceleration), with the step
/// polynomial as the native dense output.
pub(crate) struct RunTimeGalerkinSize<S>(core::marker::PhantomData<S>);

impl<S: DynLagrangian + Clone> Solvable for RunTimeGalerkinSize<S> {
    type Sim = DynIntegrator<S, RunTimeGalerkin>;
    type Vector = Vec<f64>;
    type Native = StepPolynomial;
    type Hermite = HermiteRows;
    const ACCELERATION: bool = false;

    fn width(sim: &Self::Sim) -> usize {
        sim.dimension()
    }

    fn time(sim: &Self::Sim) -> f64 {
        sim.state().t
    }

    fn node(sim: &Self::Sim) -> (u64, f64, Vec<f64>, Vec<f64>) {
        let s = sim.state();
        (s.step, s.t, s.q.clone(), s.p.clone())
    }

    fn velocity(sim: &Self::Sim) -> Result<Vec<f64>, Error> {
        sim.velocity()
    }

    fn stats(sim: &Self::Sim) -> Stats {
        *sim.stats()
    }

    fn step_toward(sim: &mut Self::Sim, t_end: f64, _last_h: Option<f64>) -> Result<(), Error> {
        if sim.lands(t_end) { sim.run_until(t_end, |_| {}) } else { sim.step().map(|_| ()) }
    }

    fn land(sim: &mut Self::Sim, t: f64) -> Result<(), Error> {
        sim.run_until(t, |_| {})
    }

    /// The polynomial of the step just taken, `start → end`.
    fn native(sim: &Self::Sim, start: &Point<Vec<f64>>, end: &Point<Vec<f64>>) -> StepPolynomial {
        match sim.galerkin_nodes() {
            Some((h, d, tau)) => {
                StepPolynomial { t0: start.t, h, tau: tau.to_vec(), q0: start.q.clone(), d: d.to_vec() }
            }
            // No step taken: the constant polynomial at the node.
            None => StepPolynomial {
                t0: start.t,
                h: (end.t - start.t).max(f64::MIN_POSITIVE),
                tau: vec![0.0, 1.0],
                q0: start.q.clone(),
                d: end.q.iter().zip(&start.q).map(|(b, a)| b - a).collect(),
            },
        }
    }

    fn hermite(start: &Point<Vec<f64>>, end: &Point<Vec<f64>>, a: Option<(&Vec<f64>, &Vec<f64>)>) -> HermiteRows {
        HermiteRows::new(start, end, a)
    }

    fn energy(sim: &Self::Sim, t: f64, q: &Vec<f64>, v: &Vec<f64>) -> f64 {
        sim.energy_at(t, q, v)
    }

    fn momentum(sim: &Self::Sim, t: f64, q: &Vec<f64>, v: &Vec<f64>) -> Vec<f64> {
        sim.momentum_at(t, q, v)
    }

    fn acceleration(_sim: &Self::Sim, _t: f64, _q: &Vec<f64>, _v: &Vec<f64>) -> Option<Vec<f64>> {
        None
    }
}

/// Integrates a run-time-sized Galerkin stepper as `plan` says.
pub(crate) fn solve_galerkin<S: DynLagrangian + Clone>(
    sim: &mut DynIntegrator<S, RunTimeGalerkin>,
    plan: Plan<'_>,
) -> Result<Solution, SolveError> {
    solve::<RunTimeGalerkinSize<S>>(sim, plan)
}
