//! Fitting a damped pendulum to noisy angle measurements with the exact
//! derivatives of the computed trajectory.
//!
//! The model is `L = ½ l² q̇² + g l cos q`, `R = ½ c q̇²` with the length
//! `l`, gravity `g` and damping `c` declared as parameters. The angle alone
//! sees only `g/l` and `c/l²` (`l² q̈ + c q̇ + g l sin q = 0`), so two of the
//! three can be fitted: here `l` and `c`, with `g` known. Measurements are
//! the angle every 25 steps of a midpoint run with the true values, plus
//! Gaussian noise of standard deviation `σ`. Levenberg–Marquardt (the
//! `levenberg-marquardt` crate) on the misfit takes the Jacobian of the
//! residuals from the forward sensitivities
//! (`Problem::solve_with_sensitivities`, no finite differences), and the
//! standard errors of the fit come from `σ² (JᵀJ)⁻¹`.
//!
//! Run with `cargo run --release --example fit_pendulum`; its test
//! (`cargo test -p lagrangian-examples --example fit_pendulum`) checks that
//! the fit lands within three standard errors of the truth.

use std::error::Error;

use lagrangian::prelude::*;
use levenberg_marquardt::{LeastSquaresProblem, LevenbergMarquardt};
use nalgebra034::{DVector, Dyn, OMatrix, Owned, U2, Vector2};

/// A damped pendulum: length, gravity and damping are parameters.
#[derive(Clone, Debug)]
pub struct Pendulum {
    l: f64,
    g: f64,
    c: f64,
}

#[lagrangian(parameters(l, g, c))]
impl Pendulum {
    fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * self.l * self.l * v[0] * v[0] + self.g * self.l * q[0].cos()
    }

    fn dissipation(&self, _q: [f64; 1], v: [f64; 1]) -> f64 {
        0.5 * self.c * v[0] * v[0]
    }
}

const TRUTH: Pendulum = Pendulum { l: 0.8, g: 9.81, c: 0.05 };
const Q0: [f64; 1] = [1.0];
const H: f64 = 2e-3;
const T_END: f64 = 10.0;
/// Steps between measurements.
const EVERY: usize = 25;

/// The fitted `(l, c)`, their standard errors and the optimiser's runs of the model.
#[derive(Clone, Debug)]
pub struct Fit {
    /// `(l, c)`.
    pub estimate: [f64; 2],
    /// Their standard errors, `σ √diag (JᵀJ)⁻¹`.
    pub standard_error: [f64; 2],
    /// Evaluations of the residuals (runs of the model) the optimiser made.
    pub evaluations: usize,
}

/// The angles at the measured nodes and their derivatives in `(l, c)`.
type Angles = (Vec<f64>, Vec<[f64; 2]>);

/// Angles at every `EVERY`-th node of the run with length `l` and damping
/// `c`, and their derivatives with respect to `(l, c)`.
fn angles(l: f64, c: f64) -> Result<Angles, Box<dyn Error>> {
    let system = TRUTH.with_parameters([l, TRUTH.g, c]);
    let run = Problem::new(system, 0.0, Q0, [0.0]).solve_with_sensitivities(
        &Scheme::MIDPOINT,
        H,
        Plan::until(T_END).every(EVERY),
    )?;
    if let Some(e) = run.error {
        return Err(e.into());
    }
    let q = run.solution.q.iter().map(|q| q[0]).collect();
    // Columns: q0, v0, then the parameters l, g, c.
    let dq = run.jacobians.iter().map(|j| [j.get(0, 2), j.get(0, 4)]).collect();
    Ok((q, dq))
}

