//! Step-size guidance: a safe `h` from the linearisation at the initial state.
//!
//! The rule. Linearise the equations of motion `q̈ = a(t, q, q̇)` at the
//! initial state: the first-order system `ż = (v, a)` has the Jacobian
//! `J = [[0, I], [∂a/∂q, ∂a/∂v]]`, whose eigenvalues are `±iω` for the
//! oscillation frequencies and real `±γ` for exponential growth (taken by
//! central differences of [`acceleration`]). Let `ρ = max |λ(J)|`, the
//! fastest rate. A symmetric method of order `p` has, on `q̈ = −ω²q`, the
//! relative frequency error `C (ωh)^p`:
//!
//! | method | `p` | `C` | stability |
//! | --- | --- | --- | --- |
//! | midpoint (`ω̃ = (2/h) atan(ωh/2)`) | 2 | 1/12 | any `ωh` (but the frequency is wrong) |
//! | trapezoid (`cos ω̃h = 1 − (ωh)²/2`, Störmer–Verlet) | 2 | 1/24 | `ωh < 2` |
//! | Galerkin degree `s`, `s` Gauss points (the `(s, s)` Padé approximant of `e^z`) | `2s` | `(s!)² / ((2s)! (2s+1)!)` | any `ωh` |
//!
//! [`suggest_step`] returns `h = (tol / C)^{1/p} / ρ`, the step at which the
//! fastest mode's relative frequency error is `tol` (its phase drifts by
//! `2π·tol` per period), capped at `ρh ≤ 1` below a stability limit.
//! A nonlinear system's frequencies change along the orbit (a pendulum's
//! slows towards the separatrix), so the guidance holds near the initial
//! state; [`Plan::energy_tolerance`](crate::Plan::energy_tolerance) watches
//! the energy for the rest of the run.

use nalgebra::DMatrix;

use crate::dense::acceleration;
use crate::system::Lagrangian;

/// A method's frequency error `C (ωh)^p` on the harmonic oscillator.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rule {
    /// The order `p`.
    pub order: u32,
    /// The constant `C`.
    pub constant: f64,
    /// The largest stable `ωh`, if there is one.
    pub stability_limit: Option<f64>,
}

impl Rule {
    /// The implicit midpoint rule ([`Midpoint`](crate::Midpoint)).
    pub fn midpoint() -> Self {
        Self { order: 2, constant: 1.0 / 12.0, stability_limit: None }
    }

    /// The trapezoid rule ([`Trapezoid`](crate::Trapezoid)): Störmer–Verlet
    /// on separable systems, stable for `ωh < 2`.
    pub fn trapezoid() -> Self {
        Self { order: 2, constant: 1.0 / 24.0, stability_limit: Some(2.0) }
    }

    /// Galerkin of degree `s` with `s` Gauss–Legendre points
    /// ([`Galerkin::gauss`](crate::Galerkin::gauss)), order `2s`.
    pub fn galerkin_gauss(s: u32) -> Self {
        let factorial = |n: u32| (1..=n).map(f64::from).product::<f64>();
        let constant = factorial(s).powi(2) / (factorial(2 * s) * factorial(2 * s + 1));
        Self { order: 2 * s, constant, stability_limit: None }
    }

    /// The largest `ωh` with relative frequency error at most `tol`.
    pub fn omega_h(&self, tol: f64) -> f64 {
        let bound = (tol / self.constant).powf(1.0 / f64::from(self.order));
        match self.stability_limit {
            Some(limit) => bound.min(limit - 1.0),
            None => bound,
        }
    }
}

/// The linearisation at a state.
#[derive(Clone, Debug, PartialEq)]
pub struct Linearization {
    /// The oscillation frequencies `ω` (imaginary parts of the eigenvalues
    /// of `J`, positive ones, largest first).
    pub frequencies: Vec<f64>,
    /// The growth rates `γ > 0` of unstable directions (largest first).
    pub growth_rates: Vec<f64>,
    /// `ρ = max |λ(J)|`.
    pub fastest: f64,
}

