//! The tolerance-driven solve: choose, pilot, run.

use core::cell::{OnceCell, RefCell};

use crate::Galerkin;
use crate::error::Error;
use crate::guidance::{self, Rule};
use crate::integrator::{Composition, Integrator};
use crate::solution::{Plan, Solution, SolveError, Stepping};
use crate::system::Lagrangian;
use crate::time_transform::{ExplicitTimeTransformed, TimeFunction};

use super::choice::{self, COMPOSITION_RHO_H, Candidate, Facts, Family, Fixed, SAFETY};
use super::pilot::{self, Clock, Cost, Growth, Probe, Rates, Richardson};
use super::tolerance::Tolerance;

/// The fraction of the span the pilot covers (at least one period of the
/// fastest mode at the start, at most the whole span).
const PILOT_FRACTION: f64 = 0.1;
/// [`PILOT_FRACTION`] from [`LOOSE_RTOL`] up. A loose tolerance's error is
/// far above round-off from the pilot's first checkpoints, so its growth
/// shows over a shorter pilot; and the pilot is a fixed share of the work
/// (its coarse and fine runs over `Tp` cost `3 Tp/T` of a final run at the
/// piloted step), which on the few-dozen-step runs a loose tolerance asks
/// for is most of what the solve spends beyond the final run.
const LOOSE_PILOT_FRACTION: f64 = 0.05;
/// The relative tolerance from which the pilot covers
/// [`LOOSE_PILOT_FRACTION`] of the span.
const LOOSE_RTOL: f64 = 1e-5;
/// The least span of the pilot on a system with a dissipation function, in
/// periods of the fastest mode at the start (one period without). The
/// dissipation damps the errors the steps make and their envelope levels
/// off rather than growing with the phase (the sensor measures `t^0.3`),
/// so half a period shows it; on a span of a few periods a whole one is most
/// of the solve's cost beside its final run: the report's sensor (6.4
/// periods) piloted 18 steps of Galerkin for a final run of 46 at
/// `rtol = 1e-3` and of 25 at `5.6e-6`.
const DISSIPATIVE_PILOT_PERIODS: f64 = 0.5;
/// The step the pilot's estimate leads to, over the pilot's step, that is
/// taken without piloting again: finer steps down to a quarter (the
/// asymptotic model `e ∝ h^p` holds better at finer steps, and an estimate
/// from a coarse step still in its pre-asymptotic range errs on the safe
/// side). A coarser composition step up to twice the pilot's is not
/// extrapolated to but replaced by the pilot's own step, whose error is
/// measured: near a composition's step cap the error at the end is not
/// monotone in `h` (the pendulum from 1 rad at `rtol = 1e-4`: Kahan–Li 8
/// piloted at `h = 0.187` asks for 1.29 times it, where the true error is
/// 12 times smaller than at `0.187`, not 7.4 times larger, and the estimate
/// 178 times the error).
const ACCEPT: core::ops::RangeInclusive<f64> = 0.25..=2.0;
/// The least step ratio below [`ACCEPT`] from which the time
/// transformation pilots again by halving its `σ`: the round's fine run at
/// `σ/2` is the next round's coarse run, and only a run at `σ/4` is new. In
/// units of a coarse run over the pilot, a halving costs 4 and a new pair at
/// `r σ` costs `3/r`; `k` halvings reach `r ≥ 1/4` for about `1/r`. Kepler
/// `e = 0.9` at `rtol = 1e-10` pilots 120 steps where a new pair took 228,
/// to the same final `σ` (within 0.5%) and error. Below, a pair at the
/// clamped `σ/16` (48) costs less than the four halvings (60). Galerkin and
/// the compositions pilot a new pair: halved from a coarse step, their
/// estimates are 11 to 22 times their largest error on the double pendulum
/// (Galerkin `s = 4` from `h = 0.047`, whose error falls faster than `h⁸`
/// below it), and the pendulum's Kahan–Li 8 at `rtol = 1e-7` estimated
/// 3.0e-8 for a run that ended 1.4e-7 from the reference (the compositions'
/// error is not monotone in `h` near their cap, see [`ACCEPT`]).
const HALVE_FROM: f64 = 1.0 / 32.0;
/// The least step ratio [`ACCEPT`] takes from a composition piloted at its
/// step cap, where the error may not yet be `∝ h^p`.
const CAPPED_ACCEPT: f64 = 0.5;
/// Pilot rounds per candidate before its last step is taken as it is.
const ROUNDS: usize = 5;
/// Checkpoints of the pilot, each twice as far from the start as the one before.
const CHECKPOINTS: usize = 7;
/// The most samples of `ρ` the step-density survey takes (every k-th node).
const SURVEY_SAMPLES: usize = 64;
/// The survey stops early once its density ratio exceeds this multiple of
/// [`DENSITY_RATIO`](choice::DENSITY_RATIO): the time transformation is
/// then chosen whatever the rest of the orbit shows.
const SURVEY_STOP: f64 = 2.0;
/// Power iterations for `ρ` at the start (from no known mode).
const START_ITERATIONS: usize = 30;
/// Coarse steps a time-transformed pilot takes at least: its two runs are
/// compared node by node. The final runs of the report's Kepler orbits at
/// `rtol ≥ 1e-4` take 8 to 9 steps per orbit, the pilot's span.
const TT_PILOT_STEPS: u64 = 8;

/// A candidate's pilot: `(step, estimated error at the end with that step)`,
/// its Richardson estimate, and the scale of the solution.
type Piloted = ((f64, f64), Richardson, f64);
/// The least cost of a Galerkin step in composition steps of Kahan–Li 8 on
/// the same system of at most four coordinates, `(s/4)^{-1.7}` times that
/// of `s = 4`: the report's calibrated runs give 1.9 (`s = 4`, pendulum)
/// to 10 (`s = 4`, outer solar system) for `s = 4`. See
/// [`galerkin_min_cost`] for more coordinates.
const GALERKIN_MIN_COST: f64 = 1.9;

/// [`GALERKIN_MIN_COST`] on `n` coordinates, times `n/4` above four: a
/// Galerkin step solves for `s·n` unknowns with derivatives in `n`
/// directions where a composition step takes 15 gradients, and the report's
/// calibrated runs give 10 composition steps per Galerkin step on the outer
/// solar system (18 coordinates, bound 8.6) and 10 to 90 on the FPU-β chain
/// (16, bound 7.6). Below the bound the cost model times nothing.
fn galerkin_min_cost(n: usize) -> f64 {
    GALERKIN_MIN_COST * (n as f64 / 4.0).max(1.0)
}

/// Steps per timed round of the cost model.
const TIMED_STEPS: usize = 8;
/// Timed rounds of the cost model (the least is kept: a round the scheduler
/// interrupts is slower, never faster).
const TIMED_ROUNDS: usize = 2;

