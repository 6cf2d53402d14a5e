//! Energy-preserving variable steps (docs/theory.md §3, §9; Chen, Guo & Wu (total variation) §3, 003 §3.2).
//!
//! ```text
//! given (t_k, q_k, p_k, E_k):   solve  R_q = p_k  + ∂A/∂q_k (x_k, x_{k+1}) = 0
//!                                      R_t = −E_k + ∂A/∂t_k (x_k, x_{k+1}) = 0   for (q_{k+1}, t_{k+1})
//!                               then   p_{k+1} = ∂A/∂q_{k+1},   E_{k+1} = −∂A/∂t_{k+1}
//! ```
//!
//! For an autonomous `L` the second equation says `E_{k+1} = E_k`; for a
//! time-dependent one it is the discrete energy balance
//! `E_{k+1} − E_k = −(∂A/∂t_k + ∂A/∂t_{k+1})` (de León & Martín de Diego).
//! For a system with forces the DEL carries `F_k^−` and the energy equation
//! the work of the forces on the time variations,
//! `R_t = −(E_k + F_{k−1}^+·v̂_{k−1}) + ∂A/∂t_k − F_k^−·v̂_k`, so that
//! `E_{k+1} − E_k = W_k` (energy-balance steps, docs/theory.md §6).
//!
//! The step size enters the energy equation only through the `O(h²)` energy
//! error of the discrete Lagrangian, so the equation can lose its root: in
//! the continuous limit the step density obeys `ρ ∝ (V''p² + V'²)^{1/3}`
//! for `½p² + V(q)` (Luo, Guo, Li & Wu (4.8)), and where that factor changes sign no
//! positive step conserves the energy. Each step is therefore solved in two
//! stages:
//!
//! 1. Newton on `(q_{k+1}, t_{k+1})` together (bordered `(N+1)×(N+1)`
//!    Jacobian), started from the DEL solution at the guessed step. This is
//!    the fast path and succeeds almost always.
//! 2. If it fails or leaves the admissible bracket
//!    `[max(h_min, h_{k−1}/r), min(h_max, r·h_{k−1})]`, a safeguarded 1-D solve
//!    of `g(h) = ∂A/∂t_k(q_{k+1}(h), h) − E_k` on that bracket, where
//!    `q_{k+1}(h)` solves the DEL at step `h` and `g'(h)` is the Schur
//!    complement of the bordered Jacobian. It samples the bracket for a sign
//!    change, then runs Newton safeguarded by bisection. Without a sign change
//!    it minimises `|g|` by golden section: the integrator then either reports
//!    [`Error::NoEnergyStep`] (the default) or, with
//!    [`EnergyFallback::LeastSquares`], takes the step of least energy error
//!    (Kane, Marsden & Ortiz's least-squares choice).
//!
//! A step never goes backwards in time and never leaves the bracket.
//!
//! The second stage is written once, as [`EnergySearch`]: the constrained
//! one-point rules (`constrained/energy.rs`) and Galerkin rules
//! (`constrained/galerkin_energy.rs`) run it alone, with trial steps that
//! solve the constrained step.

use nalgebra::SVector;

use super::{Integrator, StepPolicy, non_finite};
use crate::derivatives::{self, Segment};
use crate::discrete::DiscreteLagrangian;
use crate::error::{Error, Unplaced};
use crate::forcing;
use crate::mechanics::DiscreteMechanics;
use crate::newton::{self, Breakdown, Extended, NewtonReport};
use crate::real::max_abs;
use crate::state::{PhasePoint, State};
use crate::system::Lagrangian;

/// Limits on the step sizes of
/// [`StepPolicy::EnergyPreserving`](super::StepPolicy::EnergyPreserving) (docs/theory.md §9).
///
/// Every step lies in `[max(h_min, h_{k−1}/max_ratio), min(h_max, max_ratio·h_{k−1})]`;
/// when no step there satisfies the energy equation the integrator applies its
/// [`EnergyFallback`].
///
/// The energy equation fixes the step, not an error estimate: as a damped
/// motion comes to rest its energy error vanishes and the root moves to
/// ever larger steps, past `ωh ≈ 1`, where the motion is no longer resolved
/// and the root finally disappears. With an [`accuracy`](Self::accuracy)
/// the one-point rules also keep `ρh` below the bound at which the fastest
/// mode `ρ` of the linearisation at the node has relative frequency error
/// `accuracy` (the rule of [`guidance`](crate::guidance), order 2,
/// `C = 1/12`): `h ≤ √(12 · accuracy) / ρ`. Where every root of the energy
/// equation lies beyond that bound, the accuracy wins: the step of least
/// energy mismatch at or below the bound is taken (whatever the
/// [`EnergyFallback`]), the discrete energy takes the value it reaches, and
/// the step is counted in
/// [`Stats::accuracy_capped_steps`](super::Stats::accuracy_capped_steps).
/// A damped motion coming to rest ends in such steps: its energy error is
/// below any tolerance there, and its motion stays resolved.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepBounds {
    /// Smallest acceptable step.
    pub h_min: f64,
    /// Largest acceptable step.
    pub h_max: f64,
    /// Largest acceptable `h_k / h_{k−1}` (and `h_{k−1} / h_k`): finite and above 1.
    pub max_ratio: f64,
    /// A relative frequency error the steps must keep (see above); `None`:
    /// the energy equation alone sets the step. One-point rules only.
    pub accuracy: Option<f64>,
}

