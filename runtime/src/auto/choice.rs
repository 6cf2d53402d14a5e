//! Which method a tolerance-driven solve tries, in order, and why: from the
//! structure facts `#[lagrangian]` proves, the tolerance, and the variation
//! of the step density a pilot measures.
//!
//! | system | step density along the pilot | tolerance | first candidate |
//! | --- | --- | --- | --- |
//! | `½ vᵀMv − V(q)`, `M` constant, no forces | varies moderately: [`density_ratio`] above [`DENSITY_RATIO`], below [`UNIFORM_RATIO`] | `< 1e-8` ([`UNIFORM_RTOL`]) | Galerkin `s = 6` with uniform steps, then the time-transformed splitting |
//! | `½ vᵀMv − V(q)`, `M` constant, no forces | varies: [`density_ratio`] above [`DENSITY_RATIO`] | any (other than above) | explicit time-transformed splitting (logarithmic), Kahan–Li 8 |
//! | `½ vᵀMv − V(t, q)`, `M` constant, no forces | nearly uniform | any | the composition of Störmer–Verlet of fewer predicted stages ([`composition_order`]: Kahan–Li 8, or Yoshida 6 where Kahan–Li 8 would be held to its step cap), or Galerkin `s = 4 / 6 / 8` where the cost model predicts it cheaper |
//! | forces or dissipation | any | `≥ 1e-5` / `≥ 1e-11` / `≥ 1e-13` / tighter | Galerkin `s = 2 / 4 / 6 / 8` |
//! | anything else (non-separable, time-dependent, position-dependent mass), no forces | the linearisation's fastest rate nearly uniform: [`density_ratio`] at most [`HIGH_DEGREE_RATIO`] ([`uniform_high_degree`]) | `≥ 1e-8` ([`HIGHER_DEGREE_RTOL`]) / `≥ 1e-13` / tighter | Galerkin `s = 4 / 6 / 8`, `s = 6` at `ρh ≤ 0.7` ([`HIGH_DEGREE_RHO_H`]) |
//! | anything else | varies, or not surveyed ([`surveys_rates`]) | `≥ 1e-11` / `≥ 1e-13` / tighter | Galerkin `s = 4 / 6 / 8` |
//!
//! The orders follow the report's calibration: Kahan–Li 8 is the fastest
//! composition on the separable problems at every target, Galerkin `s = 4`
//! on the double pendulum at 1e-4 and 1e-7 and `s = 6` at 1e-10 (the
//! fastest there is `s = 8`, whose coarse pilot steps need Newton), pilot included; a lower order is faster only where the run is a few dozen
//! steps anyway. Between the composition and Galerkin on a
//! separable system the solve weighs predicted steps ([`predicted_steps`],
//! the harmonic oscillator's frequency error of each method at the
//! tolerance) by the cost of a step it times (high-order Galerkin wins on
//! the one-degree-of-freedom pendulums at tight tolerances, Kahan–Li 8 on
//! the outer solar system and the FPU chain, whose Galerkin steps cost
//! 10–90 composition steps).
//!
//! The candidates after the first are the fallbacks when a pilot fails: the
//! composition falls back to Galerkin, Galerkin to the next lower degree.

use crate::error::Error;
use crate::structure::Separability;
use crate::system::Lagrangian;

/// The step density ratio above which a time transformation is chosen:
/// `R = (mean ρ⁹)^{1/8} / (mean ρ)^{9/8}`, with the mean over time, is the
/// number of uniform steps an order-8 method needs (its error per unit time
/// grows as `ρ⁹ h⁸`) over the number a time transformation with steps
/// `∝ 1/ρ` needs for the same error. A time-transformed step costs about
/// 1.7 composition steps (the report's Kepler runs: 0.53 against
/// 0.31 µs), and the logarithmic time function gains more than the density
/// alone on the orbits it is made for: on Kepler `e = 0.5` (`R ≈ 2.1` over
/// an orbit, 1.45 from 64 samples along a survey) it needs 5.1 times fewer
/// steps than Kahan–Li 8 at every target of the report and is three times
/// faster. The survey finds 1.00–1.03 on the pendulum, Hénon–Heiles, the
/// FPU chain and the outer solar system.
pub const DENSITY_RATIO: f64 = 1.25;

