//! [`Problem`]: a [`Model`] behind a trait object, so the report can loop
//! over problems of different dimensions; and the reference solutions.

use lagrangian::prelude::*;
use serde::{Deserialize, Serialize};

use crate::cartesian;
use crate::constrained::CartesianDoublePendulum;
use crate::integrate;
use crate::methods::{Method, Setting};
use crate::problems::{self as p, Dd, Model};
use crate::run::Run;

/// How a reference solution was obtained and checked.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Reference {
    /// `q(t_end)`.
    pub q: Vec<f64>,
    /// `"exact"` (closed form in double-double) or `"double-double galerkin"`.
    pub kind: String,
    /// What was compared with what.
    pub check: String,
    /// The difference of that comparison, `max|Δq|`.
    pub agreement: f64,
    /// The largest difference accepted.
    pub accepted: f64,
    /// Seconds spent.
    pub seconds: f64,
}

/// A problem of any dimension.
pub trait Problem: Send + Sync {
    /// Short name (command line, file names).
    fn id(&self) -> &'static str;
    /// Title.
    fn title(&self) -> &'static str;
    /// Degrees of freedom.
    fn dim(&self) -> usize;
    /// Final time of the work–precision runs.
    fn horizon(&self) -> f64;
    /// First step count of the calibration sweeps.
    fn coarsest_steps(&self) -> usize;
    /// Typical period.
    fn time_scale(&self) -> f64;
    /// `(q0, v0)`.
    fn initial(&self) -> (Vec<f64>, Vec<f64>);
    /// Whether the hand-written compositions apply.
    fn separable(&self) -> bool;
    /// Whether the energy is conserved (see [`Model::CONSERVATIVE`]); runs
    /// of other problems record no energy errors.
    fn conservative(&self) -> bool;
    /// Whether the problem has a step density for the time-transformed methods.
    fn time_transform(&self) -> bool;
    /// Whether the problem has holonomic constraints: its runs then record
    /// the constraint errors, and the report shows them.
    fn constrained(&self) -> bool {
        false
    }
    /// Whether `method` applies to this problem.
    fn applies(&self, method: Method) -> bool {
        (!method.needs_separable() || self.separable())
            && (!method.needs_time_transform() || self.time_transform())
            && (!method.needs_constraints() || self.constrained())
    }
    /// One run (see [`integrate::run`]).
    fn run(&self, method: Method, setting: Setting, t_end: f64, samples: usize) -> Run;
    /// The same run from other initial data (bad-input classes of the stress section).
    fn run_from(&self, q0: Vec<f64>, v0: Vec<f64>, method: Method, setting: Setting, t_end: f64) -> Run;
    /// `q(t_end)` of a double-double Galerkin run (`s = 8`, `n` steps, Newton
    /// to 1e-30), rounded to `f64`. Needs a large stack for many degrees of freedom.
    fn double_double_galerkin(&self, t_end: f64, n: usize) -> Result<Vec<f64>, String>;
    /// The reference `q(t_end)`, checked: an exact solution in double-double
    /// against its `f64` evaluation, or a double-double Galerkin run (`s = 8`)
    /// against one with twice the steps; fails when they differ by more than
    /// `tolerance · max(1, max|q|)`.
    fn reference(&self, t_end: f64, tolerance: f64) -> Result<Reference, String>;
}

/// Adapts a [`Model`] with `N` degrees of freedom (`D = 2N`).
pub struct Adapter<M, const N: usize, const D: usize>(pub M);

fn max_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max)
}

/// The reference of problem `id` at `t_end` if it passed its check (the
/// agreement within the accepted difference; NaN fails).
fn passed(id: &str, t_end: f64, r: Reference) -> Result<Reference, String> {
    if r.agreement.partial_cmp(&r.accepted).is_none_or(|o| o.is_gt()) {
        return Err(format!(
            "reference for {id} at t = {t_end} failed its check ({}): difference {:.3e} > {:.3e}",
            r.check, r.agreement, r.accepted
        ));
    }
    Ok(r)
}