impl StepBounds {
    /// Bounds `[h0 / 1000, 1000 h0]` around a first guess, with ratio 2.
    pub fn around(h0: f64) -> Self {
        Self { h_min: 1e-3 * h0, h_max: 1e3 * h0, max_ratio: 2.0, accuracy: None }
    }

    /// The same bounds with an accuracy bound on every step: the relative
    /// frequency error `tol` of the fastest mode at the node (see
    /// [`StepBounds`]).
    pub fn with_accuracy(mut self, tol: f64) -> Self {
        self.accuracy = Some(tol);
        self
    }

    /// The largest step the accuracy bound allows at `(t, q, v)`; `None`
    /// without a bound, or where the linearisation has no time scale.
    pub(crate) fn accuracy_cap<S: Lagrangian<N> + ?Sized, const N: usize>(
        &self,
        system: &S,
        (t, q, v): (f64, [f64; N], [f64; N]),
    ) -> Option<f64> {
        let tol = self.accuracy?;
        let rho = crate::guidance::linearize(system, t, q, v).ok()?.fastest;
        (rho.is_finite() && rho > 0.0).then(|| crate::guidance::Rule::midpoint().omega_h(tol) / rho)
    }

    pub(crate) fn valid(&self) -> bool {
        self.h_min.is_finite()
            && self.h_max.is_finite()
            && self.h_min > 0.0
            && self.h_min <= self.h_max
            && self.max_ratio.is_finite()
            && self.max_ratio > 1.0
            && self.accuracy.is_none_or(|a| a > 0.0 && a < 1.0)
    }

    /// The admissible steps after a step of size `h_prev`.
    pub(crate) fn bracket(&self, h_prev: f64) -> (f64, f64) {
        let lo = self.h_min.max(h_prev / self.max_ratio);
        let hi = self.h_max.min(h_prev * self.max_ratio);
        (lo.min(hi), hi)
    }
}

/// What an energy-preserving integrator does when no admissible step size
/// satisfies the energy equation (docs/theory.md §9).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum EnergyFallback {
    /// Return [`Error::NoEnergyStep`] with the state unchanged (the default).
    #[default]
    Fail,
    /// Take the admissible step that minimises `|E_{k+1} − E_k|` (Kane,
    /// Marsden & Ortiz's least-squares step). The step still solves the DEL
    /// exactly, so it stays symplectic in `(q, p)`; the discrete energy
    /// changes by the reported mismatch, and the steps after it conserve
    /// the new value. Counted in [`Stats::energy_fallbacks`](super::Stats::energy_fallbacks).
    LeastSquares,
}

/// How an energy-preserving step was chosen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Taken {
    /// A root of the energy equation.
    Root,
    /// The least mismatch, by [`EnergyFallback::LeastSquares`].
    LeastSquares,
    /// The least mismatch below the accuracy bound, with its relative
    /// mismatch: the energy root lies beyond the bound.
    Capped(f64),
}

/// One evaluation of the energy equation along the solutions of the
/// step's position equations (the DEL, or its constrained form).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Probe<X> {
    /// The trial step, its position equations solved.
    pub(crate) trial: X,
    /// Its size.
    pub(crate) h: f64,
    /// `g(h) = ∂A/∂t_k − E_k`.
    pub(crate) g: f64,
    /// `g'(h)` along the solutions, the Schur complement of the bordered
    /// Jacobian (NaN where it cannot be formed).
    pub(crate) slope: f64,
    /// The size of the terms that cancel in `g`.
    pub(crate) scale: f64,
}

impl<X> Probe<X> {
    /// [`Error::NoEnergyStep`] from `state` for the bracket `[lo, hi]`, this
    /// probe the least mismatch in it, after `spent` iterations.
    pub(crate) fn no_energy_step(
        &self,
        state: impl Into<PhasePoint>,
        (lo, hi): (f64, f64),
        spent: usize,
        root_test: Option<(f64, f64, f64)>,
    ) -> Error {
        Error::NoEnergyStep {
            state: state.into(),
            h_lo: lo,
            h_hi: hi,
            h_best: self.h,
            mismatch: self.g.abs() / self.scale,
            iterations: spent,
            root_test,
        }
    }

