//! Holonomic constraints on run-time-sized systems ([`DynLagrangian`]):
//! the RATTLE form of the constrained discrete Euler–Lagrange equations of
//! the [module documentation](super), with every `N`- and `M`-sized object
//! on the heap and the saddle-point systems solved in `O(N)` when they are
//! banded.
//!
//! A step is what the const-size [`Constrained`](super::Constrained) step
//! does, with other linear algebra:
//!
//! * the step Jacobian `J` and `D₁A` come from the reverse-mode core of
//!   large systems (`integrator/tape_step`: the generated gradient code on
//!   dual lanes, or the tape), banded when `#[lagrangian]` proved `L`'s
//!   Hessian banded;
//! * `g` and `G` come from dual lanes whose colours follow the structure of
//!   `G` found once, at `start`, from the recorded operations of `g`
//!   (`sparsity.rs`);
//! * the saddle-point systems of the position and the momentum lines are
//!   factored whole, with each multiplier interleaved next to the
//!   coordinates its constraint involves, by banded LU with partial
//!   pivoting (`kkt.rs`): `O(N)` for a chain, in storage allocated at
//!   `start`.
//!
//! Positions are summed plainly (no Kahan compensation), and the
//! constraints must not depend on time; forces, other step policies and the
//! Galerkin families are the const-size integrator's.

use super::CONSISTENCY_TOLERANCE;
use super::kkt::{Kkt, KktFailure};
use super::sparsity::{self, Jacobian, ProbeFailure};
use crate::discrete::DiscreteLagrangian;
use crate::error::Error;
use crate::integrator::{Sliced, tape_energy, tape_legendre, velocity_derivatives};
use crate::integrator::{SparseWork, Stats, TapeModel};
use crate::newton::{Breakdown, NewtonOptions, NewtonReport};
use crate::real::{all_finite, max_abs};
use crate::state::PhasePoint;
use crate::system::DynLagrangian;

/// A RATTLE integrator for a run-time-sized system with holonomic
/// constraints ([`DynLagrangian::constraint_count`] of them), under a
/// one-point rule `R` with quadrature points ([`Midpoint`](crate::Midpoint),
/// [`Trapezoid`](crate::Trapezoid), [`AlphaBeta`](crate::AlphaBeta)), with
/// fixed steps. See the [module documentation](self).
///
/// Every failure is a [`Error`] and leaves the integrator as it was.
#[derive(Debug)]
pub struct DynConstrained<S, R> {
    system: S,
    rule: R,
    points: [f64; 2],
    h: f64,
    newton: NewtonOptions,
    state: PhasePoint,
    /// `v_k`.
    velocity: Vec<f64>,
    /// `λ` of the last step (zero before the first).
    lambda: Vec<f64>,
    /// The last increment: the next step's first guess.
    last_dq: Option<Vec<f64>>,
    /// The discrete energy of the last step (the energy of the initial data
    /// before the first).
    energy: f64,
    work: Box<SparseWork>,
    kkt: Kkt,
    /// `g` and `G` at the current node.
    g0: Jacobian,
    /// `g` and `G` at a step's end node (scratch until the step is taken).
    g1: Jacobian,
    scratch: Scratch,
    stats: Stats,
}

/// The buffers of a step, allocated at `start`.
#[derive(Clone, Debug)]
struct Scratch {
    dq: Vec<f64>,
    lambda: Vec<f64>,
    q1: Vec<f64>,
    r1: Vec<f64>,
    r2: Vec<f64>,
    end: Vec<f64>,
    v: Vec<f64>,
    mu: Vec<f64>,
}

impl<S: DynLagrangian, R: DiscreteLagrangian> DynConstrained<S, R> {
    /// Starts at `(t0, q0, v0)` with `p0 = ∂L/∂v(t0, q0, v0)`, after
    /// finding the structure of `G` and checking the data.
    ///
    /// Fails with [`Error::Unsupported`] for a rule without quadrature
    /// points, `M = 0` or `M ≥ N` constraints, time-dependent constraints,
    /// forces or dissipation, or a size whose buffers cannot be allocated;
    /// [`Error::NonFiniteConstraints`] where `g` or `G` is not finite;
    /// [`Error::InconsistentConstraints`] for data off the manifold or
    /// its tangent space by more than [`CONSISTENCY_TOLERANCE`] (relative);
    /// [`Error::SingularConstraints`] where `G` is rank-deficient (a
    /// constraint that does not depend on `q`, redundant constraints); and
    /// as [`Problem::stepper`](crate::Problem::stepper) at a run-time size
    /// for the step size, the Newton options and the initial data.
    pub fn start(system: S, rule: R, h: f64, t0: f64, q0: &[f64], v0: &[f64]) -> Result<Self, Error> {
        Self::start_with(system, rule, h, NewtonOptions::default(), t0, q0, v0)
    }

