//! The accuracy a tolerance-driven solve is asked for.

use crate::error::Error;

/// The global error a [`solve`](super::Auto::solve) must meet at the end of
/// its span: `max_i |q_i(t_end) − q_i^exact(t_end)| ≤ rtol · Q + atol`,
/// where `Q` is the largest `max_i |q_i(t)|` the pilot run meets (a scale of
/// the positions that does not vanish when one of them crosses zero).
///
/// ```
/// use lagrangian_runtime::auto::Tolerance;
///
/// let tol = Tolerance::relative(1e-8).absolute(1e-12);
/// assert_eq!(tol.bound(2.0), 2e-8 + 1e-12);
/// assert!(Tolerance::relative(f64::NAN).validate().is_err());
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tolerance {
    /// The relative tolerance, in `(0, 1)`.
    pub rtol: f64,
    /// The absolute tolerance, `≥ 0` (0 by default).
    pub atol: f64,
}

impl Tolerance {
    /// A relative tolerance `rtol` and no absolute one.
    pub fn relative(rtol: f64) -> Self {
        Self { rtol, atol: 0.0 }
    }

    /// The same relative tolerance with an absolute floor `atol`.
    pub fn absolute(mut self, atol: f64) -> Self {
        self.atol = atol;
        self
    }

    /// The absolute error allowed for positions of scale `scale`.
    pub fn bound(&self, scale: f64) -> f64 {
        self.rtol * scale + self.atol
    }

    /// `Ok` for `0 < rtol < 1` and a finite `atol ≥ 0`; otherwise
    /// [`Error::InvalidTolerance`] saying which.
    pub fn validate(&self) -> Result<(), Error> {
        let invalid = |value, reason| Err(Error::InvalidTolerance { value, reason });
        if self.rtol.is_nan() {
            return invalid(self.rtol, "the relative tolerance is NaN");
        }
        if self.rtol <= 0.0 {
            return invalid(self.rtol, "the relative tolerance must be positive");
        }
        if self.rtol >= 1.0 {
            return invalid(self.rtol, "the relative tolerance must be below 1 (a relative error of 1 is no accuracy)");
        }
        if !(self.atol.is_finite() && self.atol >= 0.0) {
            return invalid(self.atol, "the absolute tolerance must be finite and not negative");
        }
        Ok(())
    }
}