fn galerkin_dd<M: Model<N>, const N: usize>(model: &M, t_end: f64, n: usize) -> Result<[Dd; N], String> {
    let (q0, v0) = model.initial();
    let h = Dd::from(t_end) / n as f64;
    let mut sim = GalerkinIntegrator::new(model.system(), Galerkin::<8, 8, Dd>::gauss(), h)
        .newton(NewtonOptions { rtol: 1e-30, ..NewtonOptions::default() })
        .start(Dd::from(0.0), q0.map(Dd::from), v0.map(Dd::from))
        .map_err(|e| e.to_string())?;
    sim.run(n, |_| {}).map_err(|e| e.to_string())?;
    Ok(sim.state().q)
}

impl<M: Model<N>, const N: usize, const D: usize> Problem for Adapter<M, N, D>
where
    M: 'static,
{
    fn id(&self) -> &'static str {
        M::ID
    }
    fn title(&self) -> &'static str {
        M::TITLE
    }
    fn dim(&self) -> usize {
        N
    }
    fn horizon(&self) -> f64 {
        self.0.horizon()
    }
    fn coarsest_steps(&self) -> usize {
        self.0.coarsest_steps()
    }
    fn time_scale(&self) -> f64 {
        self.0.time_scale()
    }
    fn initial(&self) -> (Vec<f64>, Vec<f64>) {
        let (q, v) = self.0.initial();
        (q.to_vec(), v.to_vec())
    }
    fn separable(&self) -> bool {
        self.0.inverse_mass().is_some()
    }
    fn conservative(&self) -> bool {
        M::CONSERVATIVE
    }
    fn time_transform(&self) -> bool {
        M::TIME_TRANSFORM
    }
    fn run(&self, method: Method, setting: Setting, t_end: f64, samples: usize) -> Run {
        integrate::run::<M, N, D>(&self.0, self.0.initial(), method, setting, t_end, samples)
    }
    fn run_from(&self, q0: Vec<f64>, v0: Vec<f64>, method: Method, setting: Setting, t_end: f64) -> Run {
        let (Ok(q0), Ok(v0)) = (<[f64; N]>::try_from(q0), <[f64; N]>::try_from(v0)) else {
            return Run { failure: Some(format!("initial data must have {N} components")), ..Run::default() };
        };
        integrate::run::<M, N, D>(&self.0, (q0, v0), method, setting, t_end, 0)
    }
    fn double_double_galerkin(&self, t_end: f64, n: usize) -> Result<Vec<f64>, String> {
        Ok(galerkin_dd(&self.0, t_end, n)?.iter().map(|x| x.to_f64()).collect())
    }
    fn reference(&self, t_end: f64, tolerance: f64) -> Result<Reference, String> {
        let start = crate::clock::Clock::start();
        let (q, kind, check, agreement, scale) = match (self.0.exact(Dd::from(t_end)), self.0.exact(t_end)) {
            (Some(q), Some(f)) => {
                // The same closed form in f64: catches a formula that did not converge.
                let q: Vec<f64> = q.iter().map(|x| x.to_f64()).collect();
                let d = max_diff(&q, &f);
                let scale = q.iter().fold(1.0f64, |m, x| m.max(x.abs()));
                (q, "exact", "closed form in double-double against the same in f64".to_string(), d, scale * 1e3)
            }
            _ => {
                let n = self.0.reference_steps(t_end);
                let coarse = galerkin_dd(&self.0, t_end, n)?;
                let fine = galerkin_dd(&self.0, t_end, 2 * n)?;
                // Compared in double-double: rounded to f64 first, the two would often be equal.
                let d = coarse.iter().zip(&fine).map(|(a, b)| (*a - *b).abs().to_f64()).fold(0.0, f64::max);
                let fine: Vec<f64> = fine.iter().map(|x| x.to_f64()).collect();
                let scale = fine.iter().fold(1.0f64, |m, x| m.max(x.abs()));
                let check = format!("double-double Galerkin s = 8 with {n} against {} steps", 2 * n);
                (fine, "double-double galerkin", check, d, scale)
            }
        };
        let accepted = tolerance * scale;
        passed(
            M::ID,
            t_end,
            Reference { q, kind: kind.to_string(), check, agreement, accepted, seconds: start.seconds() },
        )
    }
}