    /// [`start`](Self::start) with Newton settings.
    pub fn start_with(
        system: S,
        rule: R,
        h: f64,
        newton: NewtonOptions,
        t0: f64,
        q0: &[f64],
        v0: &[f64],
    ) -> Result<Self, Error> {
        let Some((points, _)) = rule.galerkin_points() else {
            return Err(Error::Unsupported {
                what: "a discrete lagrangian without quadrature points (`galerkin_points`) on a run-time-sized system",
            });
        };
        newton.validate().map_err(|reason| Error::InvalidNewtonOptions { reason })?;
        if !(h.is_finite() && h > 0.0) {
            return Err(Error::InvalidStepSize { h });
        }
        let n = system.dimension();
        for (what, x) in [("q0", q0), ("v0", v0)] {
            if x.len() != n {
                return Err(Error::WrongLength { what, expected: n, found: x.len() });
            }
        }
        if !t0.is_finite() || !all_finite(q0) || !all_finite(v0) {
            return Err(Error::InvalidInitialData { reason: "t0, q0 and v0 must be finite" });
        }
        let m = system.constraint_count();
        if m == 0 || m >= n {
            return Err(Error::Unsupported {
                what: "holonomic constraints: the number of constraints M must satisfy 0 < M < N",
            });
        }
        if !S::CONSTRAINTS_AUTONOMOUS {
            return Err(Error::Unsupported { what: "time-dependent constraints on a run-time-sized system" });
        }
        // Its saddle-point steps carry no discrete forces.
        if S::HAS_FORCE || S::HAS_DISSIPATION {
            return Err(Error::Unsupported {
                what: "forces or dissipation with holonomic constraints on a run-time-sized system",
            });
        }
        let state = PhasePoint { step: 0, t: t0, q: q0.to_vec(), p: vec![0.0; n] };
        let rows = match sparsity::probe(&system, t0, q0, m) {
            Ok(rows) => rows,
            Err(ProbeFailure::ConstantRow) => return Err(Error::SingularConstraints { state, rcond: 0.0 }),
            Err(ProbeFailure::Tape) => {
                return Err(Error::InvalidInitialData {
                    reason: "the constraints could not be recorded on the derivative tape",
                });
            }
        };
        let mut g0 = Jacobian::new(n, rows.clone());
        if !g0.evaluate(&system, t0, q0) {
            return Err(Error::NonFiniteConstraints { state });
        }
        let (position, velocity) = inconsistency(&g0, q0, v0);
        if !(position <= CONSISTENCY_TOLERANCE && velocity <= CONSISTENCY_TOLERANCE) {
            return Err(Error::InconsistentConstraints { position, velocity, tolerance: CONSISTENCY_TOLERANCE });
        }
        let model = Sliced::new(&system, points);
        let (p0, energy) = tape_legendre(&model, t0, q0, v0).map_err(|reason| Error::InvalidInitialData { reason })?;
        let too_large = Error::Unsupported {
            what: "a constrained system this large with this coupling: the step matrices cannot be allocated",
        };
        let work = SparseWork::new(n, model.coupling()).map_err(|_| too_large.clone())?;
        let mut kkt = Kkt::new(n, work.step_bandwidth(), rows.clone()).map_err(|_| too_large)?;
        // The rank of `G` at the start: `[∂²L/∂v², Gᵀ; G, 0]` is regular
        // exactly when `G` has full rank (for a regular `∂²L/∂v²`).
        let (_, _, mass) = velocity_derivatives(&model, t0, q0, v0, work.step_bandwidth()).map_err(|_| {
            Error::InvalidInitialData { reason: "∂²L/∂v² could not be evaluated at the initial data" }
        })?;
        match kkt.factor(&mass.band, 1.0, &g0.entries, &g0.entries, newton.min_rcond) {
            Ok(()) => {}
            Err(KktFailure::Constraints(rcond)) => return Err(Error::SingularConstraints { state, rcond }),
            Err(KktFailure::Block(_)) => {
                return Err(Error::InvalidInitialData {
                    reason: "∂²L/∂v² is singular at the initial data: the Legendre transform is not regular",
                });
            }
            Err(KktFailure::NonFinite(_)) => return Err(Error::NonFiniteConstraints { state }),
            Err(KktFailure::Rejected(reason)) => return Err(Error::InvalidInitialData { reason }),
        }
        let g1 = g0.clone();
        let scratch = Scratch {
            dq: vec![0.0; n],
            lambda: vec![0.0; m],
            q1: vec![0.0; n],
            r1: vec![0.0; n],
            r2: vec![0.0; m],
            end: vec![0.0; n],
            v: vec![0.0; n],
            mu: vec![0.0; m],
        };
        Ok(Self {
            system,
            rule,
            points,
            h,
            newton,
            state: PhasePoint { step: 0, t: t0, q: q0.to_vec(), p: p0 },
            velocity: v0.to_vec(),
            lambda: vec![0.0; m],
            last_dq: None,
            energy,
            work: Box::new(work),
            kkt,
            g0,
            g1,
            scratch,
            stats: Stats::default(),
        })
    }