/// The density ratio ([`density_ratio`]) below which, at tolerances below
/// [`UNIFORM_RTOL`], Galerkin `s = 6` with uniform steps is tried before
/// the time transformation: its order 12 pays for the uniform steps where
/// the density varies only moderately. The report's Kepler orbits: at
/// `e = 0.5` (survey ratio 2.0) `galerkin-fp-6` is the fastest at 1e-10
/// (404 steps, 0.146 ms, against 445 steps of the splitting, a Galerkin step
/// running in 0.36 µs against the splitting's 0.53 µs), while at `e = 0.9`
/// (3.9) the splitting is the fastest at every target.
pub const UNIFORM_RATIO: f64 = 3.0;

/// The relative tolerance below which [`UNIFORM_RATIO`] applies: on Kepler
/// `e = 0.5` the splitting is the fastest at the report's targets 1e-4 and
/// 1e-7 (calibrated `rtol ≥ 1.8e-7`), Galerkin `s = 6` at 1e-10.
pub const UNIFORM_RTOL: f64 = 1e-8;

/// The Galerkin degree of [`UNIFORM_RATIO`]: `s = 6` (order 12). `s = 8`
/// piloted from `ρh ≤ 1` ends 13 to 100 times off its estimate on Kepler
/// `e = 0.5` at `rtol ≤ 1e-9` (its coarse steps are short of the
/// asymptotic range).
pub const UNIFORM_GALERKIN_DEGREE: u32 = 6;

/// Whether Galerkin with uniform steps is tried before the time
/// transformation: a moderately varying density (`ratio` below
/// [`UNIFORM_RATIO`]) at a tolerance below [`UNIFORM_RTOL`].
pub fn uniform_galerkin(rtol: f64, ratio: f64) -> bool {
    rtol < UNIFORM_RTOL && ratio < UNIFORM_RATIO
}

/// `(mean ρ⁹)^{1/8} / (mean ρ)^{9/8}` of rates sampled uniformly in time
/// (see [`DENSITY_RATIO`]); `None` without positive finite samples.
pub fn density_ratio(rates: &[f64]) -> Option<f64> {
    let max = rates.iter().fold(0.0f64, |m, r| m.max(*r));
    if !(max > 0.0 && max.is_finite()) {
        return None;
    }
    let n = rates.len() as f64;
    let mean = rates.iter().map(|r| r / max).sum::<f64>() / n;
    let mean9 = rates.iter().map(|r| (r / max).powi(9)).sum::<f64>() / n;
    Some(mean9.powf(1.0 / 8.0) / mean.powf(9.0 / 8.0))
}

/// The relative frequency error of Kahan–Li 8 on the harmonic oscillator is
/// `C (ωh)⁸` with this `C` (the rotation angle of the composed map, computed
/// to 40 digits: `4.75e-6` up to `ωh = 0.1`, `5.0e-6` at `0.4`, `5.7e-6`
/// at 1).
pub const KAHAN_LI8_CONSTANT: f64 = 4.8e-6;

/// The same constant of Yoshida 6 (`3.77e-3` up to `ωh = 0.5`, `3.55e-3` at
/// 1.5), order 6.
pub const YOSHIDA6_CONSTANT: f64 = 3.8e-3;

/// The largest `ρ h` of a composition's step, with `ρ` the fastest rate met
/// at the start and along the survey: Kahan–Li 8 on the report's FPU-β
/// chain diverges at `ρ h ≈ 4.4` and its Richardson estimate is already
/// five times low at `ρ h ≈ 1.9`.
pub const COMPOSITION_RHO_H: f64 = 1.5;

/// The fraction of the tolerance the choice and the pilot aim at: the
/// Richardson estimate is asymptotic, and the error of a fixed-step method
/// is not monotone in `h`.
pub const SAFETY: f64 = 0.3;

