//! The hidden constraint of a step's end node: the momentum moved onto the
//! cotangent space of the constraint manifold (the second half of RATTLE;
//! Hairer, Lubich & Wanner, *Geometric Numerical Integration*, §VII.1.4).
//!
//! ```text
//! ∂L/∂v(q_{k+1}, v_{k+1}) = p̂ + G(q_{k+1})ᵀ μ,      G(q_{k+1}) v_{k+1} + ∂g/∂t(t_{k+1}, q_{k+1}) = 0,
//! ```
//!
//! `p̂` the step's unconstrained end momentum (`∂A/∂q_{k+1}` with the
//! discrete force `F_k^+`). Newton on `(v, μ)` with `∂²L/∂v²` as the
//! upper-left block of the saddle-point system: one iteration for a
//! quadratic kinetic energy, after which the residual at round-off ends the
//! iteration without another Hessian.

use nalgebra::{SMatrix, SVector};

use super::linear::{self, solve_schur};
use crate::error::{Error, Unplaced};
use crate::mechanics::DiscreteMechanics;
use crate::newton::NewtonOptions;
use crate::real::max_abs;
use crate::system::Lagrangian;

/// The end node's velocity and momentum on the cotangent space.
pub(super) struct OnCotangent<const N: usize> {
    /// `v_{k+1}`, with `G(q_{k+1}) v_{k+1} = 0`.
    pub(super) velocity: [f64; N],
    /// `p_{k+1} = p̂ + G(q_{k+1})ᵀ μ`.
    pub(super) momentum: [f64; N],
    /// Newton iterations spent.
    pub(super) iterations: usize,
}

/// Solves the hidden constraint at `(t1, q1)` with Jacobian `jac1` and
/// `∂g/∂t = rate` (zero for constraints that do not depend on time), from
/// the velocity guess `v`. `h` and `spent` (the iterations of the position
/// solve) go into the errors, which the caller places at the step's start.
#[allow(clippy::too_many_arguments)]
pub(super) fn onto_cotangent<S: Lagrangian<N> + ?Sized, const N: usize, const M: usize>(
    system: &S,
    (t1, q1): (f64, [f64; N]),
    end: &[f64; N],
    (jac1, rate): (&SMatrix<f64, M, N>, &SVector<f64, M>),
    v: [f64; N],
    options: &NewtonOptions,
    (h, spent): (f64, usize),
) -> Result<OnCotangent<N>, Unplaced> {
    let jac1t = jac1.transpose();
    let finish = |v: SVector<f64, N>, mu: SVector<f64, M>, iterations| OnCotangent {
        velocity: v.into(),
        momentum: (SVector::from(*end) + jac1t * mu).into(),
        iterations,
    };
    let mut v = SVector::<f64, N>::from(v);
    let mut mu = SVector::<f64, M>::zeros();
    let mut iterations = 0;
    while iterations < options.max_iterations {
        iterations += 1;
        let vv: [f64; N] = v.into();
        let p = system.momentum(t1, q1, vv);
        let r1 = SVector::<f64, N>::from_fn(|i, _| p[i] - end[i]) - jac1t * mu;
        let r2 = jac1 * v + rate;
        // Near a turning point `|v|` is far below `|p̂|`, and the round-off
        // of the momentum residual, `ε|p̂|` through `(∂²L/∂v²)⁻¹`, can exceed
        // `rtol |v|` for good: a residual at round-off ends the iteration too.
        let p_scale = max_abs(&p).max(max_abs(end)) + (jac1t * mu).amax();
        let v_scale = jac1.amax() * v.amax() * N as f64 + rate.amax();
        if iterations > 1 && r1.amax() <= 4.0 * f64::EPSILON * p_scale && r2.amax() <= 4.0 * f64::EPSILON * v_scale {
            return Ok(finish(v, mu, iterations - 1));
        }
        let hessian = system.velocity_hessian(t1, q1, vv);
        // The saddle-point form with `−Gᵀ` in the upper right block.
        let (dv, dmu) = match solve_schur(&hessian, &(-jac1t), jac1, &r1, &r2, options.min_rcond) {
            Ok(x) => x,
            Err(linear::Singular::Block(rcond)) => {
                return Err(Unplaced::new(|state| Error::SingularJacobian {
                    state,
                    h,
                    iterations: spent + iterations,
                    rcond,
                }));
            }
            Err(linear::Singular::Schur(rcond)) => {
                return Err(Unplaced::new(|state| Error::SingularConstraints { state, rcond }));
            }
        };
        v += dv;
        mu += dmu;
        let norm = dv.amax();
        if !norm.is_finite() {
            return Err(Unplaced::new(|state| Error::NonFinite {
                state,
                h,
                iterations: spent + iterations,
                quantity: "momentum",
            }));
        }
        // The same round-off, `ε|p̂|` over the smallest mass, as a floor
        // of the correction.
        let mass = (0..N).map(|i| hessian[(i, i)].abs()).fold(f64::INFINITY, f64::min);
        let floor = 4.0 * f64::EPSILON * max_abs(&p).max(max_abs(end)) / mass;
        if norm <= options.rtol * v.amax() + options.atol + floor {
            return Ok(finish(v, mu, iterations));
        }
    }
    Err(Unplaced::new(|state| Error::NewtonDidNotConverge {
        state,
        h,
        iterations: spent + iterations,
        residual_norm: f64::NAN,
        correction_norm: f64::NAN,
    }))
}