    /// One step of size `h`; on failure nothing has changed (but the count
    /// of failed steps).
    pub fn step(&mut self) -> Result<&PhasePoint, Error> {
        match self.try_step() {
            Ok(()) => Ok(&self.state),
            Err(error) => {
                self.stats.failed_steps += 1;
                Err(error)
            }
        }
    }

    /// `n` steps, calling `observe` after each; stops at the first failure.
    pub fn run(&mut self, n: usize, mut observe: impl FnMut(&Self)) -> Result<&PhasePoint, Error> {
        for _ in 0..n {
            self.step()?;
            observe(self);
        }
        Ok(&self.state)
    }

    fn try_step(&mut self) -> Result<(), Error> {
        let Self { system, points, h, newton, state, velocity, lambda, last_dq, work, kkt, g0, g1, scratch, .. } = self;
        let (h, t0) = (*h, state.t);
        let t1 = t0 + h;
        let n = state.q.len();
        let model = Sliced::new(&*system, *points);
        let fail = |b: Breakdown, iterations: usize| match b {
            Breakdown::Singular(rcond) => Error::SingularJacobian { state: state.clone(), h, iterations, rcond },
            Breakdown::NonFinite(quantity) => Error::NonFinite { state: state.clone(), h, iterations, quantity },
            Breakdown::Rejected(reason) => Error::StepRejected { state: state.clone(), h, iterations, reason },
        };
        let kkt_fail = |f: KktFailure, iterations: usize| match f {
            KktFailure::Block(rcond) => Error::SingularJacobian { state: state.clone(), h, iterations, rcond },
            KktFailure::Constraints(rcond) => Error::SingularConstraints { state: state.clone(), rcond },
            KktFailure::NonFinite(quantity) => Error::NonFinite { state: state.clone(), h, iterations, quantity },
            KktFailure::Rejected(reason) => Error::StepRejected { state: state.clone(), h, iterations, reason },
        };
        let Scratch { dq, lambda: lam, q1, r1, r2, end, v, mu } = scratch;
        let (q0, p0) = (&state.q, &state.p);

        // Positions: (Δq, λ) from p_k + D₁A + G(q_k)ᵀλ = 0, g(q_k + Δq) = 0.
        match last_dq {
            Some(last) => dq.copy_from_slice(last),
            None => dq.iter_mut().zip(velocity.iter()).for_each(|(d, v)| *d = v * h),
        }
        lam.copy_from_slice(lambda);
        let mut iterations = 0;
        let mut converged = false;
        let (mut residual_norm, mut correction_norm) = (f64::INFINITY, f64::INFINITY);
        while iterations < newton.max_iterations {
            iterations += 1;
            let band = work.linearize_step(&model, t0, h, q0, dq, r1).map_err(|b| fail(b, iterations))?;
            for i in 0..n {
                r1[i] += p0[i];
            }
            g0.add_transposed(1.0, lam, r1);
            for i in 0..n {
                q1[i] = q0[i] + dq[i];
            }
            if !g1.evaluate(&*system, t1, q1) {
                return Err(Error::NonFiniteConstraints { state: state.clone() });
            }
            r2.copy_from_slice(&g1.values);
            residual_norm = max_abs(r1).max(max_abs(r2));
            if !residual_norm.is_finite() {
                return Err(fail(Breakdown::NonFinite("residual"), iterations));
            }
            let rcond = if iterations == 1 { newton.min_rcond } else { 0.0 };
            kkt.factor(band, 1.0, &g0.entries, &g1.entries, rcond).map_err(|f| kkt_fail(f, iterations))?;
            kkt.solve(r1, r2).map_err(|f| kkt_fail(f, iterations))?;
            for i in 0..n {
                dq[i] += r1[i];
            }
            for (l, d) in lam.iter_mut().zip(r2.iter()) {
                *l += d;
            }
            correction_norm = max_abs(r1);
            if !correction_norm.is_finite() {
                return Err(fail(Breakdown::NonFinite("correction"), iterations));
            }
            // As the const-size step: no correction below the round-off of
            // `q_k + Δq` is meaningful.
            let floor = 4.0 * f64::EPSILON * max_abs(q1).max(max_abs(q0));
            if correction_norm <= newton.rtol * max_abs(dq) + newton.atol + floor {
                converged = true;
                break;
            }
        }
        if !converged {
            return Err(Error::NewtonDidNotConverge {
                state: state.clone(),
                h,
                iterations,
                residual_norm,
                correction_norm,
            });
        }
        for i in 0..n {
            q1[i] = q0[i] + dq[i];
        }
        if !g1.evaluate(&*system, t1, q1) {
            return Err(Error::NonFiniteConstraints { state: state.clone() });
        }

        // The unconstrained end momentum D₂A = ∂A/∂q_k|_{Δq} − D₁A, with
        // D₁A = −p_k − G(q_k)ᵀλ at the solution.
        let energy = work.momentum_change(&model, t0, h, q0, dq, end).map_err(|b| fail(b, iterations))?;
        for i in 0..n {
            end[i] += p0[i];
        }
        g0.add_transposed(1.0, lam, end);

        // Momenta: (v_{k+1}, μ) from ∂L/∂v(q_{k+1}, v) = D₂A + G(q_{k+1})ᵀμ,
        // G(q_{k+1}) v = 0; one iteration for a quadratic kinetic energy.
        for i in 0..n {
            v[i] = dq[i] / h;
        }
        mu.fill(0.0);
        let mut momentum_iterations = 0;
        let mut momentum_converged = false;
        while momentum_iterations < newton.max_iterations {
            momentum_iterations += 1;
            let spent = iterations + momentum_iterations;
            let (_, p, mass) =
                velocity_derivatives(&model, t1, q1, v, work.step_bandwidth()).map_err(|b| fail(b, spent))?;
            for i in 0..n {
                r1[i] = p[i] - end[i];
            }
            g1.add_transposed(-1.0, mu, r1);
            g1.apply(v, r2);
            // Near a turning point `|v|` is far below `|p̂|`: a residual at
            // round-off ends the iteration too (as in `cotangent.rs`).
            let g_max = max_abs(&g1.entries);
            let p_scale = max_abs(&p).max(max_abs(end)) + g_max * max_abs(mu) * 4.0;
            let v_scale = g_max * max_abs(v) * 4.0;
            if momentum_iterations > 1
                && max_abs(r1) <= 4.0 * f64::EPSILON * p_scale
                && max_abs(r2) <= 4.0 * f64::EPSILON * v_scale
            {
                momentum_converged = true;
                break;
            }
            kkt.factor(&mass.band, -1.0, &g1.entries, &g1.entries, 0.0).map_err(|f| kkt_fail(f, spent))?;
            kkt.solve(r1, r2).map_err(|f| kkt_fail(f, spent))?;
            for i in 0..n {
                v[i] += r1[i];
            }
            for (m, d) in mu.iter_mut().zip(r2.iter()) {
                *m += d;
            }
            let norm = max_abs(r1);
            if !norm.is_finite() {
                return Err(fail(Breakdown::NonFinite("momentum"), spent));
            }
            if norm <= newton.rtol * max_abs(v) + newton.atol {
                momentum_converged = true;
                break;
            }
        }
        if !momentum_converged {
            return Err(Error::NewtonDidNotConverge {
                state: state.clone(),
                h,
                iterations: iterations + momentum_iterations,
                residual_norm: f64::NAN,
                correction_norm: f64::NAN,
            });
        }
        // p_{k+1} = D₂A + G(q_{k+1})ᵀμ, into `end`.
        g1.add_transposed(1.0, mu, end);
        if !all_finite(q1) || !all_finite(end) || !all_finite(v) {
            return Err(fail(Breakdown::NonFinite("position"), iterations));
        }

        // Commit.
        core::mem::swap(&mut state.q, q1);
        core::mem::swap(&mut state.p, end);
        state.t = t1;
        state.step += 1;
        core::mem::swap(velocity, v);
        core::mem::swap(lambda, lam);
        match last_dq {
            Some(last) => last.copy_from_slice(dq),
            None => *last_dq = Some(dq.clone()),
        }
        core::mem::swap(g0, g1);
        self.energy = energy;
        self.stats.steps += 1;
        let total = iterations + momentum_iterations;
        self.stats.newton_iterations += total as u64;
        self.stats.last = NewtonReport { iterations: total, residual_norm, correction_norm };
        Ok(())
    }