/// The answer of a tolerance-driven solve: the [`Solution`] of the final
/// run and the [`Estimate`] of its error.
#[derive(Clone, Debug, PartialEq)]
pub struct Solved<const N: usize> {
    /// The final run, as any [`Stepping::solve`] returns it.
    pub solution: Solution,
    /// The error estimate, the method and why, and the pilot's cost.
    pub estimate: Estimate,
}

/// What the solve estimates and decided.
#[derive(Clone, Debug, PartialEq)]
pub struct Estimate {
    /// The estimated global error `max_i |q_i − q_i^exact|` up to the end of
    /// the span: the largest the run makes (the pilot's running maximum,
    /// extrapolated). The error at the end itself may be several times
    /// smaller, where the end falls near a zero of an oscillation's error.
    pub error: f64,
    /// The scale `Q` of the positions the relative tolerance refers to.
    pub scale: f64,
    /// The absolute error asked for, `rtol · Q + atol`.
    pub requested: f64,
    /// The pilot measured the error over `[t0, measured_until]` and
    /// extrapolated it to the end with [`growth`](Self::growth).
    pub measured_until: f64,
    /// The growth of the error the pilot measured.
    pub growth: Growth,
    /// The method that ran.
    pub method: Candidate,
    /// Its name.
    pub method_name: String,
    /// Why it was chosen, in one line.
    pub reason: String,
    /// The step: `h`, or `σ` in the new time of the time transformation.
    pub step: f64,
    /// The survey's [`density_ratio`](super::choice::density_ratio) of the
    /// linearisation's fastest rate, when it ran (only for systems the time
    /// transformation applies to), over the part of the pilot's span it
    /// covered (it stops early once the ratio is clearly above the
    /// threshold).
    pub density_ratio: Option<f64>,
    /// What the pilot cost.
    pub pilot: Cost,
    /// Candidates whose pilot failed before this one: `method: error`.
    pub failures: Vec<String>,
}

/// A tolerance-driven solve: the method, its order and its step are chosen
/// to meet a [`Tolerance`] at the end of the span, from the structure facts
/// of the system and a pilot run (see the [module](super)).
///
/// ```
/// use lagrangian_runtime::auto::{Auto, Tolerance};
/// use lagrangian_runtime::{Lagrangian, Plan, Scalar, Separability};
///
/// #[derive(Clone)]
/// struct Oscillator;
/// impl Lagrangian<1> for Oscillator {
///     const AUTONOMOUS: bool = true;
///     const CYCLIC: [bool; 1] = [false];
///     const SEPARABILITY: Separability = Separability::ConstantMass;
///     fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 1], v: [D; 1]) -> D {
///         (v[0] * v[0] - q[0] * q[0]) * 0.5
///     }
/// }
///
/// let solved = Auto::new(Oscillator, 0.0, [1.0], [0.0]).tolerance(Tolerance::relative(1e-8)).solve(Plan::until(20.0))?;
/// let q = solved.solution.q.last().unwrap()[0];
/// assert!((q - 20f64.cos()).abs() < 1e-7);
/// assert!(solved.estimate.error < 1e-8);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Clone, Debug)]
pub struct Auto<S, const N: usize> {
    system: S,
    t0: f64,
    q0: [f64; N],
    v0: [f64; N],
    tolerance: Tolerance,
    fixed: Fixed,
    step: Option<f64>,
    /// The composition started from the initial data: the survey's rates,
    /// the pilot's runs, the cost model's timing and the final run of every
    /// order start from a copy of it with their own weights and step, which
    /// shares its `M⁻¹` (on the FPU-β chain of 16 masses a start costs as
    /// much as five Kahan–Li 8 steps, and a solve starts a dozen runs).
    started: RefCell<Option<Integrator<S, Composition, N>>>,
    /// The time transformation's density at the start, found once: the
    /// survey, the pilot and the final run's round-off each read it, and
    /// each reading started the splitting (a tenth of a Kepler pilot round).
    density: OnceCell<Option<f64>>,
}

/// Solves `system` from `(t0, q0, v0)` to `t_end` within `tolerance`,
/// keeping every node: [`Auto`] with the defaults.
pub fn solve_to<S: Lagrangian<N> + Clone, const N: usize>(
    system: S,
    t0: f64,
    q0: [f64; N],
    v0: [f64; N],
    t_end: f64,
    tolerance: Tolerance,
) -> Result<Solved<N>, SolveError> {
    Auto::new(system, t0, q0, v0).tolerance(tolerance).solve(Plan::until(t_end))
}

impl<S: Lagrangian<N> + Clone, const N: usize> Auto<S, N> {
    /// A solve from `(t0, q0, v0)` with the default tolerance `rtol = 1e-8`.
    pub fn new(system: S, t0: f64, q0: [f64; N], v0: [f64; N]) -> Self {
        Self {
            system,
            t0,
            q0,
            v0,
            tolerance: Tolerance::relative(1e-8),
            fixed: Fixed::default(),
            step: None,
            started: RefCell::new(None),
            density: OnceCell::new(),
        }
    }

    /// The tolerance to meet.
    pub fn tolerance(mut self, tolerance: Tolerance) -> Self {
        self.tolerance = tolerance;
        self
    }

    /// Fixes the method family; the order and step are still chosen.
    pub fn family(mut self, family: Family) -> Self {
        self.fixed.family = Some(family);
        self
    }

    /// Fixes the order (of the fixed family, or of the one chosen).
    pub fn order(mut self, order: u32) -> Self {
        self.fixed.order = Some(order);
        self
    }

    /// Fixes the step (`h`, or `σ` for the time transformation): the pilot
    /// then only estimates the error of that step.
    pub fn step(mut self, step: f64) -> Self {
        self.step = Some(step);
        self
    }

