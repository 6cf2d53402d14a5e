//! Energy-preserving steps of a run-time-sized system (docs/theory.md §9):
//! the step size `h_k` solves the discrete energy equation
//! `∂A/∂t_k(q_k, q_{k+1}, h_k) = E_k` together with the DEL, as at a
//! compile-time size (`variable_step.rs`).
//!
//! Each trial `h` is a probe: the DEL solved by the step's own banded (or
//! dense) Newton iteration, then `g(h) = ∂A/∂t_k − E_k` and its slope
//! `g'(h)`, the Schur complement of the bordered Jacobian, from the tape
//! (`tape_step/energy.rs`): `O(N)` per probe for a banded `L`. A step is
//! solved in two stages, like the compile-time one:
//!
//! 1. Newton on `g` along the solutions of the DEL, from the extrapolated
//!    step: the bordered system `(Δq, h)` eliminated to its Schur
//!    complement, each iterate's DEL solved again. It succeeds almost
//!    always, in two or three probes.
//! 2. If it fails or leaves the admissible bracket, the safeguarded search
//!    written once for every size ([`EnergySearch::bracketed`]): sampling
//!    for a sign change, Newton safeguarded by bisection, and the least
//!    mismatch by golden section, reported as [`Error::NoEnergyStep`] or
//!    taken under [`EnergyFallback::LeastSquares`].
//!
//! The first step has the given size, and so has the landing step of
//! `run_until`; the energy conserved from each is its discrete energy.
//!
//! A forced system takes energy-balance steps: the DEL carries `F_k^−`
//! and the energy equation the work of the forces on the time variations,
//! `∂A/∂t_k − w_k^− = E_k + w_{k−1}^+`, so that `E_{k+1} − E_k = W_k =
//! w_{k−1}^+ + w_k^−` (docs/theory.md §6), as at a compile-time size.

use super::{DynIntegrator, DynMethod, Sliced, is_forced, node_at};
use crate::error::{Error, Unplaced};
use crate::integrator::tape_step::{EnergyBuffers, EnergyTerms, Guess};
use crate::integrator::{Clock, EnergyFallback, EnergySearch, Probe, StepBounds, Taken};
use crate::newton::NewtonReport;
use crate::system::DynLagrangian;

/// Why a run-time-sized integrator refuses an accuracy bound on its energy
/// steps.
pub(super) const NO_ACCURACY_BOUND: &str = "an accuracy bound on energy steps of a run-time-sized system: the fastest mode of the linearisation is a dense eigenproblem of the size of the system";

/// The most probes stage 1 spends before it hands the step to the search.
const NEWTON_PROBES: usize = 8;

/// Energy-preserving steps: the bounds, what to do without a root, the
/// energy the steps conserve and the scratch of the probes.
#[derive(Debug)]
pub(super) struct EnergySteps {
    pub(super) bounds: StepBounds,
    fallback: EnergyFallback,
    /// `E_k`: the right side of the next step's energy equation.
    pub(super) energy: f64,
    /// Kahan compensation of `energy` (a time-dependent `L` or forces
    /// change it).
    pub(super) energy_carry: f64,
    /// `w_{k−1}^+`: the work of the last step's end force on a variation of
    /// its end time, which the next step's energy equation carries (zero
    /// without forces).
    pub(super) behind: f64,
    /// Kahan compensation of the time: the times are exact sums of the steps.
    pub(super) time_error: f64,
    buffers: EnergyBuffers,
    /// The latest probe.
    pub(super) latest: Option<Latest>,
    /// The number of the latest probe.
    pub(super) serial: u64,
    /// `dΔq/dh = −J⁻¹c` along the solutions of the DEL at the latest probe
    /// (scratch; valid where its slope is finite).
    tangent: Vec<f64>,
    /// Stage 1: a probe starts its Newton iteration from the latest probe's
    /// increment moved along the tangent, the increment of the bordered
    /// Newton step on `(Δq, h)`.
    pub(super) warm: bool,
    /// A probe's starting increment and the last step's increment scaled to
    /// its size (scratch, so that a probe does not allocate).
    start: Vec<f64>,
    scaled: Vec<f64>,
}

/// A probe: its number, size, increment and energy terms (a Galerkin
/// rule's probe keeps its nodes in its work, and no increment here).
#[derive(Debug)]
pub(super) struct Latest {
    pub(super) serial: u64,
    pub(super) h: f64,
    pub(super) dq: Vec<f64>,
    pub(super) terms: EnergyTerms,
}