/// Why no guidance could be given.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum GuidanceError {
    /// A tolerance that is not finite and in `(0, 1)`.
    #[error("invalid tolerance {tol}: it must lie in (0, 1)")]
    InvalidTolerance {
        /// The tolerance.
        tol: f64,
    },
    /// The state is not finite or `∂²L/∂v²` is singular there.
    #[error("no acceleration at the state: it is not finite or ∂²L/∂v² is singular")]
    NoAcceleration,
    /// The linearisation has no motion to resolve (`ρ = 0`, as at the
    /// equilibrium of a free particle): any step is as good.
    #[error("the linearisation has no frequency or growth rate: the step is not limited by the dynamics")]
    NoTimeScale,
}

/// The Jacobian of `ż = (v, a(t, q, v))` at a state, by central differences.
pub fn linearize<S: Lagrangian<N> + ?Sized, const N: usize>(
    system: &S,
    t: f64,
    q: [f64; N],
    v: [f64; N],
) -> Result<Linearization, GuidanceError> {
    let mut j = DMatrix::<f64>::zeros(2 * N, 2 * N);
    for i in 0..N {
        j[(i, N + i)] = 1.0;
    }
    for k in 0..2 * N {
        let x = if k < N { q[k] } else { v[k - N] };
        // Central differences: error O(δ²), round-off O(ε/δ).
        let delta = f64::EPSILON.cbrt() * x.abs().max(1.0);
        let at = |sign: f64| {
            let (mut q, mut v) = (q, v);
            if k < N {
                q[k] += sign * delta;
            } else {
                v[k - N] += sign * delta;
            }
            acceleration(system, t, q, v).ok_or(GuidanceError::NoAcceleration)
        };
        let (plus, minus) = (at(1.0)?, at(-1.0)?);
        for i in 0..N {
            j[(N + i, k)] = (plus[i] - minus[i]) / (2.0 * delta);
        }
    }
    if !j.iter().all(|x| x.is_finite()) {
        return Err(GuidanceError::NoAcceleration);
    }
    let eigen = j.complex_eigenvalues();
    let fastest = eigen.iter().map(|l| l.norm()).fold(0.0, f64::max);
    // Eigenvalues below this are round-off of the differences.
    let floor = 1e-6 * fastest;
    let mut frequencies: Vec<f64> = eigen.iter().filter(|l| l.im > floor).map(|l| l.im).collect();
    let mut growth_rates: Vec<f64> = eigen.iter().filter(|l| l.re > floor).map(|l| l.re).collect();
    frequencies.sort_by(|a, b| b.total_cmp(a));
    growth_rates.sort_by(|a, b| b.total_cmp(a));
    Ok(Linearization { frequencies, growth_rates, fastest })
}

/// The guidance for one system, state and method.
#[derive(Clone, Debug, PartialEq)]
pub struct StepAdvice {
    /// The linearisation it is based on.
    pub linearization: Linearization,
    /// The bound on `ρh`.
    pub omega_h: f64,
    /// The suggested step `omega_h / ρ`.
    pub h: f64,
}

/// A step size for which the fastest mode of the linearisation at
/// `(t, q, v)` has relative frequency error `tol` under `rule` (see the
/// [module docs](self)).
pub fn suggest_step<S: Lagrangian<N> + ?Sized, const N: usize>(
    system: &S,
    (t, q, v): (f64, [f64; N], [f64; N]),
    rule: Rule,
    tol: f64,
) -> Result<StepAdvice, GuidanceError> {
    if !(tol > 0.0 && tol < 1.0) {
        return Err(GuidanceError::InvalidTolerance { tol });
    }
    let linearization = linearize(system, t, q, v)?;
    if linearization.fastest.is_nan() || linearization.fastest <= 0.0 {
        return Err(GuidanceError::NoTimeScale);
    }
    let omega_h = rule.omega_h(tol);
    Ok(StepAdvice { h: omega_h / linearization.fastest, omega_h, linearization })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pade_constants() {
        assert_eq!(Rule::galerkin_gauss(1).constant, Rule::midpoint().constant);
        assert!((Rule::galerkin_gauss(2).constant - 1.0 / 720.0).abs() < 1e-18);
        assert!((Rule::galerkin_gauss(3).constant - 1.0 / 100_800.0).abs() < 1e-20);
        assert!(Rule::trapezoid().omega_h(0.5) <= 1.0);
    }
}