/// The relative frequency error that spreads `SAFETY · rtol` over the
/// `rho_span = ρT` radians of the fastest mode (at least one).
pub fn frequency_error(rtol: f64, rho_span: f64) -> f64 {
    SAFETY * rtol / rho_span.max(1.0)
}

/// The stages (trapezoid sub-steps, one force each) a composition of
/// order `order` spends per step: Yoshida 4, Yoshida 6, Kahan–Li 8.
pub fn composition_stages(order: u32) -> f64 {
    match order {
        4 => 3.0,
        6 => 7.0,
        _ => 15.0,
    }
}

/// The stages of a composition of `order` (6 or 8) over the span, as
/// [`predicted_steps`] at [`COMPOSITION_RHO_H`] times its
/// [`composition_stages`]: the quantity the order is chosen by.
pub fn composition_cost(order: u32, rtol: f64, rho_span: f64) -> f64 {
    let constant = if order == 6 { YOSHIDA6_CONSTANT } else { KAHAN_LI8_CONSTANT };
    let eps = frequency_error(rtol, rho_span);
    composition_stages(order) * predicted_steps(constant, order, COMPOSITION_RHO_H, eps, rho_span.max(1.0))
}

/// The largest `ρh` the cost model lets Galerkin take: beyond it Newton
/// needs more iterations and the nonlinear error terms the linear model
/// leaves out take over (the report's calibrated Galerkin steps on the
/// pendulum reach `ρh ≈ 0.7–0.9` at `s = 6–8`).
pub const GALERKIN_RHO_H: f64 = 1.0;

/// The cost of a Galerkin step of degree `s` over one of degree 4, as
/// `(s/4)^1.7`: the report's calibrated runs give 1.8–2.1 at `s = 6` and
/// 3.3–5 at `s = 8` on the pendulum, Hénon–Heiles and the double pendulum.
pub fn galerkin_step_cost(s: u32) -> f64 {
    (f64::from(s) / 4.0).powf(1.7)
}

/// The steps a method with frequency error `C (ρh)^p` and `ρh ≤ cap` needs
/// over `rho_span = ρ T` radians of the fastest mode for the relative
/// frequency error `eps`.
pub fn predicted_steps(constant: f64, order: u32, cap: f64, eps: f64, rho_span: f64) -> f64 {
    let rho_h = (eps / constant).powf(1.0 / f64::from(order)).min(cap);
    (rho_span / rho_h).max(1.0)
}

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

/// The composition of fewer stages over the span (see
/// [`composition_cost`]) among Kahan–Li 8 and Yoshida 6, with
/// `rho_span = ρT` the radians of the fastest mode at the start; Kahan–Li 8
/// without it. Unhindered, Kahan–Li 8 needs fewer stages wherever its step
/// is below [`COMPOSITION_RHO_H`] (from a frequency error of about `1e-4`
/// down: the report's separable problems at every target); where that cap
/// holds it, its order buys nothing and Yoshida 6 at the same or a finer
/// step costs 7 stages against 15 (the FPU-β chain at `rtol = 1e-3`, whose
/// fastest modes are barely excited).
pub fn composition_order(rtol: f64, rho_span: Option<f64>) -> u32 {
    match rho_span.filter(|r| r.is_finite() && *r > 0.0) {
        Some(r) if composition_cost(6, rtol, r) < composition_cost(8, rtol, r) => 6,
        _ => 8,
    }
}

/// The relative tolerance below which a system without forces that the
/// compositions do not apply to runs Galerkin `s = 6` rather than `s = 4`:
/// on the double pendulum at the report's target 1e-10 (calibrated
/// `rtol = 5.6e-10`) `s = 6` takes a 77-step pilot and 400 steps, 12.8 M
/// instructions, where `s = 4` took 740 and 743 steps, 21.2 M, against 7.7 M
/// of the fastest, fixed-point Galerkin `s = 8` at 200 steps; at 1e-7
/// (calibrated `rtol = 1e-6`) `s = 4` stays the faster. `s = 8` piloted at
/// the same step is 20.4 M: its coarse pilot steps need Newton.
pub const HIGHER_DEGREE_RTOL: f64 = 1e-8;

