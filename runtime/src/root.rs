//! Bracketing root finding: the Illinois variant of regula falsi.
//!
//! Regula falsi keeps a root enclosed between two points where `f` has
//! opposite signs and tries the zero of the secant through them. On a convex
//! stretch it keeps replacing the same end, and the other end, kept for
//! ever, makes it converge only linearly. The Illinois modification halves
//! the value stored at an end that has been kept twice in a row, which
//! restores superlinear convergence (order about 1.44; Dowell and Jarratt,
//! BIT 11, 1971) while the root stays bracketed.
//!
//! One [`Bracket`] serves every search in the runtime: the events' crossing
//! on a step's dense output ([`illinois`]) and the time-transformed drivers'
//! landing on a target time, whose trials are whole steps that may be
//! refused (then the bracket shrinks without a value, [`Bracket::refuse`]).

use crate::real::Real;

/// A sign change of `f` between `a` and `b`, updated by the Illinois rule.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Bracket<T> {
    a: T,
    fa: T,
    b: T,
    fb: T,
    /// Which end was replaced last: −1 for `a`, +1 for `b`, 0 for neither.
    side: i8,
}

impl<T: Real> Bracket<T> {
    /// The bracket `[a, b]` (in either order) with `f(a) = fa` and
    /// `f(b) = fb` of opposite signs.
    pub(crate) fn new((a, fa): (T, T), (b, fb): (T, T)) -> Self {
        Self { a, fa, b, fb, side: 0 }
    }

    /// The next point to try: the zero of the secant through the ends, or
    /// the midpoint when rounding puts that zero outside the open bracket.
    pub(crate) fn trial(&self) -> T {
        let (a, b) = (self.a, self.b);
        let t = b - self.fb * (b - a) / (self.fb - self.fa);
        let inside = (t - a).to_f64() * (b - t).to_f64() > 0.0;
        if inside { t } else { (a + b) * 0.5 }
    }

    /// Takes `f(t) = ft` (finite, not zero) in: `t` replaces the end whose
    /// value has the sign of `ft`, and the value of an end kept twice in a
    /// row is halved.
    pub(crate) fn update(&mut self, t: T, ft: T) {
        if (ft.to_f64() < 0.0) == (self.fb.to_f64() < 0.0) {
            (self.b, self.fb) = (t, ft);
            if self.side == 1 {
                self.fa *= 0.5;
            }
            self.side = 1;
        } else {
            (self.a, self.fa) = (t, ft);
            if self.side == -1 {
                self.fb *= 0.5;
            }
            self.side = -1;
        }
    }

    /// `f` has no value at `t` (a trial step was refused): the end `b` moves
    /// to `t` and keeps its value, so the next trial lies closer to `a`,
    /// where the last accepted value was.
    pub(crate) fn refuse(&mut self, t: T) {
        self.b = t;
    }

    /// `|b − a|` in `f64`.
    pub(crate) fn width(&self) -> f64 {
        (self.b - self.a).to_f64().abs()
    }

    /// The end `b`: the side of the bracket that began where `f` had
    /// changed sign.
    pub(crate) fn b(&self) -> T {
        self.b
    }
}

/// Why a root could not be located.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct NotFinite {
    pub(crate) t: f64,
}

/// The zero of `f` in `[a, b]` where `f(a) = fa` and `f(b) = fb` have
/// opposite signs (or `fb = 0`). Returns the end of the final bracket on the
/// side of `b` (where the sign has changed), within `tol` of the root.
pub(crate) fn illinois(
    mut f: impl FnMut(f64) -> f64,
    a: (f64, f64),
    b: (f64, f64),
    tol: f64,
) -> Result<f64, NotFinite> {
    if b.1 == 0.0 {
        return Ok(b.0);
    }
    let mut bracket = Bracket::new(a, b);
    for _ in 0..200 {
        if bracket.width() <= tol {
            break;
        }
        let t = bracket.trial();
        let ft = f(t);
        if !ft.is_finite() {
            return Err(NotFinite { t });
        }
        if ft == 0.0 {
            return Ok(t);
        }
        bracket.update(t, ft);
    }
    Ok(bracket.b())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::DoubleDouble;

    #[test]
    fn illinois_brackets_to_the_tolerance() {
        let mut calls = 0;
        let root = illinois(
            |t| {
                calls += 1;
                t.cos() - t
            },
            (0.0, 1.0),
            (1.0, 1f64.cos() - 1.0),
            1e-15,
        )
        .unwrap();
        assert!((root - 0.739_085_133_215_160_6).abs() < 2e-15, "{root}");
        assert!(calls < 20, "{calls} evaluations");
        // A flat function where plain regula falsi keeps one end for ever.
        let root = illinois(|t: f64| t.powi(9) - 1e-9, (0.0, -1e-9), (1.0, 1.0 - 1e-9), 1e-14).unwrap();
        assert!((root - 0.1).abs() < 1e-13, "{root}");
        assert_eq!(illinois(|_| f64::NAN, (0.0, -1.0), (1.0, 1.0), 1e-12), Err(NotFinite { t: 0.5 }));
    }

    #[test]
    fn the_bracket_works_in_double_double() {
        // x² = 2 on [1, 2]: the root to about 30 digits.
        let two = DoubleDouble::from(2.0);
        let f = |x: DoubleDouble| x * x - two;
        let one = DoubleDouble::from(1.0);
        let mut bracket = Bracket::new((one, f(one)), (two, f(two)));
        let mut x = bracket.trial();
        for _ in 0..100 {
            x = bracket.trial();
            let fx = f(x);
            if fx.to_f64().abs() <= 1e-30 {
                break;
            }
            bracket.update(x, fx);
        }
        let error = (x * x - two).to_f64().abs();
        assert!(error <= 1e-30, "x² − 2 = {error:e}");
    }

    #[test]
    fn a_refused_trial_moves_the_far_end_only() {
        let mut bracket = Bracket::new((0.0, -1.0), (1.0, 1.0));
        assert_eq!(bracket.trial(), 0.5);
        bracket.refuse(0.5);
        assert_eq!(bracket.width(), 0.5);
        // The secant now runs from (0, −1) to (0.5, 1): its zero is 0.25.
        assert_eq!(bracket.trial(), 0.25);
    }
}