impl EnergySteps {
    /// Steps within `bounds`, conserving `energy` until the first step sets it.
    pub(super) fn new(bounds: StepBounds, fallback: EnergyFallback, energy: f64) -> Self {
        Self {
            bounds,
            fallback,
            energy,
            energy_carry: 0.0,
            behind: 0.0,
            time_error: 0.0,
            buffers: EnergyBuffers::default(),
            latest: None,
            serial: 0,
            tangent: Vec::new(),
            warm: false,
            start: Vec::new(),
            scaled: Vec::new(),
        }
    }
}

/// A copy conserves the same energy; the probes' scratch is its own (a
/// trial is looked up only within the step that probed it).
impl Clone for EnergySteps {
    fn clone(&self) -> Self {
        Self {
            bounds: self.bounds,
            fallback: self.fallback,
            energy: self.energy,
            energy_carry: self.energy_carry,
            behind: self.behind,
            time_error: self.time_error,
            buffers: EnergyBuffers::default(),
            latest: None,
            serial: self.serial,
            tangent: Vec::new(),
            warm: false,
            start: Vec::new(),
            scaled: Vec::new(),
        }
    }

    fn clone_from(&mut self, source: &Self) {
        (self.bounds, self.fallback, self.energy) = (source.bounds, source.fallback, source.energy);
        (self.energy_carry, self.time_error, self.serial) = (source.energy_carry, source.time_error, source.serial);
        self.behind = source.behind;
    }
}

impl<S: DynLagrangian, M: DynMethod> DynIntegrator<S, M> {
    /// One energy-preserving step; the first one has the given size.
    pub(super) fn energy_step(&mut self) -> Result<(), Error> {
        let Some(bounds) = self.variable.as_ref().map(|steps| steps.bounds) else {
            let t1 = self.clock.at(self.state.step + 1, self.h);
            return self.step_by(self.h, t1);
        };
        let Some(h_prev) = self.previous.as_ref().map(|last| last.h) else {
            // E_L(q0, v0) is not the discrete energy of any step: the first
            // step has the given size and sets the energy conserved after it.
            let h = self.h;
            self.step_by(h, self.state.t + h)?;
            self.reread_energy();
            return Ok(());
        };
        if is_forced::<S>() {
            self.work_behind()?;
        }
        let (lo, hi) = bounds.bracket(h_prev);
        let guess = self.h.clamp(lo, hi);
        // With two steps of history, Newton starts from the extrapolated step.
        let start = self.earlier.as_ref().map_or(guess, |(h_earlier, _)| (2.0 * h_prev - h_earlier).clamp(lo, hi));
        let outcome = self.newton_in_h(start, lo, hi).or_else(|spent| self.bracketed(guess, lo, hi, false, spent));
        match outcome {
            Ok((trial, report, taken)) if self.galerkin.is_some() => self.accept_nodes(trial, report, taken),
            Ok((trial, report, taken)) => self.accept(trial, report, taken),
            Err(e) => {
                self.stats.failed_steps += 1;
                Err(e)
            }
        }
    }

    /// The energy conserved from here on is the discrete energy of the last
    /// step (a step of the given size: the first, or a landing).
    pub(super) fn reread_energy(&mut self) {
        let energy = self.discrete_energy();
        if let Some(steps) = self.variable.as_deref_mut() {
            (steps.energy, steps.energy_carry, steps.time_error) = (energy, 0.0, 0.0);
        }
    }

    /// `w_{k−1}^+` of the last step, for the energy equation of the next.
    fn work_behind(&mut self) -> Result<(), Error> {
        let Some(last) = self.previous.as_ref() else { return Ok(()) };
        let model = Sliced { system: &self.system, points: self.points };
        let work = self.work.end_work(&model, (last.t0, last.h), &last.q0, &last.dq);
        match (work, self.variable.as_deref_mut()) {
            (Ok(work), Some(steps)) => {
                steps.behind = work;
                Ok(())
            }
            (Ok(_), None) => Ok(()),
            (Err(failure), _) => {
                self.stats.failed_steps += 1;
                Err(Error::from_newton(failure.at(0), self.state.clone(), self.h))
            }
        }
    }