/// The largest `ρh` of Galerkin `s ≥ 6` on a system not proven
/// `½ vᵀMv − V(q)` (`ρ` the fastest rate of the linearisation at the
/// start, where no survey measures it along the orbit), for the pilot's
/// rounds and the final run. Above it a step that contains the fastest part
/// of the motion makes an error the pilot does not see when that part lies
/// at its start, where it is a node: Kepler in polar coordinates from
/// pericentre over 10 orbits with `s = 6` ends 5.8e-8 from the reference
/// at `ρh = 1` (281 steps), where 1, 2 and 4 orbits stepped with the same
/// `h`, a whole number of steps per orbit, end 2.1e-10 per orbit; at
/// `ρh = 0.5` the two agree (2.9e-12 and 2.9e-13 per orbit), and a pilot
/// at `ρh = 0.7` estimates 1.8e-10 for a run that ends 1.4e-10
/// (`rtol = 1e-10`, `HORIZON=0.01 auto_solve kepler-polar 1e-10`).
pub const HIGH_DEGREE_RHO_H: f64 = 0.7;

/// The [`density_ratio`] of the linearisation's fastest rate along a pilot
/// run up to which a system the compositions do not apply to counts as
/// uniform for [`HIGHER_DEGREE_RTOL`] (see [`uniform_high_degree`]). The
/// survey along the first coarse run of the `s = 6` pilot (up to 64
/// samples of [`guidance::linearize`](crate::guidance::linearize)) measures
/// 1.00 on the double pendulum (from `(1, −0.5)` rad, `rtol = 5.6e-10`) and
/// 2.30 on Kepler `e = 0.5` in polar coordinates from pericentre (the
/// report's 1 000 orbits, `rtol = 1.8e-12`); the bound lies between.
pub const HIGH_DEGREE_RATIO: f64 = 1.5;

/// Whether the fastest rate is surveyed along the pilot of a system the
/// compositions do not apply to: without forces, at the tolerances where
/// its Galerkin degree depends on it (below [`HIGHER_DEGREE_RTOL`], at or
/// above `1e-13`).
pub fn surveys_rates(facts: Facts, rtol: f64) -> bool {
    !facts.explicit() && !facts.forced && (1e-13..HIGHER_DEGREE_RTOL).contains(&rtol)
}

/// Galerkin `s = 6` below [`HIGHER_DEGREE_RTOL`] on a system the
/// compositions do not apply to, its steps held to [`HIGH_DEGREE_RHO_H`]:
/// only where the survey ([`surveys_rates`]) found the fastest rate nearly
/// uniform along the pilot, `ratio` at most [`HIGH_DEGREE_RATIO`]. Where it
/// varies, a step that contains the fastest part of the motion makes an
/// error a pilot from the start does not see, and no cap from the start
/// bounds it: Kepler in polar coordinates (`e = 0.5`, from pericentre, over
/// the report's 1 000 orbits) held to `ρh ≤ 0.7` ends 4.8e-8 from the
/// reference at every `rtol` from `5.6e-9` down to `3.2e-11` (55 196 steps
/// of `s = 6`, the cap), 40 times the 1.1e-9 asked at `1.8e-12`.
pub fn uniform_high_degree(facts: Facts, rtol: f64, ratio: Option<f64>) -> bool {
    surveys_rates(facts, rtol) && ratio.is_some_and(|r| r <= HIGH_DEGREE_RATIO)
}