    /// Chooses, pilots and runs to the end of `plan` (which also says what
    /// the [`Solution`] keeps). Typed refusals: [`Error::InvalidTolerance`],
    /// [`Error::InvalidSpan`], [`Error::ToleranceUnreachable`],
    /// [`Error::Chaotic`], [`Error::NoMethod`] (every candidate's pilot
    /// failed), all as [`SolveError::Step`].
    pub fn solve(self, plan: Plan<'_>) -> Result<Solved<N>, SolveError> {
        let clock = Clock::start();
        let t_end = plan.end();
        self.tolerance.validate()?;
        if !(self.t0.is_finite() && t_end.is_finite() && t_end > self.t0) {
            return Err(Error::InvalidSpan { t0: self.t0, t_end }.into());
        }
        if let Some(h) = self.step {
            Error::check_step(h)?;
        }
        let facts = Facts::of::<S, N>();
        let span = t_end - self.t0;
        // `½ vᵀMv − V(q)`: power iteration on the gradient, a fraction of the
        // cost of the dense linearisation on many coordinates, with the
        // `M⁻¹` the composition's start forms (once for every run).
        let mut rates = if facts.explicit() {
            self.composition_at(8, span).ok().and_then(|it| it.inverse_mass()).map(Rates::new)
        } else {
            None
        };
        let rho = if facts.explicit() {
            rates.as_mut().and_then(|r| r.at(&self.system, self.t0, &self.q0, START_ITERATIONS))
        } else {
            guidance::linearize(&self.system, self.t0, self.q0, self.v0).map(|l| l.fastest).ok()
        }
        .filter(|r| *r > 0.0 && r.is_finite());
        // One period of the fastest mode at the start, at least (half of one
        // with a dissipation function).
        let fraction = if self.tolerance.rtol >= LOOSE_RTOL { LOOSE_PILOT_FRACTION } else { PILOT_FRACTION };
        let periods = if S::HAS_DISSIPATION { DISSIPATIVE_PILOT_PERIODS } else { 1.0 };
        let least = rho.map_or(0.0, |r| periods * 2.0 * core::f64::consts::PI / r);
        let tp = self.t0 + (fraction * span).max(least).min(span);
        let checkpoints: [f64; CHECKPOINTS] =
            core::array::from_fn(|i| self.t0 + (tp - self.t0) * 0.5f64.powi((CHECKPOINTS - 1 - i) as i32));
        let settle = rho.map_or(0.0, |r| 2.0 * core::f64::consts::PI / r).min(0.25 * (tp - self.t0));
        let mut cost = Cost::default();
        let rho_span = rho.map(|r| r * span);
        let first = choice::candidates::<N>(facts, self.tolerance.rtol, None, rho_span, self.fixed)?;
        // The survey: how strongly the needed step density varies along the orbit.
        let mut density_ratio = None;
        let mut survey: Option<(Candidate, f64, Probe<N>)> = None;
        let mut rho_max = rho.unwrap_or(0.0);
        if facts.transformable() && self.fixed.family.is_none_or(|f| f == Family::TimeTransformed) {
            let c = first[0].0;
            let fixed_step = c.family != Family::TimeTransformed;
            let mut h = self.initial_step(c, rho, span);
            // `σ` in the new time: the step in `t` over the density at the start.
            if !fixed_step && let Some(g) = self.tt_density() {
                h /= g;
            }
            if fixed_step {
                h = h.min((tp - self.t0) / 4.0).min(rho.map_or(f64::INFINITY, |r| COMPOSITION_RHO_H / r));
            }
            // A step too coarse for the fastest part of the orbit fails: a finer one.
            for _ in 0..3 {
                let n = ((tp - self.t0) / h).ceil().max(1.0) as usize;
                // At most `SURVEY_SAMPLES` samples.
                let stride = n.div_ceil(SURVEY_SAMPLES).max(1);
                // The pilot's first coarse run, which this run then is: fixed
                // steps land on its nodes, a time transformation at its end.
                let landings = if fixed_step { self.pilot_times(h, &checkpoints) } else { vec![tp] };
                let stop = Some(SURVEY_STOP * choice::DENSITY_RATIO);
                if let Ok(p) = run_probe(c, &self, h, &landings, true, stride, rates.as_mut(), stop, false) {
                    cost.steps += p.steps;
                    let max = p.rates.iter().fold(0.0f64, |m, r| m.max(*r));
                    if max.is_finite() {
                        rho_max = rho_max.max(max);
                    }
                    density_ratio = choice::density_ratio(&p.rates);
                    // A survey stopped early is no pilot round.
                    survey = p.complete.then_some((c, h, p));
                    break;
                }
                h /= 4.0;
            }
        }
        // A system the compositions do not apply to: the fastest rate along
        // the first coarse run of Galerkin `s = 6`'s pilot, which this run
        // then is, decides between `s = 6` and `s = 4`
        // (`choice::uniform_high_degree`). It stops once its samples show
        // the rate varying: Kepler in polar coordinates over the report's
        // 1 000 orbits at `rtol = 1.8e-12` measures 2.30 over the whole
        // pilot, whose 4 014 steps the solve then does not reuse; 16 samples
        // (the first quarter) decide.
        if choice::surveys_rates(facts, self.tolerance.rtol)
            && self.fixed == Fixed::default()
            && self.step.is_none()
            && let Some(rho) = rho
        {
            let c = Candidate { family: Family::Galerkin, order: 12 };
            let h_max = (checkpoints[CHECKPOINTS - 1] - self.t0) / 4.0;
            let h = self.initial_step(c, Some(rho), span).min(choice::HIGH_DEGREE_RHO_H / rho).min(h_max);
            let n = ((tp - self.t0) / h).ceil().max(1.0) as usize;
            let stride = n.div_ceil(SURVEY_SAMPLES).max(1);
            let landings = self.pilot_times(h, &checkpoints);
            let mut general = Rates::linearised();
            let stop = Some(choice::HIGH_DEGREE_RATIO);
            if let Ok(p) = run_probe(c, &self, h, &landings, true, stride, Some(&mut general), stop, S::AUTONOMOUS) {
                cost.steps += p.steps;
                density_ratio = choice::density_ratio(&p.rates);
                // Where the rate varies, `s = 4` or an uncapped `s = 6` pilots
                // from its own step.
                let uniform = choice::uniform_high_degree(facts, self.tolerance.rtol, density_ratio);
                survey = (p.complete && uniform).then_some((c, h, p));
            }
        }
        let mut candidates = choice::candidates::<N>(facts, self.tolerance.rtol, density_ratio, rho_span, self.fixed)?;
        if facts.explicit()
            && self.fixed == Fixed::default()
            && self.step.is_none()
            && candidates[0].0.family == Family::Composition
            && let Some(rho) = rho
            && let Some(choice) = self.weigh_galerkin(candidates[0].0, rho, span)
        {
            candidates.insert(0, choice);
        }
        let mut failures = Vec::new();
        for (mut candidate, mut reason) in candidates {
            let h_cap = match candidate.family {
                Family::Composition if rho_max > 0.0 && self.step.is_none() => COMPOSITION_RHO_H / rho_max,
                // A high degree where no survey measured `ρ` along the
                // orbit: no round and no final run beyond the step whose
                // error a pilot from the start sees.
                Family::Galerkin
                    if candidate.order >= 12
                        && choice::uniform_high_degree(facts, self.tolerance.rtol, density_ratio)
                        && rho_max > 0.0
                        && self.step.is_none() =>
                {
                    choice::HIGH_DEGREE_RHO_H / rho_max
                }
                _ => f64::INFINITY,
            };
            let reuse = survey.take().filter(|s| s.0 == candidate).map(|s| (s.1, s.2));
            let beside = reuse
                .as_ref()
                .and_then(|r| self.lower_order_beside(candidate, r, span, &checkpoints, settle, h_cap, &mut cost));
            let piloted = match beside {
                Some((lower, q, why)) => {
                    reason = format!("{reason}; {why}");
                    candidate = lower;
                    Ok(q)
                }
                None => self.pilot(candidate, rho, span, &checkpoints, settle, h_cap, reuse, &mut cost),
            };
            let piloted = match piloted {
                Ok(p) if candidate.family == Family::Composition && candidate.order > 6 && p.0.0 >= 0.99 * h_cap => {
                    match self.lower_order_at_cap(candidate, &p, rho, span, &checkpoints, settle, h_cap, &mut cost) {
                        Some((lower, q, why)) => {
                            reason = format!("{reason}; {why}");
                            candidate = lower;
                            Ok(q)
                        }
                        None => Ok(p),
                    }
                }
                other => other,
            };
            match piloted {
                Ok((step, rich, scale)) => {
                    let requested = self.tolerance.bound(scale);
                    let (step, error) = step;
                    // Fixed steps divide the span: the step that runs is the
                    // chosen one or finer, and its error smaller by the order
                    // (over a short span, one or two steps, it is tens of
                    // times smaller).
                    let (step, error) = match candidate.family {
                        Family::TimeTransformed => (step, error),
                        _ => {
                            let fitted = span / (span / step).ceil();
                            (fitted, error * (fitted / step).min(1.0).powi(candidate.order as i32))
                        }
                    };
                    // The round-off of the final run, amplified like the error.
                    let steps = self.final_steps(candidate, step, span, rho);
                    let floor = pilot::roundoff(scale, steps, rich.growth, span);
                    let refusal = |floor| match rich.growth {
                        Growth::Exponential(rate) => Error::Chaotic { requested, floor, rate, t_end },
                        Growth::Power(_) => Error::ToleranceUnreachable { requested, floor },
                    };
                    if requested < floor {
                        return Err(refusal(floor).into());
                    }
                    // An estimate above the request is no answer, refused as
                    // the floor is. A pilot whose step follows its estimate
                    // ends at or below the target: only round-off (a
                    // difference of the pilot's runs at its level,
                    // extrapolated) or an exponential growth leaves it above,
                    // where no step of `f64` is shown to meet the request,
                    // whatever the method. A step the user fixed runs, its
                    // estimate reported.
                    if error > requested && self.step.is_none() {
                        return Err(refusal(error).into());
                    }
                    cost.seconds = clock.seconds();
                    let estimate = Estimate {
                        error,
                        scale,
                        requested,
                        measured_until: tp,
                        growth: rich.growth,
                        method: candidate,
                        method_name: candidate.name(),
                        reason,
                        step,
                        density_ratio,
                        pilot: cost,
                        failures,
                    };
                    let solution = self.run(candidate, step, plan)?;
                    return Ok(Solved { solution, estimate });
                }
                Err(e) => failures.push(format!("{}: {e}", candidate.name())),
            }
        }
        Err(Error::NoMethod { failures }.into())
    }