    /// Stage 1: Newton on `g(h)` from `start`, each iterate's DEL solved.
    /// `Err` carries the Newton iterations spent when it fails, stalls or
    /// leaves `[lo, hi]`.
    fn newton_in_h(&mut self, start: f64, lo: f64, hi: f64) -> Result<((f64, u64), NewtonReport, Taken), usize> {
        let outcome = self.warm_newton_in_h(start, lo, hi);
        if let Some(steps) = self.variable.as_deref_mut() {
            steps.warm = false;
        }
        outcome
    }

    /// [`newton_in_h`](Self::newton_in_h), each probe after the first
    /// started from the last one along its tangent.
    fn warm_newton_in_h(&mut self, start: f64, lo: f64, hi: f64) -> Result<((f64, u64), NewtonReport, Taken), usize> {
        let mut spent = 0;
        let mut h = start;
        for _ in 0..NEWTON_PROBES {
            let Ok(p) = self.probe(h, &mut spent) else { return Err(spent) };
            if let Some(steps) = self.variable.as_deref_mut() {
                steps.warm = p.slope.is_finite();
            }
            if self.solved(&p) {
                return Ok((p.trial, p.report(spent), Taken::Root));
            }
            let next = h - p.g / p.slope;
            if !(next >= lo && next <= hi) {
                return Err(spent);
            }
            // A correction at the rounding of `h`: the root, as well as `h` can tell.
            if (next - h).abs() <= 4.0 * f64::EPSILON * h {
                return Ok((p.trial, p.report(spent), Taken::Root));
            }
            h = next;
        }
        Err(spent)
    }

    /// Takes the chosen trial step: its increment (that of the latest probe,
    /// or solved again at its size, to the same bits), one Newton correction
    /// of the DEL from it with the momentum and energy of the step, the
    /// Kahan-summed time and, for a time-dependent `L`, the energy changed by
    /// the step's time shift.
    fn accept(&mut self, (h, serial): (f64, u64), report: NewtonReport, taken: Taken) -> Result<(), Error> {
        let latest = self.variable.as_deref_mut().and_then(|steps| steps.latest.take());
        let (dq, terms) = match latest {
            Some(latest) if latest.serial == serial => (latest.dq, latest.terms),
            other => {
                if let Some(latest) = other {
                    self.work.recycle(latest.dq);
                }
                let mut spent = 0;
                self.probe(h, &mut spent).map_err(|e| self.place(e))?;
                match self.variable.as_deref_mut().and_then(|steps| steps.latest.take()) {
                    Some(latest) => (latest.dq, latest.terms),
                    None => {
                        return Err(Error::Unsupported { what: "energy steps without their state (internal error)" });
                    }
                }
            }
        };
        let Some(steps) = self.variable.as_deref_mut() else {
            self.work.recycle(dq);
            return Err(Error::Unsupported { what: "energy steps without their state (internal error)" });
        };
        let t0 = self.state.t;
        let y = h - steps.time_error;
        let t1 = t0 + y;
        let model = Sliced { system: &self.system, points: self.points };
        let node = node_at(&self.state, (&self.carry, &self.p_carry), self.summation);
        let guess = Guess { predictor: &dq, last: None };
        let outcome = self.work.newton_step(&model, &node, h, t1, &guess, &self.newton);
        self.work.recycle(dq);
        let (mut step, e1) = match outcome {
            Ok(x) => x,
            Err(failure) => {
                self.stats.failed_steps += 1;
                return Err(Error::from_newton(failure, self.state.clone(), h));
            }
        };
        steps.time_error = (t1 - t0) - y;
        if taken == Taken::Root {
            // E_{k+1} = E_k − (∂A/∂t_k + ∂A/∂t_{k+1}) + w_{k−1}^+ + w_k^−,
            // Kahan-summed; the target is not re-read from the step (its
            // residual has one sign).
            let mut change = if S::AUTONOMOUS { 0.0 } else { -terms.time_shift };
            if is_forced::<S>() {
                change += steps.behind + terms.work;
            }
            if change != 0.0 {
                let y = change - steps.energy_carry;
                let e = steps.energy + y;
                steps.energy_carry = (e - steps.energy) - y;
                steps.energy = e;
            }
        } else {
            // A least-mismatch step changed the energy: conserve its new value.
            (steps.energy, steps.energy_carry) = (e1, 0.0);
        }
        step.report.iterations += report.iterations;
        self.commit(step, h, t1);
        self.work.energy = Some(e1);
        self.h = h;
        self.clock = Clock { t: t1, step: self.state.step };
        if taken == Taken::LeastSquares {
            self.stats.energy_fallbacks += 1;
        }
        Ok(())
    }
}