    /// `g` is round-off of its own terms.
    pub(crate) fn solved(&self) -> bool {
        self.g.abs() <= 8.0 * f64::EPSILON * self.scale
    }

    /// The report of a step taken at this probe after `iterations` Newton
    /// iterations in all.
    pub(crate) fn report(&self, iterations: usize) -> NewtonReport {
        NewtonReport { iterations, residual_norm: self.g.abs(), correction_norm: 0.0 }
    }
}

/// The search over the step size `h` of an energy-preserving step: a
/// family of steps whose position equations can be solved at any trial `h`
/// ([`probe`](Self::probe)) gets the bracket search, the safeguarded Newton
/// iteration on `g(h)` and the least-mismatch fallback written once here,
/// whatever the size of the system (the error's state is a [`PhasePoint`]).
pub(crate) trait EnergySearch {
    /// A trial step with its position equations solved.
    type Trial: Copy;

    /// `g(h)` and `g'(h)` with the position equations solved at step `h`;
    /// the Newton iterations spent go to `spent`. Changes nothing the
    /// integrator publishes.
    fn probe(&mut self, h: f64, spent: &mut usize) -> Result<Probe<Self::Trial>, Unplaced>;

    /// The failure of a trial, as the error of the step: at the state the
    /// step started from (and the integrator still holds).
    fn place(&self, failure: Unplaced) -> Error;

    /// What to do where no admissible step solves the energy equation.
    fn fallback(&self) -> EnergyFallback;

    /// Whether the trial `p` solves the energy equation: `g` is round-off
    /// of its own terms ([`Probe::solved`] unless the family knows its
    /// round-off better).
    fn solved(&self, p: &Probe<Self::Trial>) -> bool {
        p.solved()
    }

    /// [`Error::NoEnergyStep`] for the bracket `[lo, hi]`, whose least
    /// mismatch is at `best`, after `spent` iterations.
    fn no_energy_step(&self, lo: f64, hi: f64, best: &Probe<Self::Trial>, spent: usize) -> Error;

    /// Stage 2: the safeguarded solve of `g(h) = 0` on `[lo, hi]`.
    ///
    /// A trial step size whose DEL cannot be solved (Newton fails, or `g` is
    /// not finite there) narrows the bracket to the side of the guess away
    /// from it, instead of ending the step: a large trial step is the usual
    /// failure, and the smaller ones may still hold a root or the least
    /// mismatch. Only when no trial in the bracket solves does the step fail,
    /// with the error of the last trial. `capped`: the accuracy bound, not
    /// the step ratio, sets `hi` (see [`least_squares`](Self::least_squares)).
    fn bracketed(
        &mut self,
        guess: f64,
        mut lo: f64,
        mut hi: f64,
        capped: bool,
        mut spent: usize,
    ) -> Result<(Self::Trial, NewtonReport, Taken), Error> {
        let spent = &mut spent;
        // The first probe that solves: the guess, or halfway down towards `lo`
        // while trials fail (each failure lowers `hi`).
        let mut h = guess;
        let at_guess = loop {
            match self.probe(h, spent) {
                Ok(p) => break p,
                Err(e) => {
                    hi = h;
                    let next = lo + 0.5 * (h - lo);
                    if h <= lo || h - lo <= 1e-9 * h || next >= h {
                        return Err(self.place(e));
                    }
                    h = if h - lo <= 1e-3 * h { lo } else { next };
                }
            }
        };
        if self.solved(&at_guess) {
            return Ok((at_guess.trial, at_guess.report(*spent), Taken::Root));
        }
        let guess = at_guess.h;
        // Sample the bracket, nearest points first, for a sign change.
        let mut left = at_guess;
        let mut right = at_guess;
        let mut bracket = None;
        for k in 1..=8 {
            let f = k as f64 / 8.0;
            for below in [true, false] {
                let h = if below { guess - f * (guess - lo) } else { guess + f * (hi - guess) };
                if h == guess || h == left.h || h == right.h || h < lo || h > hi {
                    continue;
                }
                let Ok(p) = self.probe(h, spent) else {
                    // Unreachable trial: the bracket ends short of it.
                    if below {
                        lo = h;
                    } else {
                        hi = h;
                    }
                    continue;
                };
                if self.solved(&p) {
                    return Ok((p.trial, p.report(*spent), Taken::Root));
                }
                let near = if below { &mut left } else { &mut right };
                if p.g.signum() != near.g.signum() {
                    bracket = Some(if below { (p, *near) } else { (*near, p) });
                    break;
                }
                *near = p;
            }
            if bracket.is_some() {
                break;
            }
        }
        match bracket {
            Some((a, b)) => self.root(a, b, spent).map(|p| (p.trial, p.report(*spent), Taken::Root)),
            None => self.least_squares(lo, hi, capped, at_guess, spent),
        }
    }

