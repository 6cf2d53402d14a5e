//! Which method a tolerance-driven solve tries, in order, and why: from the
//! structure facts `#[lagrangian]` proves, the tolerance, and the variation
//! of the step density a pilot measures.
//!
//! | system | step density along the pilot | tolerance | first candidate |
//! | --- | --- | --- | --- |
//! | `½ vᵀMv − V(q)`, `M` constant, no forces | varies by more than [`DENSITY_RATIO`] | any | explicit time-transformed splitting (logarithmic), Kahan–Li 8 |
//! | `½ vᵀMv − V(q)`, `M` constant, no forces | nearly uniform | any | Kahan–Li 8 composition of Störmer–Verlet |
//! | forces or dissipation | any | `≥ 1e-5` / `≥ 1e-11` / `≥ 1e-13` / tighter | Galerkin `s = 2 / 4 / 6 / 8` |
//! | anything else (non-separable, time-dependent, position-dependent mass) | any | `≥ 1e-11` / `≥ 1e-13` / tighter | Galerkin `s = 4 / 6 / 8` |
//!
//! The orders follow the report's calibration: Kahan–Li 8 is the fastest
//! project method on the separable problems at every target, Galerkin
//! `s = 4` on the double pendulum; a lower order is faster only where the
//! run is a few dozen steps anyway.
//!
//! The candidates after the first are the fallbacks when a pilot fails: the
//! composition falls back to Galerkin, Galerkin to the next lower degree.

use crate::error::Error;
use crate::structure::Separability;
use crate::system::Lagrangian;

/// The ratio of the largest to the time-averaged fastest rate `ρ(t)` of the
/// linearisation along the pilot above which uniform steps waste most of
/// their work on the slow parts of the orbit and a time transformation is
/// chosen. Uniform steps need `max ρ · T` of them, a time transformation
/// about `mean ρ · T`: the ratio is the work saved, and it has to pay for a
/// composition of the leapfrog in `s` that costs about as much per step.
pub const DENSITY_RATIO: f64 = 4.0;

/// A method family the solve can run.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Family {
    /// A symmetric composition of the trapezoid rule (Störmer–Verlet on a
    /// separable system): Yoshida 4, Yoshida 6 or Kahan–Li 8.
    Composition,
    /// Galerkin of degree `s` with `s` Gauss points, order `2s`
    /// (`s = 2, 3, 4, 6, 8`).
    Galerkin,
    /// The explicit time-transformed splitting with the logarithmic time
    /// function, composed to order 4, 6 or 8; steps are uniform in the new
    /// time `s`.
    TimeTransformed,
}

/// One method: a family and an order.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Candidate {
    /// The family.
    pub family: Family,
    /// The classical order.
    pub order: u32,
}

impl Candidate {
    /// The method's name, as reported in an [`Estimate`](super::Estimate).
    pub fn name(&self) -> String {
        match (self.family, self.order) {
            (Family::Composition, 4) => "Yoshida 4 composition".into(),
            (Family::Composition, 6) => "Yoshida 6 composition".into(),
            (Family::Composition, _) => "Kahan–Li 8 composition".into(),
            (Family::Galerkin, p) => format!("Galerkin s = {}", p / 2),
            (Family::TimeTransformed, p) => format!("explicit time-transformed splitting, order {p}"),
        }
    }
}

/// What the macro proves about a system, as the choice reads it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Facts {
    /// [`Lagrangian::SEPARABILITY`].
    pub separability: Separability,
    /// [`Lagrangian::AUTONOMOUS`].
    pub autonomous: bool,
    /// A force or a dissipation function.
    pub forced: bool,
}

impl Facts {
    /// The facts of `S`.
    pub fn of<S: Lagrangian<N>, const N: usize>() -> Self {
        Self { separability: S::SEPARABILITY, autonomous: S::AUTONOMOUS, forced: S::HAS_FORCE || S::HAS_DISSIPATION }
    }

    /// `½ vᵀMv − V(t, q)` with constant `M` and no forces: the explicit
    /// compositions apply.
    pub fn explicit(&self) -> bool {
        self.separability.has_constant_mass() && !self.forced
    }

    /// As [`explicit`](Self::explicit), autonomous: the time-transformed
    /// splitting applies.
    pub fn transformable(&self) -> bool {
        self.explicit() && self.autonomous
    }
}