    /// Galerkin in place of the composition `c` on a separable system, when
    /// the predicted steps (the harmonic oscillator's frequency error of
    /// each method for the tolerance spread over `ρT` radians) times the
    /// cost of a step, timed here on a few steps, make it cheaper:
    /// `Some((Galerkin s, reason))`, otherwise `None`. Nothing is timed where
    /// even the largest predicted saving cannot pay for a Galerkin step (at
    /// least [`galerkin_min_cost`] steps of Kahan–Li 8, in proportion to the
    /// stages of another composition).
    fn weigh_galerkin(&self, c: Candidate, rho: f64, span: f64) -> Option<(Candidate, String)> {
        let rho_span = (rho * span).max(1.0);
        let eps = choice::frequency_error(self.tolerance.rtol, rho_span);
        let constant = if c.order == 6 { choice::YOSHIDA6_CONSTANT } else { choice::KAHAN_LI8_CONSTANT };
        let composition = choice::predicted_steps(constant, c.order, COMPOSITION_RHO_H, eps, rho_span);
        let galerkin = |s: u32| {
            let rule = Rule::galerkin_gauss(s);
            choice::predicted_steps(rule.constant, rule.order, choice::GALERKIN_RHO_H, eps, rho_span)
        };
        let degrees = [4u32, 6, 8];
        let fewest = degrees.iter().map(|&s| galerkin(s) * choice::galerkin_step_cost(s)).fold(f64::INFINITY, f64::min);
        let per_kahan_li8 = choice::composition_stages(c.order) / choice::composition_stages(8);
        if composition * per_kahan_li8 < galerkin_min_cost(N) * fewest {
            return None;
        }
        let c_composition = self.seconds_per_step(c, rho_span / composition / rho, f64::INFINITY)?;
        // Galerkin s = 4 stops timing as soon as it cannot win.
        let budget = c_composition * composition / fewest;
        let c_galerkin = self.seconds_per_step(
            Candidate { family: Family::Galerkin, order: 8 },
            rho_span / galerkin(4) / rho,
            budget,
        )?;
        let (s, cost) = degrees
            .iter()
            .map(|&s| (s, galerkin(s) * choice::galerkin_step_cost(s) * c_galerkin))
            .min_by(|a, b| a.1.total_cmp(&b.1))?;
        let against = composition * c_composition;
        (cost < against).then(|| {
            (
                Candidate { family: Family::Galerkin, order: 2 * s },
                format!(
                    "separable with a constant mass matrix and no forces, but Galerkin s = {s} is predicted \
                     {:.0} steps, {:.2} ms, against {:.0} steps, {:.2} ms of {} for rtol = {:e}",
                    galerkin(s),
                    cost * 1e3,
                    composition,
                    against * 1e3,
                    c.name(),
                    self.tolerance.rtol
                ),
            )
        })
    }

    /// Seconds per step of `c` at step `h` from the start, the least of
    /// [`TIMED_ROUNDS`] rounds of [`TIMED_STEPS`] steps; `None` when a step
    /// fails or a round after the first exceeds `budget` per step.
    fn seconds_per_step(&self, c: Candidate, h: f64, budget: f64) -> Option<f64> {
        struct Time(f64);
        impl<const N: usize> Visit<N> for Time {
            type Out = Option<f64>;
            fn visit<I: Stepping<N> + Clone>(self, mut it: I) -> Self::Out {
                let mut best = f64::INFINITY;
                for round in 0..TIMED_ROUNDS {
                    let clock = Clock::start();
                    for k in 1..=TIMED_STEPS {
                        it.step().ok()?;
                        // The first round's steps from the start (no
                        // predictor history yet, cold caches) cost more than
                        // the run's: only a later round is held to the budget.
                        if round > 0 && clock.seconds() > self.0 * k as f64 {
                            return None;
                        }
                    }
                    best = best.min(clock.seconds() / TIMED_STEPS as f64);
                }
                Some(best)
            }
        }
        if !(h.is_finite() && h > 0.0) {
            return None;
        }
        dispatch(c, self, h, Time(budget)).ok().flatten()
    }