    /// Newton on `g`, safeguarded by bisection, inside a sign change
    /// `a.h < b.h` (the classic `rtsafe` scheme: bisect whenever Newton would
    /// leave the bracket or does not halve the previous correction); a
    /// probe without a slope (NaN) takes the secant through the bracket's
    /// ends instead. A trial
    /// whose DEL fails is replaced by the bisection point; a second failure
    /// in a row ends the search with that error.
    fn root(
        &mut self,
        mut a: Probe<Self::Trial>,
        mut b: Probe<Self::Trial>,
        spent: &mut usize,
    ) -> Result<Probe<Self::Trial>, Error> {
        let mut x = if a.g.abs() < b.g.abs() { a } else { b };
        let mut dx_old = b.h - a.h;
        let mut dx = dx_old;
        for _ in 0..200 {
            let (ha, hb) = (a.h, b.h);
            // Where the probe has no slope, the secant through the bracket's ends.
            let slope = if x.slope.is_nan() { (b.g - a.g) / (hb - ha) } else { x.slope };
            let newton = x.h - x.g / slope;
            let h = if newton > ha && newton < hb && (2.0 * x.g).abs() <= (dx_old * slope).abs() {
                dx_old = dx;
                dx = x.g / slope;
                newton
            } else {
                dx_old = dx;
                dx = 0.5 * (hb - ha);
                ha + dx
            };
            if dx.abs() <= 4.0 * f64::EPSILON * h || h <= ha || h >= hb {
                return Ok(x);
            }
            let p = match self.probe(h, spent) {
                Ok(p) => p,
                Err(e) => {
                    let mid = ha + 0.5 * (hb - ha);
                    if h == mid {
                        return Err(self.place(e));
                    }
                    dx = 0.5 * (hb - ha);
                    self.probe(mid, spent).map_err(|e| self.place(e))?
                }
            };
            if self.solved(&p) {
                return Ok(p);
            }
            if p.g.signum() == a.g.signum() {
                a = p;
            } else {
                b = p;
            }
            x = p;
        }
        Ok(x)
    }

    /// No sign change found: minimise `|g|` over `[lo, hi]` by golden section,
    /// then report it or take it, as the fallback says. Trial steps whose DEL
    /// fails count as infinitely bad.
    ///
    /// When the accuracy bound sets `hi` (`capped`), the step of least
    /// mismatch is taken whatever the fallback: every step that could solve
    /// the energy equation is longer than the accuracy asked for allows,
    /// and the accuracy is the stronger demand. The step still solves the
    /// DEL, the discrete energy takes its new value, and the step is counted
    /// in [`Stats::accuracy_capped_steps`](super::Stats::accuracy_capped_steps)
    /// with its relative mismatch in
    /// [`Stats::largest_capped_energy_defect`](super::Stats::largest_capped_energy_defect).
    fn least_squares(
        &mut self,
        lo: f64,
        hi: f64,
        capped: bool,
        start: Probe<Self::Trial>,
        spent: &mut usize,
    ) -> Result<(Self::Trial, NewtonReport, Taken), Error> {
        const INV_PHI: f64 = 0.618_033_988_749_894_8;
        let mismatch = |p: &Option<Probe<Self::Trial>>| p.map_or(f64::INFINITY, |p| p.g.abs());
        let (mut a, mut b) = (lo, hi);
        let mut c = b - INV_PHI * (b - a);
        let mut d = a + INV_PHI * (b - a);
        let mut pc = self.probe(c, spent).ok();
        let mut pd = self.probe(d, spent).ok();
        let mut best = start;
        for _ in 0..60 {
            for p in [pc, pd].into_iter().flatten() {
                if p.g.abs() < best.g.abs() {
                    best = p;
                }
                if p.g.signum() != start.g.signum() || self.solved(&p) {
                    // A root after all, between two roots the sampling stepped over.
                    let (l, r) = if p.h < start.h { (p, start) } else { (start, p) };
                    let root = if self.solved(&p) { p } else { self.root(l, r, spent)? };
                    return Ok((root.trial, root.report(*spent), Taken::Root));
                }
            }
            if b - a <= 1e-9 * b {
                break;
            }
            if mismatch(&pc) < mismatch(&pd) {
                (b, d, pd) = (d, c, pc);
                c = b - INV_PHI * (b - a);
                pc = self.probe(c, spent).ok();
            } else {
                (a, c, pc) = (c, d, pd);
                d = a + INV_PHI * (b - a);
                pd = self.probe(d, spent).ok();
            }
        }
        if capped {
            return Ok((best.trial, best.report(*spent), Taken::Capped(best.g.abs() / best.scale)));
        }
        match self.fallback() {
            EnergyFallback::LeastSquares => Ok((best.trial, best.report(*spent), Taken::LeastSquares)),
            EnergyFallback::Fail => Err(self.no_energy_step(lo, hi, &best, *spent)),
        }
    }
}