    /// The state `(k, t_k, q_k, p_k)`.
    pub fn state(&self) -> &PhasePoint {
        &self.state
    }

    /// The velocity `v_k` of the momentum `p_k` (on the tangent space).
    pub fn velocity(&self) -> &[f64] {
        &self.velocity
    }

    /// The multiplier `λ_k` of the last step (zero before the first).
    pub fn multipliers(&self) -> &[f64] {
        &self.lambda
    }

    /// The constraint values `g(t_k, q_k)` at the current node.
    pub fn constraint_values(&self) -> &[f64] {
        &self.g0.values
    }

    /// The hidden constraint `G(q_k) v_k` at the current node.
    pub fn constraint_velocities(&self) -> Vec<f64> {
        let mut out = vec![0.0; self.g0.values.len()];
        self.g0.apply(&self.velocity, &mut out);
        out
    }

    /// The energy `E = v·∂L/∂v − L` at the current node.
    pub fn energy(&self) -> f64 {
        tape_energy(&Sliced::new(&self.system, self.points), self.state.t, &self.state.q, &self.velocity)
    }

    /// The discrete energy `−∂A/∂t_{k+1}` of the last step (the energy of
    /// the initial data before the first).
    pub fn discrete_energy(&self) -> f64 {
        self.energy
    }