    /// A first step from the linearisation at the start: the fastest mode's
    /// phase error over the span about the tolerance.
    fn initial_step(&self, c: Candidate, rho: Option<f64>, span: f64) -> f64 {
        let Some(rho) = rho else { return span / 64.0 };
        let rule = Rule::galerkin_gauss((c.order / 2).max(1));
        let periods = (rho * span).max(1.0);
        let h = rule.omega_h((SAFETY * self.tolerance.rtol / periods).max(1e-300)).min(0.5) / rho;
        // Every family starts coarser than the harmonic oscillator's phase
        // error asks (an upper bound: on the report's problems the
        // calibrated steps are 1.5 to 6 times coarser): a coarse round costs
        // a fraction of one at the final step, and the step it leads to is
        // accepted down to a quarter of it (see `ACCEPT`); an estimate from a
        // step still short of the asymptotic range errs on the safe side.
        match c.family {
            // Compositions spend `m` sub-steps per step of order `p`.
            Family::Composition => h * 16.0,
            // The time transformation as coarse as its pilot resolves: a
            // round of fewer than `TT_PILOT_STEPS` coarse steps runs again
            // with the `σ` for about that many (on Kepler `e = 0.9` at
            // `rtol = 1.8e-4` the pilot at 16 times the step measured an
            // error that asked for 3.4 times its `σ`).
            Family::TimeTransformed => h * 64.0,
            // Galerkin four times coarser, at most at `ρh = GALERKIN_RHO_H`,
            // beyond which Newton needs more iterations (the sensor at
            // `rtol = 1e-3`: the pilot at the phase error's step measured an
            // error that asked for 2.3 times it).
            Family::Galerkin => (4.0 * h).min(choice::GALERKIN_RHO_H / rho).max(h),
        }
    }

    /// The steps of the final run at `step` (for the time transformation,
    /// estimated as if `σ` were a time step at the start's density).
    fn final_steps(&self, c: Candidate, step: f64, span: f64, _rho: Option<f64>) -> f64 {
        match c.family {
            Family::TimeTransformed => match self.tt_density() {
                Some(g) => (span / (step * g)).max(1.0),
                None => 1.0,
            },
            _ => (span / step).ceil().max(1.0),
        }
    }

    fn tt_density(&self) -> Option<f64> {
        *self.density.get_or_init(|| {
            ExplicitTimeTransformed::new(self.system.clone(), TimeFunction::Logarithmic, 1.0)
                .start(self.t0, self.q0, self.v0)
                .ok()
                .map(|it| it.density())
                .filter(|g| g.is_finite() && *g > 0.0)
        })
    }

    /// Yoshida 6 in place of Kahan–Li 8 where the survey ran Kahan–Li 8 at
    /// its step cap `h_cap` (`survey`: the step and the run) and Yoshida 6
    /// at the same step meets the target: no Richardson pair of either
    /// order, only one run of Yoshida 6 over the pilot, compared node by
    /// node with the survey's. Its difference is Yoshida 6's error: on the
    /// harmonic oscillator Kahan–Li 8's frequency error is
    /// `C₈/C₆ (ωh)² ≤ 1/350` of Yoshida 6's at every `ωh ≤ 1.5`, so on
    /// every mode of the linearisation the companion's error is negligible.
    /// Held to the same cap, Yoshida 6 spends 7 stages where Kahan–Li 8
    /// spends 15 (the FPU-β chain at `rtol = 1e-3`, whose fastest modes are
    /// barely excited, has accuracy to spare at the cap). `None` where it
    /// does not apply or misses the target: Kahan–Li 8 is then piloted as
    /// usual, the survey's run its first coarse run.
    #[allow(clippy::too_many_arguments)]
    fn lower_order_beside(
        &self,
        candidate: Candidate,
        survey: &(f64, Probe<N>),
        span: f64,
        checkpoints: &[f64; CHECKPOINTS],
        settle: f64,
        h_cap: f64,
        cost: &mut Cost,
    ) -> Option<(Candidate, Piloted, String)> {
        let (h, ref kahan_li8) = *survey;
        let at_cap = h >= 0.99 * h_cap && h <= h_cap;
        let kl8 = Candidate { family: Family::Composition, order: 8 };
        if candidate != kl8 || self.fixed != Fixed::default() || self.step.is_some() || !at_cap {
            return None;
        }
        let lower = Candidate { family: Family::Composition, order: 6 };
        // The survey's checkpoints, on its nodes.
        let times = self.pilot_times(h, checkpoints);
        let run = run_probe(lower, self, h, &times, true, 0, None, None, false).ok()?;
        cost.steps += run.steps;
        let tp = *times.last()?;
        let scale = run.scale.max(kahan_li8.scale).max(f64::MIN_POSITIVE);
        let rich = Richardson::companion(&run, kahan_li8, &times, self.t0, settle);
        let roundoff = pilot::roundoff(scale, (span / h).ceil(), rich.growth, span);
        let at_end = rich.at(self.t0, tp, self.t0 + span).max(roundoff);
        let target = SAFETY * self.tolerance.bound(scale);
        if !matches!(rich.growth, Growth::Power(_)) || at_end > target {
            return None;
        }
        let why = format!(
            "held to ρh ≤ {COMPOSITION_RHO_H} by its cap, where {} at the same step is within the tolerance \
             (its difference from Kahan–Li 8, extrapolated: {at_end:.1e} of {target:.1e})",
            lower.name()
        );
        Some((lower, ((h, at_end), rich, scale), why))
    }

    /// A composition held to its step cap `h_cap` with accuracy to spare
    /// (`piloted`) wastes its order: the next lower composition at the same
    /// cap costs fewer stages per step (Yoshida 6 7 against Kahan–Li 8's
    /// 15). It is piloted where the harmonic oscillator's frequency errors,
    /// `C₆ (ρh)⁶` against `C₈ (ρh)⁸` at the cap, predict that it meets the
    /// target there too, and taken if it costs fewer stages over the span:
    /// the lower candidate, its pilot and the reason.
    #[allow(clippy::too_many_arguments)]
    fn lower_order_at_cap(
        &self,
        candidate: Candidate,
        piloted: &Piloted,
        rho: Option<f64>,
        span: f64,
        checkpoints: &[f64; CHECKPOINTS],
        settle: f64,
        h_cap: f64,
        cost: &mut Cost,
    ) -> Option<(Candidate, Piloted, String)> {
        let ((step, error), _, scale) = *piloted;
        let ratio = choice::YOSHIDA6_CONSTANT / choice::KAHAN_LI8_CONSTANT / COMPOSITION_RHO_H.powi(2);
        let meets = error * ratio <= SAFETY * self.tolerance.bound(scale);
        if self.fixed.order.is_some() || self.step.is_some() || !meets {
            return None;
        }
        let lower = Candidate { family: Family::Composition, order: 6 };
        let stages = |c: Candidate| choice::composition_stages(c.order);
        let q = self.pilot(lower, rho, span, checkpoints, settle, h_cap, None, cost).ok()?;
        let relative = (stages(lower) / q.0.0) / (stages(candidate) / step);
        (stages(lower) / q.0.0 < stages(candidate) / step).then(|| {
            let why = format!(
                "held to ρh ≤ {COMPOSITION_RHO_H} with accuracy to spare, where {} at step {:.3e} costs {:.2} of its stages",
                lower.name(),
                q.0.0,
                relative
            );
            (lower, q, why)
        })
    }