impl<S: Lagrangian<N>, M: DiscreteLagrangian, const N: usize> Integrator<S, M, N> {
    /// One energy-preserving step after the first.
    pub(super) fn energy_step(&mut self, bounds: StepBounds) -> Result<&State<N>, Error> {
        let h_prev = self.memory.previous.map_or(self.h, |last| last.h);
        let (mut lo, mut hi) = bounds.bracket(h_prev);
        let mut capped = false;
        if bounds.accuracy.is_some() {
            let State { t, q, p, .. } = self.state;
            // The last step's mean velocity starts the inverse Legendre transform.
            let guess = self.memory.previous.map_or([0.0; N], |last| last.dq.map(|d| d / last.h));
            if let Ok(v) = self.system.velocity(t, q, p, guess)
                && let Some(cap) = bounds.accuracy_cap(&self.system, (t, q, v))
            {
                let bound = cap.max(bounds.h_min);
                capped = bound < hi;
                hi = hi.min(bound);
                lo = lo.min(hi);
            }
        }
        let guess = self.h.clamp(lo, hi);
        // Trial solves below may fail; only the outcome of the whole step counts.
        let stats = self.stats;
        let outcome = self.coupled(guess, lo, hi).or_else(|spent| self.bracketed(guess, lo, hi, capped, spent));
        self.stats = stats;
        match outcome {
            Ok((seg, report, taken)) => self.accept(seg, report, taken),
            Err(e) => {
                self.stats.failed_steps += 1;
                Err(e)
            }
        }
    }

    /// Stage 1: Newton on `(dq, h)` from the DEL solution at `guess`. `Err`
    /// carries the iterations spent when it fails or lands outside `[lo, hi]`.
    fn coupled(&mut self, guess: f64, lo: f64, hi: f64) -> Result<(Segment<N>, NewtonReport, Taken), usize> {
        let State { t: t0, q: q0, p: p0, .. } = self.state;
        let e0 = self.energy_target();
        // With two steps of history, start from the extrapolated step and the
        // quadratic position predictor, both O(h³) accurate. Otherwise start
        // from the DEL solution at the guessed step: the energy equation fixes
        // h only through the O(h²) energy error of the method, so its Newton
        // correction is trustworthy only once R_q is already near zero.
        let (start, first) = match (self.memory.previous, self.memory.earlier) {
            (Some(last), Some((h_earlier, _))) => {
                let h = (2.0 * last.h - h_earlier).clamp(lo, hi);
                // One Newton correction of the DEL alone at that step first:
                // the energy equation fixes h only weakly (g' = O(h)), so a
                // coupled correction from the predictor turns its DEL residual
                // into a large, wrong change of h (measured: −8e-3 relative,
                // undone by the next iteration). From the corrected
                // positions the coupled iteration converges in two (double
                // pendulum from (0.5, 0.3), h = 0.01: 3.0 iterations per step
                // in all, against 4.0 without this correction and without the
                // round-off floors of `Extended`).
                let predicted = self.predict(h);
                match self.del_correction(h, predicted) {
                    Some(dq) => (
                        Extended { q: SVector::from(dq), t: h, t_floor: 0.0, q_floor: 0.0 },
                        NewtonReport { iterations: 1, ..Default::default() },
                    ),
                    None => (
                        Extended { q: SVector::from(predicted), t: h, t_floor: 0.0, q_floor: 0.0 },
                        NewtonReport::default(),
                    ),
                }
            }
            _ => {
                let (dq, first) = self.solve_del(guess).map_err(|_| 0usize)?;
                (Extended { q: SVector::from(dq), t: guess, t_floor: 0.0, q_floor: 0.0 }, first)
            }
        };
        let (system, method, min_rcond) = (&self.system, &self.method, self.newton.min_rcond);
        let pc = self.p_carry;
        let linearize = |x: &Extended<N>, _| {
            if x.t.is_nan() || x.t <= 0.0 {
                return Err(Breakdown::Rejected("the energy equation drove the step size to h ≤ 0"));
            }
            let seg = Segment { t0, h: x.t, q0, dq: x.q.into() };
            let d = forcing::extended_step_derivatives(system, method, &seg);
            let r = SVector::<f64, N>::from_fn(|i, _| (p0[i] + d.d_q0[i]) + pc[i]);
            let r_t = d.d_t0 - e0;
            let ratio_q = r.amax() / max_abs(&p0).max(max_abs(&d.d_q0));
            let t_scale = e0.abs().max(d.d_t0.abs());
            let ratio_t = r_t.abs() / t_scale;
            let mut lin = newton::bordered_correction(
                r,
                r_t,
                t_scale,
                max_abs(&q0),
                d.d2_q0_q1,
                d.d2_q0_t1,
                d.d2_t0_q1,
                d.d2_t0_t1,
                min_rcond,
            )?;
            (lin.cancelled, lin.scale) = (ratio_q.max(ratio_t), 1.0);
            Ok(lin)
        };
        match newton::solve(start, &self.newton, linearize) {
            Ok((x, mut report)) if x.t >= lo && x.t <= hi => {
                report.iterations += first.iterations;
                Ok((Segment { t0, h: x.t, q0, dq: x.q.into() }, report, Taken::Root))
            }
            Ok((_, report)) => Err(first.iterations + report.iterations),
            Err(failure) => Err(first.iterations + failure.iterations()),
        }
    }