/// What the user fixed; `None` leaves it to the choice.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Fixed {
    /// The method family.
    pub family: Option<Family>,
    /// The order.
    pub order: Option<u32>,
}

/// The Galerkin degrees the solve carries.
pub const GALERKIN_DEGREES: [u32; 5] = [2, 3, 4, 6, 8];

/// Kahan–Li 8 at every tolerance: in the report's calibration it is the
/// fastest project method on the separable problems from `1e-4` to `1e-10`
/// (Yoshida 6 ahead by a few per cent only on FPU-β at `1e-4`), and its
/// time-transformed splitting on eccentric Kepler orbits.
fn composition_order(_rtol: f64) -> u32 {
    8
}

/// Galerkin `s = 4` for most tolerances: the report's fastest project
/// method on the double pendulum from `1e-4` to `1e-10`; with forces
/// `s = 2` at coarse tolerances (the sensor's fastest at `1e-4`).
fn galerkin_degree(rtol: f64, forced: bool) -> u32 {
    match (forced, rtol) {
        (true, r) if r >= 1e-5 => 2,
        (_, r) if r >= 1e-11 => 4,
        (_, r) if r >= 1e-13 => 6,
        (_, _) => 8,
    }
}

/// `Ok` when `order` exists in `family`.
fn check_order<const N: usize>(family: Family, order: u32) -> Result<(), Error<N>> {
    let ok = match family {
        Family::Composition | Family::TimeTransformed => matches!(order, 4 | 6 | 8),
        Family::Galerkin => order.is_multiple_of(2) && GALERKIN_DEGREES.contains(&(order / 2)),
    };
    if ok {
        Ok(())
    } else {
        Err(Error::InvalidMethod {
            reason: "no such order in this family for a tolerance-driven solve: compositions and the \
                     time-transformed splitting have orders 4, 6 and 8, Galerkin 4, 6, 8, 12 and 16",
        })
    }
}

