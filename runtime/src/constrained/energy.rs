//! Energy-preserving and energy-balance variable steps of the constrained
//! one-point rules: the step size `h` as one more unknown of a RATTLE step,
//! fixed by the discrete energy equation of the unconstrained rule
//! (Kane, Marsden & Ortiz; Marsden & West §4.7, time as a variable):
//!
//! ```text
//! p_k + D₁A(q_k, q_{k+1}, h) + F_k^− + G(q_k)ᵀλ_k = 0,   g(q_{k+1}) = 0,
//! ∂A/∂t_k(q_k, q_{k+1}, h) − w_k^− = E_k + w_{k−1}^+,
//! ```
//!
//! then the momentum line as for fixed steps. The constraints `g(q)` do not
//! depend on time, so the time component of the constrained variational
//! principle carries no multiplier: the constraint forces do no work, and
//! the energy equation is the unconstrained one (`w = 0` without forces,
//! the de León–Martín de Diego energy evolution for a time-dependent `L`).
//! A moving manifold `g(t, q)` would add the work `λ·∂g/∂t` of the
//! constraint forces: those systems are refused at `start`.
//!
//! The step size is found by the search of the unconstrained rules
//! ([`EnergySearch`]): at each trial `h` the position line is solved as for a
//! fixed step, and `g(h) = ∂A/∂t_k − w_k^− − E_k` is evaluated with its
//! slope along the constrained solutions,
//!
//! ```text
//! g'(h) = ∂²A/∂t_k∂t_{k+1} + ∂²A/∂t_k∂q_{k+1} · x,    [ J    G(q_k)ᵀ ] [x]     [∂²A/∂q_k∂t_{k+1}]
//!                                                     [ G(q_{k+1})  0 ] [y] = − [        0       ]
//! ```
//!
//! with `J = ∂²A/∂q_k∂q_{k+1}` (forces included) and `x = ∂q_{k+1}/∂h`. The
//! first step has the given size; the energy of that step is the one
//! conserved. The coupled Newton iteration on `(q_{k+1}, h)` that the
//! unconstrained rules try first is not used: the search starts at the step
//! extrapolated from the last two.

use nalgebra::SVector;

use super::linear::{self, inverse, solve_schur_inverted};
use super::{Constrained, Positions, commit, jacobian, positions};
use crate::derivatives::{self, Segment};
use crate::discrete::DiscreteLagrangian;
use crate::error::{Error, Unplaced};
use crate::forcing;
use crate::integrator::{Clock, EnergyFallback, EnergySearch, Integrator, Method, Probe, StepBounds, Taken};
use crate::newton::NewtonReport;
use crate::system::Lagrangian;

/// Why a constrained system with moving constraints `g(t, q)` takes no
/// energy-preserving steps.
pub(super) const MOVING_CONSTRAINTS: &str = "energy-preserving steps with time-dependent (moving) constraints `g(t, q)`: the constraint forces do work on a moving manifold, which the energy equation does not carry";

/// Why a constrained system takes no energy-preserving steps with an
/// accuracy bound.
pub(super) const ACCURACY_BOUND: &str = "an accuracy bound (`StepBounds::with_accuracy`) on energy-preserving steps with holonomic constraints: the fastest mode of the constrained linearisation is not computed";

/// One energy-preserving step (the first has the given size); on failure
/// nothing in `it` has changed.
pub(super) fn energy_step<S: Lagrangian<N>, D: DiscreteLagrangian, const N: usize, const M: usize>(
    it: &mut Integrator<S, Constrained<D, M>, N>,
    bounds: StepBounds,
) -> Result<(), Error> {
    let Some(last) = it.memory.previous else {
        // As without constraints: E_L(q0, v0) is not the discrete energy of
        // any step, so the first step has the given size and its discrete
        // energy is the one conserved.
        let h = it.h;
        let t1 = it.state.t + h;
        <Constrained<D, M> as Method<f64>>::fixed_step(it, h, t1)?;
        reread_energy(it);
        return Ok(());
    };
    let (lo, hi) = bounds.bracket(last.h);
    // The energy root moves smoothly with the motion: extrapolated from the
    // last two steps, the guess is off by O(h³) relative to h.
    let guess = match it.memory.earlier {
        Some(earlier) => 2.0 * last.h - earlier.h,
        None => last.h,
    }
    .clamp(lo, hi);
    match it.bracketed(guess, lo, hi, false, 0) {
        Ok((solved, report, taken)) => accept(it, solved, report, taken),
        Err(error) => {
            it.stats.failed_steps += 1;
            Err(error)
        }
    }
}

/// Sets the energy target to the discrete energy of the last step.
pub(super) fn reread_energy<S: Lagrangian<N>, D: DiscreteLagrangian, const N: usize, const M: usize>(
    it: &mut Integrator<S, Constrained<D, M>, N>,
) {
    it.energy_carry = 0.0;
    if let Some(last) = &it.memory.previous {
        it.energy = -derivatives::end_time_derivative(&it.system, &it.method.rule, last);
    }
}