    /// `dq` after one Newton correction of the DEL `p_k + ∂A/∂q_k = 0` at step
    /// `h` (forces included), or `None` where the correction cannot be made
    /// (a singular or non-finite Jacobian or residual).
    fn del_correction(&self, h: f64, dq: [f64; N]) -> Option<[f64; N]> {
        let step = self
            .del_linearization(h, dq, max_abs(&self.state.p), true, &mut None, &mut super::one_point::Impulse::new())
            .ok()?;
        let out: [f64; N] = core::array::from_fn(|i| dq[i] + step.correction[i]);
        out.iter().all(|x| x.is_finite()).then_some(out)
    }

    /// The local root test `(x, low, high)` of [`Error::NoEnergyStep`] at the
    /// current node, for discrete Lagrangians with a known energy-error
    /// constant `κ` ([`DiscreteLagrangian::energy_error_kappa`]).
    ///
    /// `Ê_z(h) − H(z) ≈ a₂ h² + a₃ h³` for a step of size `h` from node `z`,
    /// `a₂ = [(1 − 12κ) vᵀL_qq v − aᵀL_vv a]/8` with `a = L_vv⁻¹(L_q − L_vq v)`;
    /// `a₃ = (a₂(z_k) − a₂(z_{k−1}))/(3h')` from the node behind; with
    /// `x = a₂/(a₃ h')` and the step ratio bound `r`, the local model has an
    /// admissible root iff `x ≥ (r² − r + 1)/(r(r − 1))` or `x ≤ −3` (`r ≥ 2`;
    /// `−(r² − r + 1)/(r − 1)` below). A diagnostic, computed on the error path only.
    fn root_test(&self) -> Option<(f64, f64, f64)> {
        let kappa = self.method.energy_error_kappa()?;
        let StepPolicy::EnergyPreserving(bounds) = self.policy else { return None };
        let last = self.memory.previous?;
        let h = last.h;
        let guess = last.dq.map(|x| x / h);
        let State { t, q, p, .. } = self.state;
        let a2_here = self.energy_coefficient(kappa, t, q, p, guess)?;
        let p_behind = derivatives::step_derivatives(&self.system, &self.method, &last).d_q0.map(|x| -x);
        let a2_behind = self.energy_coefficient(kappa, last.t0, last.q0, p_behind, guess)?;
        let x = 3.0 * a2_here / (a2_here - a2_behind);
        let (low, high) = root_band(1, bounds.max_ratio);
        x.is_finite().then_some((x, low, high))
    }

    /// `a₂` at the node `(t, q, p)` (see [`root_test`](Self::root_test)).
    fn energy_coefficient(&self, kappa: f64, t: f64, q: [f64; N], p: [f64; N], guess: [f64; N]) -> Option<f64> {
        use nalgebra::SMatrix;
        use num_dual::HyperDual64;
        let v = self.system.velocity(t, q, p, guess).ok()?;
        // Second derivatives of L in (q, v) by scalar hyper-duals: off the
        // stepping path, so plainness beats speed here.
        let at = |a: usize, b: usize| {
            let mut qd = q.map(HyperDual64::from_re);
            let mut vd = v.map(HyperDual64::from_re);
            for (k, eps1) in [(a, true), (b, false)] {
                let x = if k < N { &mut qd[k] } else { &mut vd[k - N] };
                if eps1 {
                    x.eps1 = 1.0;
                } else {
                    x.eps2 = 1.0;
                }
            }
            self.system.lagrangian(HyperDual64::from_re(t), qd, vd)
        };
        let lq = SVector::<f64, N>::from_fn(|i, _| at(i, i).eps1);
        let lqq = SMatrix::<f64, N, N>::from_fn(|i, j| at(i, j).eps1eps2);
        // ∂²L/∂v_i∂q_j
        let lvq = SMatrix::<f64, N, N>::from_fn(|i, j| at(N + i, j).eps1eps2);
        let lvv = SMatrix::<f64, N, N>::from_fn(|i, j| at(N + i, N + j).eps1eps2);
        let v = SVector::<f64, N>::from(v);
        let a = lvv.try_inverse()? * (lq - lvq * v);
        let a2 = ((1.0 - 12.0 * kappa) * v.dot(&(lqq * v)) - a.dot(&(lvv * a))) / 8.0;
        a2.is_finite().then_some(a2)
    }