impl<S: DynLagrangian, M: DynMethod> EnergySearch for DynIntegrator<S, M> {
    /// The trial's size and the number of its probe.
    type Trial = (f64, u64);

    /// `g(h)` and `g'(h)` with the DEL solved at step `h`, from the
    /// predictor of a fixed step of that size.
    fn probe(&mut self, h: f64, spent: &mut usize) -> Result<Probe<(f64, u64)>, Unplaced> {
        if self.galerkin.is_some() {
            return self.node_probe(h, spent);
        }
        let n = self.state.q.len();
        let last = self.previous.as_ref().map(|last| (last.h, &last.dq[..]));
        let earlier = self.earlier.as_ref().map(|(h, dq)| (*h, &dq[..]));
        let (mut predictor, mut scaled) = match self.variable.as_deref_mut() {
            Some(steps) => (core::mem::take(&mut steps.start), core::mem::take(&mut steps.scaled)),
            None => Default::default(),
        };
        predictor.clear();
        predictor.resize(n, 0.0);
        match self.variable.as_deref() {
            Some(EnergySteps { warm: true, latest: Some(from), tangent, .. }) => {
                for ((x, d), t) in predictor.iter_mut().zip(&from.dq).zip(tangent) {
                    *x = d + (h - from.h) * t;
                }
            }
            _ => crate::integrator::predict_into(h, last, earlier, &self.v0, &mut predictor),
        }
        scaled.clear();
        if let Some(last) = self.previous.as_ref() {
            scaled.extend(last.dq.iter().map(|x| x * (h / last.h)));
        }
        let guess = Guess { predictor: &predictor, last: self.previous.is_some().then_some(&scaled[..]) };
        let model = Sliced { system: &self.system, points: self.points };
        let node = node_at(&self.state, (&self.carry, &self.p_carry), self.summation);
        let Some(steps) = self.variable.as_deref_mut() else {
            return Err(Unplaced::new(|_| Error::Unsupported { what: "energy steps under fixed steps" }));
        };
        let probed = self.work.energy_probe(&mut steps.buffers, &model, &node, h, &guess, &self.newton);
        (steps.start, steps.scaled) = (predictor, scaled);
        let (dq, report, terms) = probed.map_err(|failure| Unplaced::newton(failure, h))?;
        *spent += report.iterations;
        let target = steps.energy + steps.behind;
        let g = terms.d_t0 - target;
        steps.serial += 1;
        if terms.slope.is_finite() {
            steps.tangent.clear();
            steps.tangent.extend(steps.buffers.tangent().iter().map(|y| -y));
        }
        let latest = Latest { serial: steps.serial, h, dq, terms };
        if let Some(old) = steps.latest.replace(latest) {
            self.work.recycle(old.dq);
        }
        if !g.is_finite() {
            let iterations = *spent;
            return Err(Unplaced::new(|state| Error::NonFinite { state, h, iterations, quantity: "energy equation" }));
        }
        Ok(Probe { trial: (h, steps.serial), h, g, slope: terms.slope, scale: target.abs().max(terms.d_t0.abs()) })
    }

    fn place(&self, failure: Unplaced) -> Error {
        failure.at(self.state.clone())
    }

    fn fallback(&self) -> EnergyFallback {
        self.variable.as_ref().map_or_else(EnergyFallback::default, |steps| steps.fallback)
    }

    /// A Galerkin rule's energy equation is solved where `g` is within
    /// `64 ε` of the size of the terms of `E`, as at a compile-time size
    /// (`galerkin/energy.rs`): its energy error is `O(h^{2s+1})`, so `g'`
    /// is small and round-off fixes `h` to fewer digits than the nodes.
    fn solved(&self, p: &Probe<(f64, u64)>) -> bool {
        match self.galerkin {
            Some(_) => p.g.abs() <= 64.0 * f64::EPSILON * p.scale,
            None => p.solved(),
        }
    }

    fn no_energy_step(&self, lo: f64, hi: f64, best: &Probe<(f64, u64)>, spent: usize) -> Error {
        best.no_energy_step(self.state.clone(), (lo, hi), spent, None)
    }
}