/// Galerkin `s = 4` for most tolerances: the report's fastest project
/// method on the double pendulum at `1e-4` and `1e-7` with its pilot; with
/// forces `s = 2` at coarse tolerances (the sensor's fastest at `1e-4`).
/// `s = 6` below `1e-11`, and below [`HIGHER_DEGREE_RTOL`] where the rates
/// are `uniform` ([`uniform_high_degree`]).
fn galerkin_degree(rtol: f64, forced: bool, uniform: bool) -> u32 {
    match (forced, rtol) {
        (true, r) if r >= 1e-5 => 2,
        (_, r) if r >= 1e-11 && !uniform => 4,
        (_, r) if r >= 1e-13 => 6,
        (_, _) => 8,
    }
}

/// `Ok` when `order` exists in `family`.
fn check_order<const N: usize>(family: Family, order: u32) -> Result<(), Error> {
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
/// `density_ratio` is the survey's [`density_ratio`] (`None` before it is
/// measured).
/// `rho_span = ρT` (the fastest rate at the start times the span, `None`
/// where it is not measured) chooses the composition's order.
pub fn candidates<const N: usize>(
    facts: Facts,
    rtol: f64,
    density_ratio: Option<f64>,
    rho_span: Option<f64>,
    fixed: Fixed,
) -> Result<Vec<(Candidate, String)>, Error> {
    let mut out: Vec<(Candidate, String)> = Vec::new();
    let varying = density_ratio.is_some_and(|r| r > DENSITY_RATIO);
    let order_in = |family: Family, default: u32| {
        fixed.order.filter(|_| fixed.family == Some(family) || fixed.family.is_none()).unwrap_or(default)
    };
    let uniform = uniform_high_degree(facts, rtol, density_ratio);
    let galerkin_order = 2 * galerkin_degree(rtol, facts.forced, uniform);
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
    // The predicted stages behind the order, when the order was chosen.
    let stages_why = || match rho_span.filter(|_| fixed.order.is_none()) {
        Some(r) => format!(
            " (predicted {:.0} stages of Yoshida 6 against {:.0} of Kahan–Li 8 over ρT = {r:.0})",
            composition_cost(6, rtol, r),
            composition_cost(8, rtol, r)
        ),
        None => String::new(),
    };
    let tt = || {
        // Kahan–Li 8: the report's fastest on the eccentric orbits at every target.
        let order = order_in(Family::TimeTransformed, 8);
        (
            Candidate { family: Family::TimeTransformed, order },
            format!(
                "separable, autonomous and unforced, and the step density varies along the orbit (uniform \
                 steps need {ratio:.1}× those of steps ∝ 1/ρ, > {DENSITY_RATIO}): steps uniform in s = ∫dt/r"
            ),
        )
    };
    let composition = || {
        let order = order_in(Family::Composition, composition_order(rtol, rho_span));
        (
            Candidate { family: Family::Composition, order },
            if facts.explicit() {
                match density_ratio {
                    Some(r) => format!(
                        "separable with a constant mass matrix and no forces, step density nearly uniform \
                         (ratio {r:.2} ≤ {DENSITY_RATIO}): explicit composition of order {order} for rtol = {rtol:e}{}",
                        stages_why()
                    ),
                    None => format!(
                        "separable with a constant mass matrix and no forces: explicit composition of order {order} for rtol = {rtol:e}{}",
                        stages_why()
                    ),
                }
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
    // The survey's verdict, where it decided the degree.
    let why = match density_ratio.filter(|_| surveys_rates(facts, rtol)) {
        Some(r) if uniform => format!(
            "{why}, the fastest rate nearly uniform along the pilot (density ratio {r:.2} ≤ {HIGH_DEGREE_RATIO}), \
             steps held to ρh ≤ {HIGH_DEGREE_RHO_H}"
        ),
        Some(r) => {
            format!("{why}, the fastest rate varying along the pilot (density ratio {r:.2} > {HIGH_DEGREE_RATIO})")
        }
        None => why.to_string(),
    };
    let why = why.as_str();
    match fixed.family {
        Some(Family::TimeTransformed) => out.push(tt()),
        Some(Family::Composition) => out.push(composition()),
        Some(Family::Galerkin) => {
            let order = order_in(Family::Galerkin, galerkin_order);
            out.push(galerkin(order, "Galerkin as asked"));
        }
        None => {
            if facts.transformable() && varying {
                if uniform_galerkin(rtol, ratio) && fixed.order.is_none() {
                    out.push(galerkin(
                        2 * UNIFORM_GALERKIN_DEGREE,
                        &format!(
                            "separable, autonomous and unforced, the step density varying only moderately (uniform \
                             steps need {ratio:.1}× those of steps ∝ 1/ρ for order 8, < {UNIFORM_RATIO}) and a tight \
                             tolerance (< {UNIFORM_RTOL:e}): uniform steps of order 12"
                        ),
                    ));
                }
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
        candidates::<2>(facts, rtol, ratio, None, Fixed::default()).unwrap()[0].0
    }

    #[test]
    fn the_table() {
        assert_eq!(first(KEPLER, 1e-10, Some(1.2)), Candidate { family: Family::Composition, order: 8 });
        assert_eq!(first(KEPLER, 1e-5, Some(1.2)), Candidate { family: Family::Composition, order: 8 });
        assert_eq!(first(KEPLER, 1e-10, Some(20.0)), Candidate { family: Family::TimeTransformed, order: 8 });
        // A moderately varying density at a tight tolerance: uniform Galerkin s = 6 first.
        assert_eq!(first(KEPLER, 1e-10, Some(2.0)), Candidate { family: Family::Galerkin, order: 12 });
        assert_eq!(first(KEPLER, 1e-10, Some(3.9)), Candidate { family: Family::TimeTransformed, order: 8 });
        assert_eq!(first(KEPLER, 1e-7, Some(2.0)), Candidate { family: Family::TimeTransformed, order: 8 });
        let c = candidates::<2>(KEPLER, 1e-10, Some(2.0), None, Fixed::default()).unwrap();
        assert_eq!(c[1].0, Candidate { family: Family::TimeTransformed, order: 8 });
        assert_eq!(first(GENERAL, 1e-8, None), Candidate { family: Family::Galerkin, order: 8 });
        // Below 1e-8, s = 6 only where the survey found the fastest rate nearly uniform.
        assert_eq!(first(GENERAL, 1e-10, None), Candidate { family: Family::Galerkin, order: 8 });
        assert_eq!(first(GENERAL, 1e-10, Some(1.1)), Candidate { family: Family::Galerkin, order: 12 });
        assert_eq!(first(GENERAL, 1e-10, Some(3.0)), Candidate { family: Family::Galerkin, order: 8 });
        assert_eq!(first(GENERAL, 1e-7, Some(1.1)), Candidate { family: Family::Galerkin, order: 8 });
        assert_eq!(first(FORCED, 1e-10, Some(1.1)), Candidate { family: Family::Galerkin, order: 8 });
        assert_eq!(first(GENERAL, 1e-12, None), Candidate { family: Family::Galerkin, order: 12 });
        assert_eq!(first(GENERAL, 1e-14, None), Candidate { family: Family::Galerkin, order: 16 });
        assert_eq!(first(FORCED, 1e-4, Some(20.0)), Candidate { family: Family::Galerkin, order: 4 });
        assert_eq!(first(FORCED, 1e-6, Some(20.0)), Candidate { family: Family::Galerkin, order: 8 });
    }

    #[test]
    fn the_density_ratio_weighs_the_fastest_parts() {
        assert!((density_ratio(&[2.0; 8]).unwrap() - 1.0).abs() < 1e-12);
        // One sample in eight at four times the rate: (mean ρ⁹)^{1/8}/(mean ρ)^{9/8}.
        let mut rates = [1.0; 8];
        rates[3] = 4.0;
        let expected = ((7.0 + 4f64.powi(9)) / 8.0).powf(1.0 / 8.0) / (11.0f64 / 8.0).powf(9.0 / 8.0);
        assert!((density_ratio(&rates).unwrap() - expected).abs() < 1e-12 * expected);
        assert!(expected > 2.5, "{expected}");
        assert_eq!(density_ratio(&[]), None);
    }

    #[test]
    fn predicted_steps_follow_the_frequency_error() {
        // Kahan–Li 8 at eps = C (0.1)^8: ρh = 0.1, 100 steps over 10 radians.
        let eps = KAHAN_LI8_CONSTANT * 1e-8;
        assert!((predicted_steps(KAHAN_LI8_CONSTANT, 8, 1.5, eps, 10.0) - 100.0).abs() < 1e-9);
        // The cap holds.
        assert_eq!(predicted_steps(KAHAN_LI8_CONSTANT, 8, 1.5, 1e-1, 15.0), 10.0);
    }

    #[test]
    fn the_order_follows_the_predicted_stages() {
        // Unhindered, Kahan–Li 8 needs fewer stages: ρh = (eps/C)^{1/8} below the cap.
        let (rtol, rho_span) = (1e-8, 100.0);
        let eps = frequency_error(rtol, rho_span);
        let kl8 = 15.0 * rho_span / (eps / KAHAN_LI8_CONSTANT).powf(1.0 / 8.0);
        let y6 = 7.0 * rho_span / (eps / YOSHIDA6_CONSTANT).powf(1.0 / 6.0);
        assert!((composition_cost(8, rtol, rho_span) - kl8).abs() < 1e-9 * kl8);
        assert!((composition_cost(6, rtol, rho_span) - y6).abs() < 1e-9 * y6);
        assert_eq!(composition_order(rtol, Some(rho_span)), 8);
        // Both held to ρh = 1.5 (frequency error 0.05): 7 stages against 15 per step.
        assert_eq!(composition_cost(8, 0.5, 3.0), 15.0 * 3.0 / COMPOSITION_RHO_H);
        assert_eq!(composition_cost(6, 0.5, 3.0), 7.0 * 3.0 / COMPOSITION_RHO_H);
        // Kahan–Li 8 held to its cap, Yoshida 6 at ρh = 0.96 (frequency error 3e-3).
        let loose = 0.1;
        assert_eq!(composition_cost(8, loose, 10.0), 15.0 * 10.0 / COMPOSITION_RHO_H);
        assert!(composition_cost(6, loose, 10.0) < 0.75 * composition_cost(8, loose, 10.0));
        assert_eq!(composition_order(loose, Some(10.0)), 6);
        assert_eq!(composition_order(loose, None), 8);
        let c = candidates::<2>(KEPLER, loose, Some(1.0), Some(10.0), Fixed::default()).unwrap();
        assert_eq!(c[0].0, Candidate { family: Family::Composition, order: 6 });
        // A time transformation stays of order 8.
        let c = candidates::<2>(KEPLER, loose, Some(20.0), Some(10.0), Fixed::default()).unwrap();
        assert_eq!(c[0].0, Candidate { family: Family::TimeTransformed, order: 8 });
        // A fixed order wins.
        let fixed = Fixed { family: None, order: Some(8) };
        assert_eq!(candidates::<2>(KEPLER, loose, Some(1.0), Some(10.0), fixed).unwrap()[0].0.order, 8);
    }

    #[test]
    fn fallbacks_and_fixed_parts() {
        let c = candidates::<2>(GENERAL, 1e-8, None, None, Fixed::default()).unwrap();
        assert_eq!(c.iter().map(|c| c.0.order).collect::<Vec<_>>(), [8, 6]);
        let fixed = Fixed { family: Some(Family::Galerkin), order: Some(12) };
        assert_eq!(candidates::<2>(KEPLER, 1e-8, None, None, fixed).unwrap()[0].0.order, 12);
        let bad = Fixed { family: Some(Family::Composition), order: Some(5) };
        assert!(matches!(candidates::<2>(KEPLER, 1e-8, None, None, bad), Err(Error::InvalidMethod { .. })));
        let tt = Fixed { family: Some(Family::TimeTransformed), order: None };
        assert!(matches!(candidates::<2>(GENERAL, 1e-8, None, None, tt), Err(Error::NotSeparable { .. })));
    }
}