    /// The right side of the energy equation `∂A/∂t_k − w_k^− = E_k^−` of
    /// the next step: `E_k`, plus, for a forced system, the work
    /// `w_{k−1}^+ = F_{k−1}^+·v̂_{k−1}` of the last step's end force (time as
    /// a variable in the discrete Lagrange–d'Alembert principle, docs/theory.md §6).
    fn energy_target(&self) -> f64 {
        match self.memory.previous {
            Some(behind) if forcing::is_forced::<S, N>() => {
                self.energy + forcing::end_work(&self.system, &self.method, &behind)
            }
            _ => self.energy,
        }
    }

    /// Applies a solved step: `p_{k+1}`, `E_{k+1}`, the Kahan-summed time.
    fn accept(&mut self, seg: Segment<N>, report: NewtonReport, taken: Taken) -> Result<&State<N>, Error> {
        let State { step, t: t0, .. } = self.state;
        let h = seg.h;
        // E_{k+1} alone: the momentum comes from `advance` as an increment.
        let d_t1 = derivatives::end_time_derivative(&self.system, &self.method, &seg);
        let (q1, p1, carry, p_carry) = self.advance(&seg, None);
        // t_{k+1} = t_k + h with Kahan compensation: times stay exact sums of the steps.
        let y = h - self.time_error;
        let t1 = t0 + y;
        let quantity = if !super::one_point::action_finite(&self.system, &self.method, &seg) {
            Some("lagrangian")
        } else if d_t1.is_finite() {
            non_finite(t1, &q1, &p1)
        } else {
            Some("energy")
        };
        if let Some(quantity) = quantity {
            self.stats.failed_steps += 1;
            return Err(Error::NonFinite { state: self.state.into(), h, iterations: report.iterations, quantity });
        }
        self.time_error = (t1 - t0) - y;
        self.carry = carry;
        self.p_carry = p_carry;
        if S::DISCONTINUOUS {
            self.watch_energy(&seg, t1);
        }
        if taken != Taken::Root {
            // A least-mismatch step changed the energy: conserve its new value.
            (self.energy, self.energy_carry) = (-d_t1, 0.0);
        } else {
            // E_{k+1} = E_k − (∂A/∂t_k + ∂A/∂t_{k+1}), Kahan-summed: the target
            // of the energy equation is not re-read from the step, whose solve
            // leaves a residual of one sign (Newton approaches a root from one
            // side), so that residuals do not add up over long runs.
            let mut de =
                if S::AUTONOMOUS { 0.0 } else { -derivatives::time_shift_derivative(&self.system, &self.method, &seg) };
            if forcing::is_forced::<S, N>() {
                // The discrete work across node k: E_k^− = E_k + w_{k−1}^+ + w_k^−.
                let behind = self.memory.previous.map_or(0.0, |b| forcing::end_work(&self.system, &self.method, &b));
                de += behind + forcing::start_forcing(&self.system, &self.method, &seg).work;
            }
            let y = de - self.energy_carry;
            let e1 = self.energy + y;
            self.energy_carry = (e1 - self.energy) - y;
            self.energy = e1;
        }
        self.memory.earlier = self.memory.previous.map(|last| (last.h, last.dq));
        self.memory.previous = Some(seg);
        self.state = State { step: step + 1, t: t1, q: q1, p: p1 };
        self.h = h;
        self.clock = super::Clock { t: t1, step: step + 1 };
        self.stats.steps += 1;
        self.stats.newton_iterations += report.iterations as u64;
        match taken {
            Taken::Root => {}
            Taken::LeastSquares => self.stats.energy_fallbacks += 1,
            Taken::Capped(defect) => {
                self.stats.accuracy_capped_steps += 1;
                self.stats.largest_capped_energy_defect = self.stats.largest_capped_energy_defect.max(defect);
            }
        }
        self.stats.last = report;
        Ok(&self.state)
    }
}

impl<S: Lagrangian<N>, M: DiscreteLagrangian, const N: usize> EnergySearch for Integrator<S, M, N> {
    type Trial = Segment<N>;