    /// The pilot of one candidate, its steps at most `h_cap`:
    /// `Ok((step, estimate at that step, scale))`.
    #[allow(clippy::too_many_arguments)]
    fn pilot(
        &self,
        c: Candidate,
        rho: Option<f64>,
        span: f64,
        checkpoints: &[f64; CHECKPOINTS],
        settle: f64,
        h_cap: f64,
        mut reuse: Option<(f64, Probe<N>)>,
        cost: &mut Cost,
    ) -> Result<Piloted, Error> {
        let mut h = match (self.step, c.family) {
            (Some(h), _) => h,
            (None, Family::TimeTransformed) => {
                let g = self.tt_density().ok_or(Error::InvalidSetting { reason: "no step density at the start" })?;
                self.initial_step(c, rho, span) / g
            }
            (None, _) => self.initial_step(c, rho, span),
        };
        let p = c.order as i32;
        let mut failures = 0;
        let mut last: Option<Piloted> = None;
        // The finest step piloted whose estimate missed the target: a
        // round-off-limited finer round does not climb back to it.
        let mut too_coarse = f64::INFINITY;
        // The coarsest step piloted whose estimate met the target: a round
        // that would pilot about it or finer takes it instead.
        let mut met: Option<Piloted> = None;
        // The checkpoints of a round whose fine run is the next round's
        // coarse run (see `HALVE_FROM`): on the nodes of both.
        let mut halved: Option<Vec<f64>> = None;
        // A Galerkin cap (`s ≥ 6` without a survey, `ρh ≤ HIGH_DEGREE_RHO_H`)
        // bounds the first round and the step taken, not the rounds that
        // measure: a round whose runs agree to round-off at it measures
        // again at coarser steps, as every Galerkin pilot does (the charged
        // particle in a magnetic field at `rtol = 1e-12` and Kepler in polar
        // coordinates over 1 000 orbits at `1.8e-12` differ by round-off
        // alone at `ρh = 0.7` and at `ρh = 1`, and that difference,
        // extrapolated over the span, is above the request), and a measured
        // error asks for the capped step with its estimate scaled to it.
        let measure_cap = match c.family {
            Family::Galerkin => f64::INFINITY,
            _ => h_cap,
        };
        // A few coarse steps over the pilot at least.
        let h_max = ((checkpoints[CHECKPOINTS - 1] - self.t0) / 4.0).min(measure_cap);
        let fixed_step = c.family != Family::TimeTransformed;
        if fixed_step && self.step.is_none() {
            h = h.min(h_cap);
        }
        // The energy guard of the coarse runs (see `pilot::probe`): Galerkin
        // on a conservative autonomous system, whose pilot starts at up to
        // `ρh = 1` with `ρ` from the start alone (the compositions' steps
        // are capped by the rates the survey met along the orbit).
        let guard = c.family == Family::Galerkin
            && S::AUTONOMOUS
            && !S::HAS_FORCE
            && !S::HAS_DISSIPATION
            && self.step.is_none();
        for _ in 0..ROUNDS {
            if fixed_step && self.step.is_none() {
                h = h.min(h_max);
                // The survey's step, when near: its run is this round's coarse run.
                if let Some(r) = reuse.as_ref().filter(|r| r.0 <= 1.25 * h) {
                    h = r.0;
                }
            }
            if let Some(m) = met.as_ref().filter(|m| h <= 1.25 * m.0.0) {
                return Ok(*m);
            }
            // Fixed steps: checkpoints on the coarse nodes (two steps from
            // the start at least), so that neither run takes a landing step.
            let times: Vec<f64> = match halved.take() {
                Some(times) => times,
                None if fixed_step => self.pilot_times(h, checkpoints),
                None => checkpoints.to_vec(),
            };
            let tp = *times.last().expect("at least one checkpoint");
            // A time transformation's nodes fall at different times in the
            // two runs: they are compared node by node at equal new time, and
            // land only at the pilot's end.
            let landings: Vec<f64> = if fixed_step { times.clone() } else { vec![tp] };
            // The survey's run at this step is this round's coarse run (its
            // steps are already counted).
            let (coarse, reused) = match reuse.take().filter(|r| r.0 == h && self.step.is_none()) {
                Some((_, p)) => (Ok(p), true),
                None => (run_probe(c, self, h, &landings, true, 0, None, None, guard), false),
            };
            let fine = match &coarse {
                // The coarse run left its orbit (its energy did): as a round
                // whose runs differ by a tenth of the positions (below), a
                // quarter of the step, without the fine run.
                Ok(p) if p.lost => {
                    cost.steps += p.steps;
                    too_coarse = too_coarse.min(h);
                    h /= 4.0;
                    continue;
                }
                Ok(p) if !fixed_step && p.steps < TT_PILOT_STEPS && self.step.is_none() => {
                    if !reused {
                        cost.steps += p.steps;
                    }
                    // A coarser σ than the pilot resolves, asked for by an
                    // estimate already measured: that extrapolation is taken
                    // (a finer round would measure the same ratio again).
                    if let Some(prev) = last {
                        return Ok(prev);
                    }
                    // Too few nodes to compare: a finer σ, for about a
                    // quarter more steps than the least.
                    h *= p.steps.max(1) as f64 / (1.25 * TT_PILOT_STEPS as f64);
                    continue;
                }
                Ok(_) => Some(run_probe(c, self, h / 2.0, &landings, true, 0, None, None, false)),
                Err(_) => None,
            };
            let (coarse, fine) = match (coarse, fine) {
                (Ok(a), Some(Ok(b))) => (a, b),
                (Err(e), _) | (_, Some(Err(e))) => {
                    failures += 1;
                    if failures > 2 || self.step.is_some() {
                        return Err(e);
                    }
                    h /= 4.0;
                    continue;
                }
                (Ok(_), None) => unreachable!("the fine run follows a successful coarse one"),
            };
            cost.steps += if reused { fine.steps } else { coarse.steps + fine.steps };
            let scale = coarse.scale.max(fine.scale).max(f64::MIN_POSITIVE);
            let rich =
                Richardson::new(&coarse, &fine, c.order, &times, self.t0, settle, !fixed_step, S::HAS_DISSIPATION);
            let target = SAFETY * self.tolerance.bound(scale);
            let at_end = rich.at(self.t0, tp, self.t0 + span);
            if self.step.is_some() {
                return Ok(((h, at_end), rich, scale));
            }
            // The round-off of a final run at this step (as many steps over
            // the span as the coarse run takes over the pilot).
            let roundoff = pilot::roundoff(scale, coarse.steps as f64 * span / (tp - self.t0), rich.growth, span);
            if let Growth::Exponential(_) = rich.growth {
                // Round-off amplified over the span already above the
                // tolerance: no step helps (the caller refuses).
                if roundoff > target {
                    return Ok(((h, at_end), rich, scale));
                }
            }
            if rich.is_roundoff() {
                // The difference is round-off: the method is more accurate
                // than it can show at this step. A coarser step shows it,
                // unless round-off alone is already the tolerance.
                if let Some(prev) = last.filter(|_| roundoff > target) {
                    return Ok(prev);
                }
                if (fixed_step && h >= h_max) || 4.0 * h >= too_coarse {
                    // As coarse as the pilot resolves (or a coarser step
                    // already missed) and still exact to round-off.
                    return Ok(((h.min(h_cap), at_end.max(roundoff)), rich, scale));
                }
                last = Some(((h.min(h_cap), at_end.max(roundoff)), rich, scale));
                if at_end.max(roundoff) <= target {
                    met = last;
                }
                h *= 4.0;
                continue;
            }
            if at_end > target {
                too_coarse = too_coarse.min(h);
            }
            let ratio = (target / at_end).powf(1.0 / p as f64);
            let ratio = ratio.min(h_cap / h);
            // A difference of the size of the positions is no error estimate
            // (the coarse run left the orbit: the double pendulum at ρh ≈ 1
            // from its start at rest), whatever step it asks for: at
            // `rtol ≥ 3e-4` the double pendulum's asks for about a quarter
            // of it, where the final run's Newton fails half-way. A quarter
            // of the step, not the sixteenth the model asks for at tighter
            // tolerances.
            if rich.error > 0.1 * scale {
                h /= 4.0;
                continue;
            }
            // Within `ACCEPT`, a composition's step no coarser than the
            // measured one (see `ACCEPT`). Galerkin and the time
            // transformation, which have no such cap, take the coarser step
            // their estimate asks for: on the Kepler orbits at
            // `rtol = 1.8e-4` the estimate at the pilot's `σ` is within 10% of
            // the error of the whole run at that `σ`.
            let capped_family = c.family == Family::Composition;
            let kept = if ACCEPT.contains(&ratio) && capped_family { ratio.min(1.0) } else { ratio };
            let h_new = h * kept;
            // The estimate at the step taken: error ∝ h^p.
            let estimate = at_end * kept.powi(p);
            last = Some(((h_new, estimate), rich, scale));
            // A composition piloted at its largest step may be short of the
            // asymptotic range, where the error falls faster than `h^p`: a
            // step below half of it is piloted again rather than
            // extrapolated that far.
            let at_cap = capped_family && fixed_step && h >= 0.99 * h_cap && ratio < CAPPED_ACCEPT;
            if ACCEPT.contains(&ratio) && !at_cap {
                break;
            }
            // Far from the pilot's step the asymptotic model is not trusted:
            // pilot again nearer. The time transformation, asked for a finer
            // `σ` from `HALVE_FROM` up, halves it, the fine run the next
            // round's coarse run.
            if c.family == Family::TimeTransformed && (HALVE_FROM..1.0).contains(&ratio) {
                h /= 2.0;
                reuse = Some((h, fine));
                halved = Some(times);
                continue;
            }
            let next = h * ratio.clamp(1.0 / 16.0, 4.0);
            // A fixed step at the pilot's largest (a few coarse steps over the
            // pilot) asked for a coarser one: the next round would run the
            // same pair again, and the extrapolation just measured is taken.
            if fixed_step
                && h >= h_max
                && next > h
                && let Some(prev) = last
            {
                return Ok(prev);
            }
            // A coarser σ whose run would take fewer steps than the pilot
            // resolves (`TT_PILOT_STEPS`): the extrapolation just measured
            // is taken, as that round would take it, without running it.
            if c.family == Family::TimeTransformed
                && 4.0 * coarse.steps as f64 * h / next < 3.0 * TT_PILOT_STEPS as f64
                && let Some(prev) = last
            {
                return Ok(prev);
            }
            h = next;
        }
        last.ok_or(Error::InvalidSetting { reason: "no pilot round completed" })
    }