impl<S: Lagrangian<N>, D: DiscreteLagrangian, const N: usize, const M: usize> EnergySearch
    for Integrator<S, Constrained<D, M>, N>
{
    type Trial = Positions<N, M>;

    fn probe(&mut self, h: f64, spent: &mut usize) -> Result<Probe<Positions<N, M>>, Unplaced> {
        let state = self.state;
        let solved = positions(self, h, state.t + h)?;
        *spent += solved.iterations;
        let (system, rule) = (&self.system, &self.method.rule);
        let seg = solved.seg;
        // Lagrange–d'Alembert with time as a variable, as without constraints.
        let d = forcing::extended_step_derivatives(system, rule, &seg);
        let target = energy_target(self);
        let g = d.d_t0 - target;
        if !g.is_finite() {
            let iterations = *spent;
            return Err(Unplaced::new(|state| Error::NonFinite { state, h, iterations, quantity: "energy equation" }));
        }
        Ok(Probe { trial: solved, h, g, slope: slope(self, &seg, &d), scale: target.abs().max(d.d_t0.abs()) })
    }

    fn place(&self, failure: Unplaced) -> Error {
        failure.at(self.state)
    }

    fn fallback(&self) -> EnergyFallback {
        self.fallback
    }

    /// Without the local root test: its model of the energy error is that
    /// of the unconstrained flow.
    fn no_energy_step(&self, lo: f64, hi: f64, best: &Probe<Positions<N, M>>, spent: usize) -> Error {
        best.no_energy_step(self.state, (lo, hi), spent, None)
    }
}

/// `g'(h)` along the constrained solutions `q_{k+1}(h)` (see the module
/// documentation); NaN where the saddle-point system is singular, which
/// the search takes as "bisect".
fn slope<S: Lagrangian<N>, D: DiscreteLagrangian, const N: usize, const M: usize>(
    it: &Integrator<S, Constrained<D, M>, N>,
    seg: &Segment<N>,
    d: &derivatives::ExtendedStepDerivatives<N>,
) -> f64 {
    let (system, state) = (&it.system, &it.state);
    let (Some((_, g0)), Some((_, g1))) =
        (jacobian::<S, N, M>(system, state.t, &state.q), jacobian::<S, N, M>(system, seg.t1(), &seg.q1()))
    else {
        return f64::NAN;
    };
    let (j_inv, rcond) = inverse(d.d2_q0_q1);
    if rcond <= it.newton.min_rcond {
        return f64::NAN;
    }
    match solve_schur_inverted(&j_inv, &g0.transpose(), &g1, &d.d2_q0_t1, &SVector::zeros(), it.newton.min_rcond) {
        Ok((x, _)) => d.d2_t0_t1 + d.d2_t0_q1.dot(&x),
        Err(linear::Singular::Block(_) | linear::Singular::Schur(_)) => f64::NAN,
    }
}

/// The right side of the energy equation: `E_k`, plus for a forced system
/// the work `w_{k−1}^+` of the last step's end force.
fn energy_target<S: Lagrangian<N>, D: DiscreteLagrangian, const N: usize, const M: usize>(
    it: &Integrator<S, Constrained<D, M>, N>,
) -> f64 {
    match &it.memory.previous {
        Some(behind) if forcing::is_forced::<S, N>() => {
            it.energy + forcing::end_work(&it.system, &it.method.rule, behind)
        }
        _ => it.energy,
    }
}

/// Takes the step `solved` found by the search (`report`: its Newton
/// iterations in all and its energy mismatch): the momentum line, the Kahan-summed time and energy
/// target. On failure nothing in `it` has changed.
fn accept<S: Lagrangian<N>, D: DiscreteLagrangian, const N: usize, const M: usize>(
    it: &mut Integrator<S, Constrained<D, M>, N>,
    mut solved: Positions<N, M>,
    report: NewtonReport,
    taken: Taken,
) -> Result<(), Error> {
    let (system, rule) = (&it.system, &it.method.rule);
    let (seg, iterations) = (solved.seg, report.iterations);
    let d_t1 = derivatives::end_time_derivative(system, rule, &seg);
    if !d_t1.is_finite() {
        it.stats.failed_steps += 1;
        return Err(Error::NonFinite { state: it.state.into(), h: seg.h, iterations, quantity: "energy" });
    }
    // E_{k+1} − E_k: zero for an autonomous, unforced L; the energy
    // evolution −(∂A/∂t_k + ∂A/∂t_{k+1}) of a time-dependent one; the
    // discrete work w_{k−1}^+ + w_k^− across node k of the forces.
    let mut de = if S::AUTONOMOUS { 0.0 } else { -derivatives::time_shift_derivative(system, rule, &seg) };
    if forcing::is_forced::<S, N>() {
        let behind = it.memory.previous.map_or(0.0, |b| forcing::end_work(system, rule, &b));
        de += behind + forcing::start_forcing(system, rule, &seg).work;
    }
    // t_{k+1} = t_k + h with Kahan compensation.
    let t0 = it.state.t;
    let y = seg.h - it.time_error;
    let t1 = t0 + y;
    solved.iterations = iterations;
    if let Err(error) = commit(it, solved, t1) {
        it.stats.failed_steps += 1;
        return Err(error);
    }
    it.time_error = (t1 - t0) - y;
    if taken == Taken::Root {
        // Kahan-summed, the target not re-read from the step (whose solve
        // leaves a residual of one sign), as without constraints.
        let y = de - it.energy_carry;
        let e1 = it.energy + y;
        it.energy_carry = (e1 - it.energy) - y;
        it.energy = e1;
    } else {
        // A least-mismatch step changed the energy: conserve its new value.
        (it.energy, it.energy_carry) = (-d_t1, 0.0);
        it.stats.energy_fallbacks += 1;
    }
    it.stats.last = report;
    it.h = seg.h;
    it.clock = Clock { t: it.state.t, step: it.state.step };
    Ok(())
}