    /// Counters of the steps taken so far.
    pub fn stats(&self) -> &Stats {
        &self.stats
    }

    /// The bandwidth of the interleaved saddle-point matrix: independent of
    /// `N` for a chain.
    pub fn saddle_point_bandwidth(&self) -> usize {
        self.kkt.bandwidth()
    }

    /// The step size.
    pub fn step_size(&self) -> f64 {
        self.h
    }

    /// The discrete Lagrangian.
    pub fn rule(&self) -> &R {
        &self.rule
    }
}

/// The relative distances of `(q, v)` from the manifold and its tangent
/// space, as the const-size integrator measures them.
fn inconsistency(g: &Jacobian, q: &[f64], v: &[f64]) -> (f64, f64) {
    let mut gv = vec![0.0; g.values.len()];
    g.apply(v, &mut gv);
    let (mut position, mut velocity) = (0.0f64, 0.0f64);
    for (r, (&value, &rate)) in g.values.iter().zip(&gv).enumerate() {
        let norm = g.row_norm(r);
        position = position.max(value.abs() / norm);
        velocity = velocity.max(rate.abs() / norm);
    }
    let speed = max_abs(v);
    (position / max_abs(q).max(1.0), if speed > 0.0 { velocity / speed } else { velocity })
}

#[cfg(test)]
mod tests;