    /// The checkpoints of a fixed-step pilot at step `h`: on its coarse
    /// nodes (two steps from the start at least), so that neither run takes
    /// a landing step.
    fn pilot_times(&self, h: f64, checkpoints: &[f64; CHECKPOINTS]) -> Vec<f64> {
        let mut t: Vec<f64> = checkpoints
            .iter()
            .map(|&c| ((c - self.t0) / h).round())
            .filter(|&m| m >= 2.0)
            .map(|m| self.t0 + m * h)
            .collect();
        t.dedup();
        if t.is_empty() {
            t.push(self.t0 + 2.0 * h);
        }
        t
    }

    /// The composition of `order` at step `h` from the start: a copy of the
    /// composition started first (kept in `started`), its weights those
    /// of `order` (the start does not depend on them).
    fn composition_at(&self, order: u32, h: f64) -> Result<Integrator<S, Composition, N>, Error> {
        let mut started = self.started.borrow_mut();
        let it = match started.as_ref() {
            Some(it) => it,
            None => started
                .insert(Integrator::new(self.system.clone(), composition(order), h).start(self.t0, self.q0, self.v0)?),
        };
        let mut it = it
            .recomposed(composition(order))
            .ok_or(Error::InvalidSetting { reason: "the started composition has stepped" })?;
        it.set_step_size(h)?;
        Ok(it)
    }

    /// The final run at `step` (for fixed steps, one that divides the span)
    /// to the end of `plan`.
    fn run(&self, c: Candidate, step: f64, plan: Plan<'_>) -> Result<Solution, SolveError> {
        struct Run<'p, const N: usize>(Plan<'p>);
        impl<'p, const N: usize> Visit<N> for Run<'p, N> {
            type Out = Result<Solution, SolveError>;
            fn visit<I: Stepping<N> + Clone>(self, mut it: I) -> Self::Out {
                it.solve(self.0)
            }
        }
        dispatch(c, self, step, Run(plan))?
    }
}

/// Something done with a stepper of any type.
trait Visit<const N: usize> {
    type Out;
    fn visit<I: Stepping<N> + Clone>(self, it: I) -> Self::Out;
}

#[allow(clippy::too_many_arguments)]
fn run_probe<S: Lagrangian<N> + Clone, const N: usize>(
    c: Candidate,
    auto: &Auto<S, N>,
    step: f64,
    checkpoints: &[f64],
    every_node: bool,
    stride: usize,
    rates: Option<&mut Rates<N>>,
    stop_above: Option<f64>,
    energy_guard: bool,
) -> Result<Probe<N>, Error> {
    struct P<'a, const N: usize>(&'a [f64], bool, usize, Option<&'a mut Rates<N>>, Option<f64>, bool);
    impl<const N: usize> Visit<N> for P<'_, N> {
        type Out = Result<Probe<N>, Error>;
        fn visit<I: Stepping<N> + Clone>(self, it: I) -> Self::Out {
            pilot::probe(it, self.0, self.1, self.2, self.3, self.4, self.5)
        }
    }
    dispatch(c, auto, step, P(checkpoints, every_node, stride, rates, stop_above, energy_guard))?
}

fn composition(order: u32) -> Composition {
    match order {
        4 => Composition::YOSHIDA4,
        6 => Composition::YOSHIDA6,
        _ => Composition::KAHAN_LI8,
    }
}