/// Gaussian pseudo-random numbers (xorshift64* and Box–Muller) from `seed`.
fn gaussian(seed: u64, n: usize) -> Vec<f64> {
    let mut state = seed.max(1);
    let mut uniform = move || {
        state ^= state >> 12;
        state ^= state << 25;
        state ^= state >> 27;
        ((state.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    };
    (0..n).map(|_| (-2.0 * uniform().ln()).sqrt() * (std::f64::consts::TAU * uniform()).cos()).collect()
}

/// The misfit of the angles at `(l, c)` to the measurements, as the
/// `levenberg-marquardt` crate asks for it: residuals `r = q − y` and their
/// Jacobian from the forward sensitivities, computed once per point the
/// optimiser visits.
struct Misfit<'a> {
    measured: &'a [f64],
    theta: Vector2<f64>,
    /// Angles and their derivatives at `theta`; empty where the run failed.
    angles: Angles,
}

impl LeastSquaresProblem<f64, Dyn, U2> for Misfit<'_> {
    type ResidualStorage = Owned<f64, Dyn>;
    type JacobianStorage = Owned<f64, Dyn, U2>;
    type ParameterStorage = Owned<f64, U2>;

    fn set_params(&mut self, x: &Vector2<f64>) {
        self.theta = *x;
        // A run that fails (a length or damping the model cannot take)
        // leaves no residuals: the optimiser then stops with a typed reason.
        self.angles = angles(x[0], x[1]).unwrap_or_default();
    }

    fn params(&self) -> Vector2<f64> {
        self.theta
    }

    fn residuals(&self) -> Option<DVector<f64>> {
        let (q, _) = &self.angles;
        (q.len() == self.measured.len())
            .then(|| DVector::from_iterator(q.len(), q.iter().zip(self.measured).map(|(q, y)| q - y)))
    }

    fn jacobian(&self) -> Option<OMatrix<f64, Dyn, U2>> {
        let (_, dq) = &self.angles;
        (dq.len() == self.measured.len()).then(|| OMatrix::<f64, Dyn, U2>::from_fn(dq.len(), |i, j| dq[i][j]))
    }
}

/// Fits `(l, c)` from `guess` to `measured` by Levenberg–Marquardt (the
/// `levenberg-marquardt` crate, MINPACK's algorithm); `sigma` is the
/// noise's standard deviation.
pub fn fit(measured: &[f64], sigma: f64, guess: [f64; 2]) -> Result<Fit, Box<dyn Error>> {
    let mut problem = Misfit { measured, theta: Vector2::from(guess), angles: Angles::default() };
    problem.set_params(&Vector2::from(guess));
    let (problem, report) = LevenbergMarquardt::new().with_tol(1e-12).minimize(problem);
    if !report.termination.was_successful() {
        return Err(format!("levenberg–marquardt stopped: {:?}", report.termination).into());
    }
    let theta = problem.params();
    // Covariance σ² (JᵀJ)⁻¹ at the fit.
    let (_, dq) = angles(theta[0], theta[1])?;
    let j = OMatrix::<f64, Dyn, U2>::from_fn(dq.len(), |i, k| dq[i][k]);
    let covariance = (j.transpose() * &j)
        .try_inverse()
        .ok_or("the normal equations are singular: (l, c) are not determined by these measurements")?
        * (sigma * sigma);
    Ok(Fit {
        estimate: [theta[0], theta[1]],
        standard_error: [covariance[(0, 0)].sqrt(), covariance[(1, 1)].sqrt()],
        evaluations: report.number_of_evaluations,
    })
}

/// Synthetic measurements with noise `sigma` from `seed`.
pub fn measurements(sigma: f64, seed: u64) -> Result<Vec<f64>, Box<dyn Error>> {
    let (q, _) = angles(TRUTH.l, TRUTH.c)?;
    Ok(q.iter().zip(gaussian(seed, q.len())).map(|(q, e)| q + sigma * e).collect())
}

fn main() -> Result<(), Box<dyn Error>> {
    let sigma = 0.01;
    let measured = measurements(sigma, 7)?;
    let f = fit(&measured, sigma, [0.85, 0.1])?;
    println!("{} measurements, noise σ = {sigma} rad, {} runs of the model", measured.len(), f.evaluations);
    for (k, (name, truth)) in [("l", TRUTH.l), ("c", TRUTH.c)].iter().enumerate() {
        let (est, se) = (f.estimate[k], f.standard_error[k]);
        println!("{name}: {est:.6} ± {se:.1e} (truth {truth}, off by {:.2} standard errors)", (est - truth) / se);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_fit_recovers_length_and_damping_within_three_standard_errors() {
        let sigma = 0.01;
        for seed in [7] {
            let measured = measurements(sigma, seed).unwrap();
            let f = fit(&measured, sigma, [0.85, 0.1]).unwrap();
            for (k, truth) in [TRUTH.l, TRUTH.c].into_iter().enumerate() {
                let (est, se) = (f.estimate[k], f.standard_error[k]);
                eprintln!("seed {seed}: {est} ± {se:.1e} (truth {truth}), {} runs", f.evaluations);
                assert!(se > 0.0 && se < 0.1 * truth, "seed {seed}: standard error {se} of {truth}");
                assert!((est - truth).abs() <= 3.0 * se, "seed {seed}: {est} vs {truth} ± {se}");
            }
        }
    }
}