impl Problem for CartesianDoublePendulum {
    fn id(&self) -> &'static str {
        Self::ID
    }
    fn title(&self) -> &'static str {
        Self::TITLE
    }
    fn dim(&self) -> usize {
        4
    }
    fn horizon(&self) -> f64 {
        self.angles().horizon()
    }
    fn coarsest_steps(&self) -> usize {
        self.angles().coarsest_steps()
    }
    fn time_scale(&self) -> f64 {
        self.angles().time_scale()
    }
    fn initial(&self) -> (Vec<f64>, Vec<f64>) {
        let (q, v) = self.initial_state();
        (q.to_vec(), v.to_vec())
    }
    fn separable(&self) -> bool {
        false
    }
    fn conservative(&self) -> bool {
        true
    }
    fn time_transform(&self) -> bool {
        false
    }
    fn constrained(&self) -> bool {
        true
    }
    fn applies(&self, method: Method) -> bool {
        Self::method_applies(method)
    }
    fn run(&self, method: Method, setting: Setting, t_end: f64, samples: usize) -> Run {
        self.integrate(self.initial_state(), method, setting, t_end, samples)
    }
    fn run_from(&self, q0: Vec<f64>, v0: Vec<f64>, method: Method, setting: Setting, t_end: f64) -> Run {
        let (Ok(q0), Ok(v0)) = (<[f64; 4]>::try_from(q0), <[f64; 4]>::try_from(v0)) else {
            return Run { failure: Some("initial data must have 4 components".into()), ..Run::default() };
        };
        self.integrate((q0, v0), method, setting, t_end, 0)
    }
    /// The angle problem's double-double Galerkin run, mapped to Cartesian positions.
    fn double_double_galerkin(&self, t_end: f64, n: usize) -> Result<Vec<f64>, String> {
        let theta = galerkin_dd(&self.angles(), t_end, n)?;
        Ok(cartesian::to_cartesian(&theta, &[Dd::from(0.0); 2]).0.iter().map(|x| x.to_f64()).collect())
    }
    /// The angle problem's reference (double-double Galerkin `s = 8`
    /// against twice the steps), each run mapped to Cartesian positions in
    /// double-double and compared there.
    fn reference(&self, t_end: f64, tolerance: f64) -> Result<Reference, String> {
        let start = crate::clock::Clock::start();
        let angles = self.angles();
        let n = angles.reference_steps(t_end);
        let position = |theta: [Dd; 2]| cartesian::to_cartesian(&theta, &[Dd::from(0.0); 2]).0;
        let coarse = position(galerkin_dd(&angles, t_end, n)?);
        let fine = position(galerkin_dd(&angles, t_end, 2 * n)?);
        let agreement = coarse.iter().zip(&fine).map(|(a, b)| (*a - *b).abs().to_f64()).fold(0.0, f64::max);
        let q: Vec<f64> = fine.iter().map(|x| x.to_f64()).collect();
        let accepted = tolerance * q.iter().fold(1.0f64, |m, x| m.max(x.abs()));
        let check = format!(
            "double-double Galerkin s = 8 on the angle equations with {n} against {} steps, mapped to Cartesian positions",
            2 * n
        );
        let kind = "double-double galerkin".to_string();
        passed(Self::ID, t_end, Reference { q, kind, check, agreement, accepted, seconds: start.seconds() })
    }
}

/// Every problem of the report, in priority order; `scale` multiplies each horizon.
pub fn all(scale: f64) -> Vec<Box<dyn Problem>> {
    vec![
        Box::new(Adapter::<_, 1, 2>(p::Pendulum { scale })),
        Box::new(Adapter::<_, 2, 4>(p::Kepler::<500> { scale })),
        Box::new(Adapter::<_, 2, 4>(p::Kepler::<900> { scale })),
        Box::new(Adapter::<_, 2, 4>(p::HenonHeiles { scale })),
        Box::new(Adapter::<_, 18, 36>(p::OuterSolarSystem { scale })),
        Box::new(Adapter::<_, 2, 4>(p::DoublePendulum { scale })),
        Box::new(Adapter::<_, 2, 4>(p::KeplerPolar { scale })),
        Box::new(CartesianDoublePendulum { scale }),
        Box::new(Adapter::<_, { p::FPU_N }, { 2 * p::FPU_N }>(p::Fpu { scale })),
        Box::new(Adapter::<_, 1, 2>(p::PerturbedPendulum { scale })),
        Box::new(Adapter::<_, 2, 4>(p::Sensor { scale })),
    ]
}

/// The hard orbit of the stress section (not in the work–precision suite).
pub fn kepler_099(scale: f64) -> Box<dyn Problem> {
    Box::new(Adapter::<_, 2, 4>(p::Kepler::<990> { scale }))
}