/// Builds the stepper of `c` with step `step` at the start and hands it to `v`.
fn dispatch<S: Lagrangian<N> + Clone, V: Visit<N>, const N: usize>(
    c: Candidate,
    auto: &Auto<S, N>,
    step: f64,
    v: V,
) -> Result<V::Out, Error> {
    let (sys, t0, q0, v0) = (auto.system.clone(), auto.t0, auto.q0, auto.v0);
    macro_rules! galerkin {
        ($($s:literal)*) => {
            match c.order / 2 {
                $($s => Ok(v.visit(Integrator::new(sys, Galerkin::<$s, $s>::gauss(), step).start(t0, q0, v0)?)),)*
                _ => Err(Error::InvalidMethod { reason: "no such Galerkin degree in a tolerance-driven solve" }),
            }
        };
    }
    match c.family {
        Family::Composition => Ok(v.visit(auto.composition_at(c.order, step)?)),
        Family::Galerkin => galerkin!(2 3 4 6 8),
        Family::TimeTransformed => Ok(v.visit(
            ExplicitTimeTransformed::new(sys, TimeFunction::Logarithmic, step)
                .composition(composition(c.order))
                .start(t0, q0, v0)?,
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Scalar, Separability, Trapezoid};

    /// Two masses on springs, coupled: `M = [[2, 1], [1, 1]]` (or the
    /// singular `[[1, 1], [1, 1]]`), `V = ½ q₀² + ½ q₁² + ¼ q₀⁴`.
    #[derive(Clone, Debug)]
    struct Coupled {
        m00: f64,
    }

    impl Lagrangian<2> for Coupled {
        const AUTONOMOUS: bool = true;
        const CYCLIC: [bool; 2] = [false, false];
        const SEPARABILITY: Separability = Separability::ConstantMass;
        fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 2], v: [D; 2]) -> D {
            let kinetic = (v[0] * v[0] * self.m00 + v[0] * v[1] * 2.0 + v[1] * v[1]) * 0.5;
            let potential = (q[0] * q[0] + q[1] * q[1]) * 0.5 + q[0] * q[0] * q[0] * q[0] * 0.25;
            kinetic - potential
        }
    }

    fn probe_of<I: Stepping<2> + Clone>(it: I, times: &[f64]) -> Probe<2> {
        pilot::probe(it, times, true, 0, None, None, false).unwrap()
    }

    #[test]
    fn a_copy_of_the_started_composition_steps_as_a_fresh_start() {
        let auto = Auto::new(Coupled { m00: 2.0 }, 0.0, [0.7, -0.2], [0.1, 0.3]);
        let times = [0.8, 1.6, 3.2];
        for order in [8, 6, 8] {
            let c = Candidate { family: Family::Composition, order };
            for h in [0.2, 0.1, 0.05] {
                // Through the solve's dispatch: the first call starts, the
                // following ones copy the started integrator.
                let copied = run_probe(c, &auto, h, &times, true, 0, None, None, false).unwrap();
                let fresh = Integrator::new(auto.system.clone(), composition(order), h).start(0.0, auto.q0, auto.v0);
                let fresh = probe_of(fresh.unwrap(), &times);
                assert_eq!(copied.samples.len(), fresh.samples.len());
                for (a, b) in copied.samples.iter().zip(&fresh.samples) {
                    assert_eq!(
                        (a.t.to_bits(), a.q.map(f64::to_bits), a.p.map(f64::to_bits)),
                        (b.t.to_bits(), b.q.map(f64::to_bits), b.p.map(f64::to_bits))
                    );
                }
                assert_eq!(copied.steps, fresh.steps);
            }
            // Started once, by the first order; the others are copies of it.
            assert_eq!(auto.started.borrow().as_ref().map(|it| it.method().order()), Some(8));
        }
    }

    /// Two uncoupled oscillators, `ω = 1` and `ω = 10`, the fast one at rest.
    #[derive(Clone, Debug)]
    struct SlowAndFast;

    impl Lagrangian<2> for SlowAndFast {
        const AUTONOMOUS: bool = true;
        const CYCLIC: [bool; 2] = [false, false];
        const SEPARABILITY: Separability = Separability::ConstantMass;
        fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 2], v: [D; 2]) -> D {
            (v[0] * v[0] + v[1] * v[1] - q[0] * q[0] - q[1] * q[1] * 100.0) * 0.5
        }
    }

    #[test]
    fn yoshida6_runs_beside_kahan_li8_at_its_cap_when_the_fast_mode_is_at_rest() {
        // The fast mode holds Kahan–Li 8 to `ρh ≤ 1.5` (`h = 0.15`), where
        // the slow mode's error of Yoshida 6 is far below `rtol = 1e-3`.
        let (span, rtol) = (50.0, 1e-3);
        let solved = Auto::new(SlowAndFast, 0.0, [1.0, 0.0], [0.0, 0.0])
            .tolerance(Tolerance::relative(rtol))
            .solve(Plan::until(span));
        let solved = solved.unwrap();
        let e = &solved.estimate;
        assert_eq!(e.method, Candidate { family: Family::Composition, order: 6 }, "{}", e.reason);
        assert!(e.reason.contains("its difference from Kahan–Li 8"), "{}", e.reason);
        assert!((e.step - span / (span / (COMPOSITION_RHO_H / 10.0)).ceil()).abs() < 1e-12, "step {}", e.step);
        // No Richardson pair: the survey's run and one of Yoshida 6, as many steps.
        assert_eq!(e.pilot.steps % 2, 0);
        let survey = e.pilot.steps / 2;
        assert!(survey as f64 <= (e.measured_until / e.step).ceil() + 1.0, "pilot {} steps", e.pilot.steps);
        // The largest error along the run, against `cos t`.
        let error = solved
            .solution
            .t
            .iter()
            .zip(&solved.solution.q)
            .map(|(t, q)| (q[0] - t.cos()).abs().max(q[1].abs()))
            .fold(0.0f64, f64::max);
        assert!(error <= e.requested, "error {error:e} against {:e} asked", e.requested);
        assert!((0.1..=10.0).contains(&(e.error / error)), "estimate {:e} against the error {error:e}", e.error);
    }

    #[test]
    fn a_singular_constant_mass_matrix_is_refused_at_the_start() {
        let singular = Coupled { m00: 1.0 };
        let trapezoid = Integrator::new(singular.clone(), Trapezoid, 0.1).start(0.0, [0.7, -0.2], [0.1, 0.3]);
        assert!(matches!(trapezoid, Err(Error::InvalidInitialData { .. })), "{trapezoid:?}");
        let kahan_li8 =
            Integrator::new(singular.clone(), Composition::KAHAN_LI8, 0.1).start(0.0, [0.7, -0.2], [0.1, 0.3]);
        assert!(matches!(kahan_li8, Err(Error::InvalidInitialData { .. })), "{kahan_li8:?}");
        // The solve reports the failed start of every candidate, typed.
        let solved = Auto::new(singular, 0.0, [0.7, -0.2], [0.1, 0.3]).solve(Plan::until(5.0));
        assert!(solved.is_err());
    }
}