    /// `g(h)` and `g'(h)` with the DEL solved at step `h`.
    fn probe(&mut self, h: f64, spent: &mut usize) -> Result<Probe<Segment<N>>, Unplaced> {
        let State { t: t0, q: q0, .. } = self.state;
        let (dq, report) = self.solve_del(h).map_err(|failure| Unplaced::newton(failure, h))?;
        *spent += report.iterations;
        let seg = Segment { t0, h, q0, dq };
        // The forced DEL (solved by `solve_del`) and energy equation.
        let d = forcing::extended_step_derivatives(&self.system, &self.method, &seg);
        let slope = match d.d2_q0_q1.try_inverse() {
            Some(inv) => d.d2_t0_t1 - d.d2_t0_q1.dot(&(inv * d.d2_q0_t1)),
            None => f64::NAN,
        };
        let target = self.energy_target();
        let g = d.d_t0 - target;
        if !g.is_finite() {
            let iterations = *spent;
            return Err(Unplaced::new(|state| Error::NonFinite { state, h, iterations, quantity: "energy equation" }));
        }
        Ok(Probe { trial: seg, h, g, slope, scale: target.abs().max(d.d_t0.abs()) })
    }

    fn place(&self, failure: Unplaced) -> Error {
        failure.at(self.state)
    }

    fn fallback(&self) -> EnergyFallback {
        self.fallback
    }

    fn no_energy_step(&self, lo: f64, hi: f64, best: &Probe<Segment<N>>, spent: usize) -> Error {
        best.no_energy_step(self.state, (lo, hi), spent, self.root_test())
    }
}

impl<S: Lagrangian<N>, M: DiscreteLagrangian, const N: usize> Integrator<S, M, N> {
    /// The last step taken, from node `k − 1` to node `k`, as start and
    /// increments; `None` before the first step.
    pub fn last_segment(&self) -> Option<&Segment<N>> {
        self.memory.previous.as_ref()
    }

    /// The tangent map of the last step in the extended phase space
    /// `(t, q, −E, p)` (docs/theory.md §8), a `(2N+2)×(2N+2)` matrix; see
    /// [`symplectic::extended_tangent_map`](crate::symplectic::extended_tangent_map).
    /// For variable steps it preserves `dq∧dp − dt∧dE`.
    pub fn last_extended_tangent_map(&self) -> Option<nalgebra::DMatrix<f64>> {
        crate::symplectic::extended_tangent_map(&self.system, &self.method, self.memory.previous.as_ref()?)
    }
}

/// The band `(low, high)` of the condition's value `x` without an admissible
/// root, for a symmetric method of order `2s` and the step ratio bound `r`
/// (docs/energy-steps.md (3.2)): the local model
/// `x (ρ^{2s} − 1) + ρ^{2s+1} + 1 = 0` has a root `ρ ∈ [1/r, r]` iff
/// `x ≥ f(1/r)` or `x ≤ max_{1 < ρ ≤ r} f(ρ)`, with
/// `f(ρ) = −(ρ^{2s+1} + 1)/(ρ^{2s} − 1)`, whose maximum on `ρ > 1` is at the
/// root `ρ*` of `ρ^{2s+1} − (2s+1)ρ − 2s` (`s = 1`: `ρ* = 2`, `f = −3`).
pub(crate) fn root_band(s: i32, r: f64) -> (f64, f64) {
    let f = |rho: f64| -(rho.powi(2 * s + 1) + 1.0) / (rho.powi(2 * s) - 1.0);
    let high = f(1.0 / r);
    // ρ* ∈ (1, 2]: the polynomial is −4s at 1 and positive at 2.
    let (mut lo, mut hi) = (1.0f64, 2.0f64);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if mid.powi(2 * s + 1) - f64::from(2 * s + 1) * mid - f64::from(2 * s) < 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let low = f(r.min(hi));
    (low, high)
}

#[cfg(test)]
mod tests {
    use super::root_band;

    #[test]
    fn the_root_band_reproduces_the_thresholds_of_the_local_model() {
        // s = 1 closed form (3.3): r = 2 gives (−3, 3/2); r = 1.5 gives
        // (−(r² − r + 1)/(r − 1), (r² − r + 1)/(r(r − 1))).
        let (low, high) = root_band(1, 2.0);
        assert!((low + 3.0).abs() < 1e-12 && (high - 1.5).abs() < 1e-12, "{low} {high}");
        let r = 1.5;
        let (low, high) = root_band(1, r);
        assert!((low + (r * r - r + 1.0) / (r - 1.0)).abs() < 1e-12, "{low}");
        assert!((high - (r * r - r + 1.0) / (r * (r - 1.0))).abs() < 1e-12, "{high}");
        // The table's x*_s for a ratio bound above ρ*.
        for (s, x_star) in [(2, -2.0633), (3, -1.7404), (4, -1.5744), (8, -1.3140)] {
            let (low, _) = root_band(s, 4.0);
            assert!((low - x_star).abs() < 1e-4, "s = {s}: {low}");
        }
    }
}