/// The candidates, first choice first, each with its one-line reason.
/// `density_ratio` is the pilot's `max ρ / mean ρ` (`None` before it is
/// measured).
pub fn candidates<const N: usize>(
    facts: Facts,
    rtol: f64,
    density_ratio: Option<f64>,
    fixed: Fixed,
) -> Result<Vec<(Candidate, String)>, Error<N>> {
    let mut out: Vec<(Candidate, String)> = Vec::new();
    let varying = density_ratio.is_some_and(|r| r > DENSITY_RATIO);
    let order_in = |family: Family, default: u32| {
        fixed.order.filter(|_| fixed.family == Some(family) || fixed.family.is_none()).unwrap_or(default)
    };
    let galerkin_order = 2 * galerkin_degree(rtol, facts.forced);
    match fixed.family {
        Some(Family::TimeTransformed) if !facts.transformable() => {
            return Err(Error::NotSeparable {
                reason: "the time-transformed splitting needs an autonomous `½ vᵀMv − V(q)` with a constant \
                         mass matrix and no forces",
            });
        }
        Some(Family::Composition) if facts.forced => {
            return Err(Error::Unsupported { what: "a composition on a system with forces or dissipation" });
        }
        _ => {}
    }
    let ratio = density_ratio.unwrap_or(1.0);
    let tt = || {
        let order = order_in(Family::TimeTransformed, composition_order(rtol));
        (
            Candidate { family: Family::TimeTransformed, order },
            format!(
                "separable, autonomous and unforced, and the step density the pilot needs varies by a factor \
                 {ratio:.1} along the orbit (> {DENSITY_RATIO}): steps uniform in s = ∫dt/r"
            ),
        )
    };
    let composition = || {
        let order = order_in(Family::Composition, composition_order(rtol));
        (
            Candidate { family: Family::Composition, order },
            if facts.explicit() {
                format!(
                    "separable with a constant mass matrix and no forces: explicit composition of order {order} for rtol = {rtol:e}"
                )
            } else {
                format!(
                    "composition of order {order} as asked (implicit sub-steps: the system is not proven separable)"
                )
            },
        )
    };
    let galerkin = |order: u32, why: &str| {
        (
            Candidate { family: Family::Galerkin, order },
            format!("{why}: Galerkin s = {} for rtol = {rtol:e}", order / 2),
        )
    };
    let why = if facts.forced {
        "forces or dissipation (energy balance, not conservation)"
    } else if !facts.autonomous && facts.separability.has_constant_mass() {
        "time-dependent potential"
    } else if !facts.autonomous {
        "time-dependent and not proven separable"
    } else {
        "not proven `½ vᵀMv − V(q)` with a constant mass matrix"
    };
    match fixed.family {
        Some(Family::TimeTransformed) => out.push(tt()),
        Some(Family::Composition) => out.push(composition()),
        Some(Family::Galerkin) => {
            let order = order_in(Family::Galerkin, galerkin_order);
            out.push(galerkin(order, "Galerkin as asked"));
        }
        None => {
            if facts.transformable() && varying {
                out.push(tt());
            }
            if facts.explicit() {
                out.push(composition());
                let order = fixed.order.filter(|o| check_order::<N>(Family::Galerkin, *o).is_ok()).unwrap_or(8);
                out.push(galerkin(order, "fallback after the composition"));
            } else {
                let order = fixed.order.unwrap_or(galerkin_order);
                out.push(galerkin(order, why));
            }
        }
    }
    // A lower Galerkin degree converges Newton from farther away: the
    // fallback for a failed Galerkin pilot.
    if let Some(&(Candidate { family: Family::Galerkin, order }, _)) = out.last()
        && fixed.order.is_none()
        && let Some(&lower) = GALERKIN_DEGREES.iter().rev().find(|&&s| 2 * s < order)
    {
        out.push(galerkin(2 * lower, "fallback after the higher degree"));
    }
    for (c, _) in &out {
        check_order::<N>(c.family, c.order)?;
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    const KEPLER: Facts = Facts { separability: Separability::ConstantMass, autonomous: true, forced: false };
    const FORCED: Facts = Facts { separability: Separability::ConstantMass, autonomous: true, forced: true };
    const GENERAL: Facts = Facts { separability: Separability::NotProven, autonomous: true, forced: false };

    fn first(facts: Facts, rtol: f64, ratio: Option<f64>) -> Candidate {
        candidates::<2>(facts, rtol, ratio, Fixed::default()).unwrap()[0].0
    }

    #[test]
    fn the_table() {
        assert_eq!(first(KEPLER, 1e-10, Some(1.5)), Candidate { family: Family::Composition, order: 8 });
        assert_eq!(first(KEPLER, 1e-5, Some(1.5)), Candidate { family: Family::Composition, order: 8 });
        assert_eq!(first(KEPLER, 1e-10, Some(20.0)), Candidate { family: Family::TimeTransformed, order: 8 });
        assert_eq!(first(GENERAL, 1e-8, None), Candidate { family: Family::Galerkin, order: 8 });
        assert_eq!(first(GENERAL, 1e-12, None), Candidate { family: Family::Galerkin, order: 12 });
        assert_eq!(first(GENERAL, 1e-14, None), Candidate { family: Family::Galerkin, order: 16 });
        assert_eq!(first(FORCED, 1e-4, Some(20.0)), Candidate { family: Family::Galerkin, order: 4 });
        assert_eq!(first(FORCED, 1e-6, Some(20.0)), Candidate { family: Family::Galerkin, order: 8 });
    }

    #[test]
    fn fallbacks_and_fixed_parts() {
        let c = candidates::<2>(GENERAL, 1e-8, None, Fixed::default()).unwrap();
        assert_eq!(c.iter().map(|c| c.0.order).collect::<Vec<_>>(), [8, 6]);
        let fixed = Fixed { family: Some(Family::Galerkin), order: Some(12) };
        assert_eq!(candidates::<2>(KEPLER, 1e-8, None, fixed).unwrap()[0].0.order, 12);
        let bad = Fixed { family: Some(Family::Composition), order: Some(5) };
        assert!(matches!(candidates::<2>(KEPLER, 1e-8, None, bad), Err(Error::InvalidMethod { .. })));
        let tt = Fixed { family: Some(Family::TimeTransformed), order: None };
        assert!(matches!(candidates::<2>(GENERAL, 1e-8, None, tt), Err(Error::NotSeparable { .. })));
    }
}
