//! Initial data onto the constraint manifold: the positions by Gauss–Newton
//! on `g(q) = 0` along the rows of `G` (the nearest point to first order),
//! the velocities by the orthogonal projection onto the (affine) space of
//! velocities with `G(t, q) v + ∂g/∂t(t, q) = 0`.

use nalgebra::SVector;

use super::linear::{SCHUR_MIN_RCOND, inverse};
use super::{Constrained, jacobian, rate};
use crate::error::Error;
use crate::real::max_abs;
use crate::state::State;
use crate::system::Lagrangian;

/// Gauss–Newton iterations allowed before the projection gives up.
const MAX_ITERATIONS: usize = 50;

impl<D, const M: usize> Constrained<D, M> {
    /// `(q, v)` moved onto the constraint manifold and its tangent space:
    /// `q` to a nearby point with `g(t, q) = 0` (Gauss–Newton steps
    /// `q ← q − Gᵀ(GGᵀ)⁻¹g`, to round-off), then
    /// `v ← v − Gᵀ(GGᵀ)⁻¹(Gv + ∂g/∂t)`, so that `G(t, q) v + ∂g/∂t = 0`
    /// (`G v = 0` for constraints that do not depend on time). Data already
    /// consistent come back unchanged to round-off.
    ///
    /// Fails with [`Error::NonFiniteConstraints`] where `g` or `G` is not
    /// finite, [`Error::SingularConstraints`] where `G` is rank-deficient,
    /// and [`Error::NewtonDidNotConverge`] where the iteration does not
    /// settle (the data are too far from the manifold); the state in the
    /// errors is `(t, q, 0)`.
    pub fn project<S: Lagrangian<N>, const N: usize>(
        &self,
        system: &S,
        t: f64,
        q: [f64; N],
        v: [f64; N],
    ) -> Result<([f64; N], [f64; N]), Error> {
        let state = State { step: 0, t, q, p: [0.0; N] };
        let mut x = SVector::<f64, N>::from(q);
        let mut correction = f64::INFINITY;
        for iteration in 1..=MAX_ITERATIONS {
            let (g, jac) = jacobian::<S, N, M>(system, t, &x.into())
                .ok_or_else(|| Error::NonFiniteConstraints { state: state.into() })?;
            let (inv, rcond) = inverse(jac * jac.transpose());
            if rcond <= SCHUR_MIN_RCOND {
                return Err(Error::SingularConstraints { state: state.into(), rcond });
            }
            let dx = jac.transpose() * (inv * SVector::from(g));
            x -= dx;
            correction = dx.amax();
            if !correction.is_finite() {
                return Err(Error::NonFiniteConstraints { state: state.into() });
            }
            if correction <= 1e-15 * x.amax().max(1.0) || (iteration > 1 && correction == 0.0) {
                let q: [f64; N] = x.into();
                let (_, jac) = jacobian::<S, N, M>(system, t, &q)
                    .ok_or_else(|| Error::NonFiniteConstraints { state: state.into() })?;
                let rate = SVector::from(
                    rate::<S, N, M>(system, t, &q)
                        .ok_or_else(|| Error::NonFiniteConstraints { state: state.into() })?,
                );
                let (inv, _) = inverse(jac * jac.transpose());
                let w = SVector::from(v);
                let v = w - jac.transpose() * (inv * (jac * w + rate));
                return Ok((q, v.into()));
            }
        }
        Err(Error::NewtonDidNotConverge {
            state: state.into(),
            h: 0.0,
            iterations: MAX_ITERATIONS,
            residual_norm: f64::NAN,
            correction_norm: correction.max(0.0) / max_abs(&q).max(1.0),
        })
    }
}
