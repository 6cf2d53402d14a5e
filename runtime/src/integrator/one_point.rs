//! The one-point rules (`Midpoint`, `Trapezoid`, `AlphaBeta`, any user
//! [`DiscreteLagrangian`]) as [`Method`]s.
//!
//! In `f64` they take the direct path: the step's only unknown is the
//! increment `dq = q_{k+1} − q_k`, and each Newton iteration is one
//! hyper-dual sweep of the action `A(t_k, h, q_k, dq)` that yields the
//! residual `p_k + ∂A/∂q_k`, the Jacobian `∂²A/∂q_k∂q_{k+1}` and, after
//! convergence, the momentum change. Where the macro wrote gradient code
//! (`Lagrangian::HAS_GRADIENT_QV`, no forces) and the rule is a quadrature
//! of `L` at one or two points, the same quantities come from that code on
//! dual numbers with one lane per coordinate (forward over reverse), which
//! carries `N` derivative components through the operations that depend on
//! `q` and `v` instead of the hyper-dual's `N × N` block through all of them
//! ([`gradient_linearization`]). In any other [`Real`](crate::Real)
//! they run as the Galerkin rule of degree 1 whose quadrature is their own
//! point(s) (`galerkin/one_point.rs`), which is the same discrete Lagrangian.

use std::sync::Arc;

use nalgebra::{SMatrix, SVector};

use super::method::{F64Readouts, Method, sealed};
use super::{
    IMPLAUSIBLE_GROWTH, Integrator, Stats, StepBounds, StepPolicy, Summation, add_increment, implausible_growth,
    non_finite,
};
use crate::dense::{Hermite, Node};
use crate::derivatives::{self, Segment};
use crate::discrete::DiscreteLagrangian;
use crate::error::Error;
use crate::forcing::{self, DiscreteForces, EnergyBalance};
use crate::hyperdual::DualArray;
use crate::mechanics::DiscreteMechanics;
use crate::newton::{self, Jacobian, NewtonFailure, NewtonReport};
use crate::real::{fold_max_abs, is_non_finite, max_abs, nan_bits};
use crate::state::State;
use crate::symplectic::{self, TangentMap};
use crate::system::Lagrangian;

/// What a one-point rule keeps of its last two steps.
#[derive(Debug)]
pub struct OnePointMemory<const N: usize> {
    /// The last step, from node `k − 1` to node `k`; `None` at the start.
    pub(crate) previous: Option<Segment<N>>,
    /// `(h, dq)` of the step before that, for the predictor.
    pub(crate) earlier: Option<(f64, [f64; N])>,
    /// Explicit (Störmer–Verlet) steps: `M⁻¹` of the constant mass matrix
    /// and the force at the current node, made at the first explicit step.
    pub(crate) explicit: Option<Box<ExplicitCache<N>>>,
    /// Reverse-mode steps: the tape, its buffers and the factored matrices
    /// (see [`Derivatives`](crate::Derivatives)); `None` in forward mode.
    pub(crate) sparse: Option<Box<super::tape_step::SparseWork>>,
}

impl<const N: usize> Clone for OnePointMemory<N> {
    fn clone(&self) -> Self {
        Self {
            previous: self.previous,
            earlier: self.earlier,
            explicit: self.explicit.clone(),
            sparse: self.sparse.clone(),
        }
    }

    /// Field by field into the boxes `self` has: reverse mode's work copies
    /// into its own buffers (see `SparseWork::clone_from`) instead of
    /// allocating a tape and buffers at every step of a `solve`.
    fn clone_from(&mut self, source: &Self) {
        let Self { previous, earlier, explicit, sparse } = self;
        *previous = source.previous;
        *earlier = source.earlier;
        explicit.clone_from(&source.explicit);
        sparse.clone_from(&source.sparse);
    }
}

impl<const N: usize> OnePointMemory<N> {
    /// The increment of a step of size `h` predicted from the last two steps
    /// (`v0·h` before the first): see [`predict_into`](super::predict_into).
    #[inline]
    pub(super) fn predict(&self, h: f64, v0: &[f64; N]) -> [f64; N] {
        let mut out = [0.0; N];
        let last = self.previous.as_ref().map(|last| (last.h, &last.dq[..]));
        let earlier = self.earlier.as_ref().map(|(h, dq)| (*h, &dq[..]));
        super::predict_into(h, last, earlier, v0, &mut out);
        out
    }
}

impl<M: DiscreteLagrangian> sealed::Sealed for M {}

impl<M: DiscreteLagrangian> Method<f64> for M {
    type Memory<const N: usize> = OnePointMemory<N>;

    fn method_order(&self) -> u32 {
        self.order()
    }

    fn memory<const N: usize>(&self) -> OnePointMemory<N> {
        OnePointMemory { previous: None, earlier: None, explicit: None, sparse: None }
    }

    fn legendre<S: Lagrangian<N>, const N: usize>(
        system: &S,
        t0: f64,
        q0: [f64; N],
        v0: [f64; N],
    ) -> Result<([f64; N], f64), Error> {
        // `if const`: codegen can skip the forward-mode code below for large N.
        if const { super::sparse::too_large_for_forward(N) } {
            return super::sparse::legendre(system, t0, q0, v0);
        }
        let (p0, energy, ()) = checked_start(system, t0, q0, v0, v0, |m| m.try_inverse().map(|_| ()))?;
        Ok((p0, energy))
    }

    fn start_memory<S: Lagrangian<N>, const N: usize>(
        &self,
        system: &S,
        t0: f64,
        q0: [f64; N],
        v0: [f64; N],
        memory: &mut OnePointMemory<N>,
    ) -> Result<([f64; N], f64), Error> {
        // Explicit steps: the regularity check's `M⁻¹` is the one the first
        // step needs (the mass matrix is constant), formed and inverted once
        // for both (on the FPU-β chain of 16 masses the matrix and its
        // inverse are most of an integrator's start).
        if const { !Integrator::<S, M, N>::EXPLICIT || super::sparse::too_large_for_forward(N) } {
            return Self::legendre(system, t0, q0, v0);
        }
        let (p0, energy, cache) = checked_start(system, t0, q0, v0, [0.0; N], explicit_cache_of)?;
        memory.explicit = Some(cache);
        Ok((p0, energy))
    }

    fn prefers_reverse<S: Lagrangian<N>, const N: usize>(&self, policy: &StepPolicy) -> bool {
        // The explicit path is cheap in forward mode up to `FORWARD_MAX_N`.
        let explicit = M::EXPLICIT_FOR_CONSTANT_MASS
            && S::SEPARABILITY.has_constant_mass()
            && !S::HAS_FORCE
            && !S::HAS_DISSIPATION;
        N >= super::Derivatives::REVERSE_MIN_N && !explicit && super::sparse::unsupported::<S, N>(policy).is_none()
    }

    fn supports_derivatives<S: Lagrangian<N>, const N: usize>(
        &self,
        reverse: bool,
        policy: &StepPolicy,
    ) -> Result<(), Error> {
        match super::sparse::unsupported::<S, N>(policy) {
            Some(what) if reverse => Err(Error::Unsupported { what }),
            _ => Ok(()),
        }
    }

    #[inline(always)]
    fn fixed_step<S: Lagrangian<N>, const N: usize>(
        it: &mut Integrator<S, Self, N>,
        h: f64,
        t1: f64,
    ) -> Result<(), Error> {
        it.step_by(h, t1)
    }

    fn energy_step<S: Lagrangian<N>, const N: usize>(
        it: &mut Integrator<S, Self, N>,
        bounds: StepBounds,
    ) -> Result<(), Error> {
        if const { super::sparse::too_large_for_forward(N) } {
            return Err(Error::Unsupported { what: "energy-preserving steps with reverse-mode derivatives" });
        }
        // `start` refuses the policy for these systems: no energy-step code
        // is compiled for them.
        if const { !S::ENERGY_STEPS } {
            return Err(Error::Unsupported { what: super::NO_ENERGY_STEPS });
        }
        if it.memory.previous.is_some() {
            return it.energy_step(bounds).map(|_| ());
        }
        // The first step has the given h0 (Luo, Guo, Li & Wu §V starts from τ0):
        // E_L(q0, v0) is not the discrete energy of any step, and
        // demanding E_1 = E_L(q0, v0) has no root but h → 0. The energy
        // conserved from then on is the discrete E_1, within O(h0²) of E_L.
        let h = it.h;
        it.step_by(h, it.state.t + h)?;
        Self::reread_energy(it);
        Ok(())
    }

    fn reread_energy<S: Lagrangian<N>, const N: usize>(it: &mut Integrator<S, Self, N>) {
        if const { super::sparse::too_large_for_forward(N) || !S::ENERGY_STEPS } {
            // Only energy-preserving steps reread the energy; refused here.
            return;
        }
        it.energy_carry = 0.0;
        if let Some(last) = &it.memory.previous {
            it.energy = -derivatives::end_time_derivative(&it.system, &it.method, last);
        }
    }

    fn last_step_size<const N: usize>(memory: &OnePointMemory<N>) -> Option<f64> {
        memory.previous.map(|last| last.h)
    }

    fn discrete_energy<S: Lagrangian<N>, const N: usize>(it: &Integrator<S, Self, N>) -> f64 {
        if const { super::sparse::too_large_for_forward(N) } {
            return it.sparse_discrete_energy();
        }
        if it.reverse() {
            return it.sparse_discrete_energy();
        }
        match &it.memory.previous {
            Some(seg) => -derivatives::end_time_derivative(&it.system, &it.method, seg),
            None => it.system.energy(it.state.t, it.state.q, it.v0),
        }
    }
}

impl<M: DiscreteLagrangian> F64Readouts for M {
    fn velocity_guess<S: Lagrangian<N>, const N: usize>(it: &Integrator<S, Self, N>) -> [f64; N] {
        match &it.memory.previous {
            Some(last) => last.dq.map(|x| x / last.h),
            None => it.v0,
        }
    }

    fn constant_mass_velocity<S: Lagrangian<N>, const N: usize>(it: &Integrator<S, Self, N>) -> Option<[f64; N]> {
        let mut v = [0.0; N];
        it.memory.sparse.as_ref()?.constant_mass_velocity(&it.state.p, &mut v).then_some(v)
    }

    fn tangent_map<S: Lagrangian<N>, const N: usize>(it: &Integrator<S, Self, N>) -> Option<TangentMap<N>> {
        // A dense 2N × 2N matrix: not offered at the sizes reverse mode serves.
        if const { super::sparse::too_large_for_forward(N) } {
            return None;
        }
        if it.reverse() {
            return None;
        }
        symplectic::tangent_map(&it.system, &it.method, it.memory.previous.as_ref()?)
    }

    fn forcing_impulse<S: Lagrangian<N>, const N: usize>(
        it: &Integrator<S, Self, N>,
        symmetry: &(impl crate::noether::Generator<N> + ?Sized),
    ) -> Option<f64> {
        // Reverse mode refuses forces at `start`: no impulse.
        if const { super::sparse::too_large_for_forward(N) } {
            return it.memory.previous.map(|_| 0.0);
        }
        if it.reverse() {
            return it.memory.previous.map(|_| 0.0);
        }
        Some(crate::noether::forcing_impulse(&it.system, &it.method, it.memory.previous.as_ref()?, symmetry))
    }

    /// A one-point step is a straight line in `q`: dense output is the cubic
    /// Hermite through both nodes.
    type Native<const N: usize> = Hermite<N>;

    fn native<S: Lagrangian<N>, const N: usize>(
        _: &Integrator<S, Self, N>,
        start: &Node<N>,
        end: &Node<N>,
    ) -> Hermite<N> {
        Hermite::cubic(start, end)
    }
}

impl<S: Lagrangian<N>, M: DiscreteLagrangian, const N: usize> Integrator<S, M, N> {
    /// One step of size `h`, whose end node is stamped with time `t1`
    /// (`t_k + h` up to the round-off the clock avoids accumulating).
    #[inline]
    pub(super) fn step_by(&mut self, h: f64, t1: f64) -> Result<(), Error> {
        if const { super::sparse::too_large_for_forward(N) } || self.reverse() {
            return self.sparse_step(h, t1, Self::EXPLICIT);
        }
        if const { Self::EXPLICIT } {
            return match self.summation {
                Summation::Compensated => self.verlet_step::<false>(h, t1),
                Summation::Plain => self.verlet_step::<true>(h, t1),
            };
        }
        let State { step, t: t0, q: q0, .. } = self.state;
        let (dq, report, impulse, lagrangian) =
            self.solve_del_with_impulse(h).map_err(|failure| self.fail(h, failure))?;
        let seg = Segment { t0, h, q0, dq };
        let (q1, p1, carry, p_carry) = self.advance(&seg, impulse);
        // `L` at the rule's points of an iterate near the solution `dq`
        // (see `solve_del_with_impulse`): Newton's evaluation there computed
        // it on the way to the residual, so the check costs no evaluation of
        // its own.
        let quantity = if lagrangian.is_finite() { non_finite(t1, &q1, &p1) } else { Some("lagrangian") };
        if let Some(quantity) = quantity {
            self.stats.failed_steps += 1;
            return Err(Error::NonFinite { state: self.state.into(), h, iterations: report.iterations, quantity });
        }
        self.carry = carry;
        self.p_carry = p_carry;
        if S::DISCONTINUOUS {
            self.watch_energy(&seg, t1);
        }
        self.memory.earlier = self.memory.previous.map(|last| (last.h, last.dq));
        self.memory.previous = Some(seg);
        self.state = State { step: step + 1, t: t1, q: q1, p: p1 };
        self.stats.steps += 1;
        self.stats.newton_iterations += report.iterations as u64;
        self.stats.last = report;
        Ok(())
    }

    /// The rule's DEL is explicit for this system (see
    /// [`DiscreteLagrangian::EXPLICIT_FOR_CONSTANT_MASS`]): the macro proved
    /// `L = ½ vᵀMv − V(t, q)` with constant `M`, and there are no forces.
    pub(super) const EXPLICIT: bool =
        M::EXPLICIT_FOR_CONSTANT_MASS && S::SEPARABILITY.has_constant_mass() && !S::HAS_FORCE && !S::HAS_DISSIPATION;

    /// One step of the trapezoid rule on `L = ½ vᵀMv − V(t, q)` with constant
    /// `M`, where its DEL is explicit (Störmer–Verlet, velocity form):
    ///
    /// ```text
    /// q_{k+1} = q_k + h M⁻¹ (p_k + (h/2) f_k),   p_{k+1} = p_k + (h/2)(f_k + f_{k+1}),   f = −∇V
    /// ```
    ///
    /// No Newton iteration (`Stats` counts none); the same Kahan sums, checks
    /// and failure semantics as the Newton path, whose trajectories it
    /// reproduces to round-off. The one-stage case of [`explicit_step`],
    /// written out: one pass over the coordinates for the kick, drift and
    /// position sum, one for the force and one for the momentum sum; the
    /// state is written once, after the checks. `PLAIN`
    /// ([`Summation::Plain`]): `q_k + Δq` and `p_k + Δp` rounded once, the
    /// compensations (zero) neither read nor written.
    #[inline]
    fn verlet_step<const PLAIN: bool>(&mut self, h: f64, t1: f64) -> Result<(), Error> {
        // One stage written out rather than run through `explicit_step`'s
        // sub-step loop: measured 39.6 against 48.1 ns per Kepler step
        // (`--bench step -- explicit`, one run each, load ≈ 3.5).
        let (step, t0) = (self.state.step, self.state.t);
        let cache = match explicit_cache(&self.system, &mut self.memory.explicit, t0, &self.state.q) {
            Ok(cache) => cache,
            Err(failure) => return Err(self.fail(h, failure)),
        };
        cache.node_force(&self.system, step, t0, &self.state.q);
        let (q0, p0, qc0, pc0) = (&self.state.q, &self.state.p, &self.carry, &self.p_carry);
        let half = 0.5 * h;
        let f0 = &cache.forces[usize::from(step % 2 == 1)];
        let (mut dq, mut q1, mut qc1) = ([0.0; N], [0.0; N], [0.0; N]);
        let mut bad = 0;
        // The drift `x = dq[j]` and the Kahan sum of `q_{k+1}`, in the same
        // pass as the kick where `M⁻¹` is diagonal.
        let mut drift = |j: usize, x: f64| {
            dq[j] = x;
            if PLAIN {
                q1[j] = q0[j] + x;
            } else {
                let u = qc0[j] + x;
                q1[j] = q0[j] + u;
                qc1[j] = u - (q1[j] - q0[j]);
            }
            bad |= nan_bits(q1[j]);
        };
        // The drift's momentum `(p_k + (h/2) f_k) + c_p`.
        let momentum = |j: usize| if PLAIN { p0[j] + half * f0[j] } else { (p0[j] + half * f0[j]) + pc0[j] };
        // A diagonal `M⁻¹` skips the products with its zeros, which add
        // exact zeros (only the sign of a zero increment can differ).
        match &cache.diagonal {
            Some(_) if cache.unit => {
                for j in 0..N {
                    drift(j, momentum(j) * h);
                }
            }
            Some(d) => {
                for j in 0..N {
                    drift(j, (d[j] * momentum(j)) * h);
                }
            }
            None => {
                let mut mv = [0.0; N];
                for j in 0..N {
                    mv[j] = momentum(j);
                }
                // By reference: by value the `N × N` matrix would be copied.
                #[allow(clippy::op_ref)]
                let v: [f64; N] = (&*cache.inverse_mass * SVector::from(mv) * h).into();
                for j in 0..N {
                    drift(j, v[j]);
                }
            }
        }
        let dq_max = fold_max_abs(&dq);
        if let Some(last) = &self.memory.previous
            && !explicit_growth_ruled_out(dq_max, fold_max_abs(q0), h, last.h, &last.dq)
        {
            let mut predicted = [0.0; N];
            let earlier = self.memory.earlier.as_ref().map(|(h, dq)| (*h, &dq[..]));
            super::predict_into(h, Some((last.h, &last.dq[..])), earlier, &self.v0, &mut predicted);
            if implausible_growth(&dq, &predicted, &last.dq.map(|x| x * (h / last.h)), q0) {
                let reason = IMPLAUSIBLE_GROWTH;
                return Err(self.fail(h, NewtonFailure::Rejected { iterations: 0, reason }));
            }
        }
        let (f0, f1) = cache.forces_at(step);
        let l1 = potential_force(&self.system, t1, &q1, f1);
        let (mut p1, mut pc1) = ([0.0; N], [0.0; N]);
        for j in 0..N {
            if PLAIN {
                p1[j] = p0[j] + half * (f0[j] + f1[j]);
            } else {
                let u = pc0[j] + half * (f0[j] + f1[j]);
                p1[j] = p0[j] + u;
                pc1[j] = u - (p1[j] - p0[j]);
            }
            bad |= nan_bits(p1[j]);
        }
        if is_non_finite(bad | nan_bits(t1) | nan_bits(l1)) {
            let quantity = non_finite(t1, &q1, &p1).unwrap_or("lagrangian");
            self.stats.failed_steps += 1;
            return Err(Error::NonFinite { state: self.state.into(), h, iterations: 0, quantity });
        }
        if S::DISCONTINUOUS {
            self.watch_energy(&Segment { t0, h, q0: *q0, dq }, t1);
        }
        let taken = ExplicitStep { dq, q1, carry: qc1, p1, p_carry: pc1 };
        commit_explicit(
            &mut self.memory,
            (&mut self.state, &mut self.carry, &mut self.p_carry, &mut self.stats),
            h,
            t1,
            &taken,
        );
        Ok(())
    }

    /// `(q_{k+1}, p_{k+1})` after the solved step `seg`, each the Kahan sum of
    /// the node's value and the step's increment: `q_{k+1} = q_k + Δq`,
    /// `p_{k+1} = p_k + Δp` with `Δp = ∂A/∂q_k + ∂A/∂q_{k+1} + F_k^− + F_k^+`
    /// taken at fixed increment. Summed this way the rounding of the nodes
    /// does not accumulate (it is carried into the next sum), so a moving
    /// centre of mass or large coordinates do not bias the energy or the
    /// momenta. `impulse`: the momentum change when Newton's last
    /// linearisation already gave it ([`Impulse`]); evaluated otherwise.
    /// Returns the new compensations too; changes nothing.
    #[inline]
    pub(super) fn advance(
        &self,
        seg: &Segment<N>,
        impulse: Option<[f64; N]>,
    ) -> ([f64; N], [f64; N], [f64; N], [f64; N]) {
        let dp = match (impulse, self.gradient_points()) {
            (Some(dp), _) => dp,
            (None, Some(points)) => gradient_momentum_change(&self.system, points, seg),
            (None, None) => forcing::momentum_change(&self.system, &self.method, seg),
        };
        let (q1, q) = add_increment(self.summation, &self.state.q, &self.carry, &seg.dq);
        let (p1, p) = add_increment(self.summation, &self.state.p, &self.p_carry, &dp);
        (q1, p1, q, p)
    }

    /// Records the relative change of the discrete energy across the node
    /// between the last step and `seg` (see [`Stats::largest_energy_jump`](crate::Stats::largest_energy_jump)).
    pub(super) fn watch_energy(&mut self, seg: &Segment<N>, t1: f64) {
        let after = -derivatives::end_time_derivative(&self.system, &self.method, seg);
        // The last step's energy was this function's `after` one step ago.
        let before = self.watched_energy.unwrap_or_else(|| self.system.energy(self.state.t, self.state.q, self.v0));
        self.watched_energy = Some(after);
        let jump = (after - before).abs() / before.abs().max(f64::MIN_POSITIVE);
        if jump.is_finite() && jump > self.stats.largest_energy_jump {
            self.stats.largest_energy_jump = jump;
            self.stats.largest_energy_jump_at = t1;
        }
    }

    /// Solves the DEL `p_k + ∂A/∂q_k = 0` for the increment `dq = q_{k+1} − q_k`
    /// of a step of size `h` (see `Segment` for why the increment). The
    /// failure is the solve's alone: the caller that gives up on the step
    /// makes it the step's [`Error`] (an energy step's search may recover).
    #[inline]
    pub(super) fn solve_del(&mut self, h: f64) -> Result<([f64; N], NewtonReport), NewtonFailure> {
        self.solve_del_with_impulse(h).map(|(dq, report, _, _)| (dq, report))
    }

    /// [`solve_del`](Self::solve_del), the step's momentum change
    /// `Σ_j w h L_q(q_j)` at the solution where Newton's last linearisation
    /// gives it ([`Impulse`]), and a number that is finite exactly where `L`
    /// is finite at the rule's points of an iterate near the solution (up
    /// to overflow of a sum of finite values; see [`Impulse::lagrangian`]):
    /// the last one, or from gradient code the last fresh linearisation's,
    /// within `2·KEEP_BELOW·‖Δq‖` of it. Not the returned increment itself:
    /// where `L` stops being finite closer to the solution than that, the
    /// step is taken.
    // Always inlined: with more than one caller in a program (the step, the
    // landing step, `Problem`'s dispatch) the inliner keeps it out of line,
    // and the pendulum's midpoint step then costs 530 instructions against
    // 446 inlined (callgrind, `examples/step_profile.rs`).
    #[inline(always)]
    #[allow(clippy::type_complexity)]
    pub(super) fn solve_del_with_impulse(
        &mut self,
        h: f64,
    ) -> Result<([f64; N], NewtonReport, Option<[f64; N]>, f64), NewtonFailure> {
        let State { q: q0, p: p0, .. } = self.state;
        let predictor = self.predict(h);
        let p_scale = max_abs(&p0);
        // Newton's rounding floor for the increment: that of the positions.
        let q_floor = 4.0 * f64::EPSILON * max_abs(&q0);
        // The condition estimate on the first iteration only (see
        // `newton::square_correction_unestimated`); the inverse Jacobian is
        // kept for the iterations Newton lets keep it.
        let mut first = true;
        let mut inverse = None;
        let mut impulse = Impulse::new();
        let eval = |x: &SVector<f64, N>, jacobian: Jacobian| {
            let estimate = core::mem::replace(&mut first, false);
            if jacobian == Jacobian::Fresh {
                inverse = None;
            }
            self.del_linearization(h, (*x).into(), p_scale, estimate, &mut inverse, &mut impulse)
                .map(|step| step.floor(q_floor))
        };
        match newton::solve(SVector::from(predictor), &self.newton, eval) {
            Ok((dq, report)) => {
                let dq: [f64; N] = dq.into();
                if let Some(last) = &self.memory.previous
                    && !last_rules_out_growth(&dq, &last.dq, (h / last.h).abs())
                    && implausible_growth(&dq, &predictor, &last.dq.map(|x| x * (h / last.h)), &q0)
                {
                    let reason = IMPLAUSIBLE_GROWTH;
                    return Err(NewtonFailure::Rejected { iterations: report.iterations, reason });
                }
                Ok((dq, report, impulse.at_solution(&dq, p_scale), impulse.lagrangian))
            }
            Err(failure) => Err(failure),
        }
    }

    /// The Newton correction of the DEL `p_k + ∂A/∂q_k = 0` at the increment
    /// `dq` of a step of size `h` (forces included: Lagrange–d'Alembert puts
    /// `F_k^−` into `∂A/∂q_k` and `∂F_k^−/∂q_{k+1}` into the Jacobian), its
    /// residual measured against the terms that cancel (`p_scale` = `max|p_k|`).
    /// `estimate`: estimate the Jacobian's condition number too. With an
    /// `inverse` Jacobian kept from an earlier iterate, the correction is made
    /// with it (simplified Newton: see [`Jacobian::Kept`]), and from the
    /// macro's gradient code only the residual is evaluated; without one, the
    /// inverse made here is left in it. From the gradient code, the impulse
    /// at `dq` and the correction made there are left in `impulse`, and
    /// `L` at the rule's points ([`Impulse::lagrangian`]) from every path
    /// but the gradient code's residual beside a kept inverse.
    #[inline(always)]
    pub(super) fn del_linearization(
        &self,
        h: f64,
        dq: [f64; N],
        p_scale: f64,
        estimate: bool,
        inverse: &mut Option<SMatrix<f64, N, N>>,
        impulse: &mut Impulse<N>,
    ) -> Result<newton::Linearization<SVector<f64, N>>, newton::Breakdown> {
        let State { t: t0, q: q0, .. } = self.state;
        let (system, method) = (&self.system, &self.method);
        let seg = Segment { t0, h, q0, dq };
        // Beside a kept inverse the residual alone is evaluated where that is
        // cheaper, and the Jacobian is a zero that is not used.
        let (d_q0, jacobian) = match (self.gradient_points(), &*inverse) {
            // In `f64`: no dual lanes, and the correction does not wait for
            // `1/J` (a shorter chain of dependent operations from one iterate
            // to the next).
            // `L` is not evaluated here: its value would cost the
            // transcendental functions whose derivatives the residual does
            // not need (`cos` beside `sin`); the last fresh iterate's stays.
            (Some(points), Some(_)) => {
                let (d_q0, dp) = gradient_residual(system, points, &seg);
                impulse.evaluated(dp, None);
                (d_q0, SMatrix::zeros())
            }
            // Without gradient code: first derivatives on `N` dual lanes
            // instead of the hyper-dual sweep's `N² + 2N` (forces keep the
            // full evaluation, which adds theirs).
            (None, Some(_)) if !forcing::is_forced::<S, N>() => {
                let (d_q0, action) = derivatives::start_gradient(system, method, &seg);
                impulse.lagrangian = action;
                (d_q0, SMatrix::zeros())
            }
            (Some(points), None) => {
                // `I'` only where the impulse is linearised.
                let mut slope = Impulse::<N>::LINEARISED.then(SMatrix::zeros);
                let (d_q0, jacobian, dp, lagrangian) = gradient_linearization(system, points, &seg, slope.as_mut());
                impulse.evaluated(dp, slope);
                impulse.lagrangian = lagrangian;
                (d_q0, jacobian)
            }
            (None, _) => {
                let d = forcing::with_forces(system, method, &seg, derivatives::step_derivatives(system, method, &seg));
                impulse.lagrangian = d.action;
                (d.d_q0, d.d2_q0_q1)
            }
        };
        let r = self.del_residual(&d_q0);
        let scale = p_scale.max(max_abs(&d_q0));
        let step = match inverse.as_ref() {
            Some(kept) => newton::kept_correction(r, kept)?,
            None => {
                let (step, inv) = if estimate {
                    newton::square_correction(r, jacobian, self.newton.min_rcond)?
                } else {
                    newton::square_correction_unestimated(r, jacobian)?
                };
                *inverse = Some(inv);
                step
            }
        };
        if Impulse::<N>::LINEARISED {
            impulse.correction = step.correction.into();
        }
        Ok(step.cancelling(scale))
    }

    /// The DEL residual `p_k + ∂A/∂q_k` from `d_q0 = ∂A/∂q_k`. The momentum
    /// carries its compensation: `p_k` is `p0 + pc` (zero, and not added,
    /// under plain summation: one addition fewer on the chain from one
    /// iterate to the next).
    #[inline(always)]
    fn del_residual(&self, d_q0: &[f64; N]) -> SVector<f64, N> {
        let (p0, pc) = (&self.state.p, &self.p_carry);
        match self.summation {
            Summation::Compensated => SVector::from_fn(|i, _| (p0[i] + d_q0[i]) + pc[i]),
            Summation::Plain => SVector::from_fn(|i, _| p0[i] + d_q0[i]),
        }
    }

    /// The rule's quadrature points `c_j` when its Newton steps take their
    /// derivatives from the macro's gradient code: a rule of the form
    /// `A = h Σ_j w L(t_k + c_j h, q_k + c_j Δq, Δq/h)` (midpoint,
    /// trapezoid, α-β) on a system with `gradient_qv` and without forces.
    #[inline(always)]
    fn gradient_points(&self) -> Option<[f64; 2]> {
        if S::HAS_GRADIENT_QV && !forcing::is_forced::<S, N>() {
            self.method.galerkin_points().map(|(points, _)| points)
        } else {
            None
        }
    }

    /// The increment predicted by quadratic extrapolation of the positions:
    /// the secant velocities `dq/h` of the last two steps, placed at their
    /// midpoints, extrapolated linearly to the midpoint of the new step. Its
    /// error is `O(h³)`, so Newton usually converges in two iterations.
    #[inline]
    pub(super) fn predict(&self, h: f64) -> [f64; N] {
        self.memory.predict(h, &self.v0)
    }

    /// The last step as a segment `(t_k, h, q_k, dq)`: its increment `dq` is
    /// the one Newton solved for, free of the rounding of `q_{k+1} = q_k + dq`
    /// (which, when every step rounds the same way, adds up over long runs).
    /// `None` before the first step.
    pub fn last_step(&self) -> Option<&Segment<N>> {
        self.memory.previous.as_ref()
    }

    /// The discrete forces `(F_k^−, F_k^+)` of the last step (docs/theory.md §6), or
    /// `None` before the first step; zero for a system without forces.
    pub fn last_forces(&self) -> Option<DiscreteForces<N>> {
        // Reverse mode refuses forces at `start`.
        if const { super::sparse::too_large_for_forward(N) } {
            return self.memory.previous.map(|_| DiscreteForces { minus: [0.0; N], plus: [0.0; N] });
        }
        if self.reverse() {
            return self.memory.previous.map(|_| DiscreteForces { minus: [0.0; N], plus: [0.0; N] });
        }
        Some(forcing::discrete_forces(&self.system, &self.method, self.memory.previous.as_ref()?))
    }

    /// The energy balance `E_{k+1} − E_k − W_k` across node `k`, the node
    /// between the last two steps (see [`forcing`](crate::forcing) for `W_k`
    /// and when the balance is exact), or `None` before the second step and
    /// in reverse mode ([`Derivatives`](crate::Derivatives)).
    ///
    /// The step before the last is rebuilt from the last one and its stored
    /// increment, so its start point carries the round-off of one subtraction.
    pub fn energy_balance(&self) -> Option<EnergyBalance> {
        // Not offered in reverse mode (no forces there: the balance is the
        // conservation of the discrete energy).
        if const { super::sparse::too_large_for_forward(N) } {
            return None;
        }
        if self.reverse() {
            return None;
        }
        let ahead = self.memory.previous.as_ref()?;
        let (h, dq) = self.memory.earlier?;
        let behind = Segment { t0: ahead.t0 - h, h, q0: core::array::from_fn(|i| ahead.q0[i] - dq[i]), dq };
        Some(forcing::energy_balance(&self.system, &self.method, &behind, ahead))
    }
}

/// Whether the action of the solved step `seg`, `L` at the rule's points
/// (in `f64`), is finite. Its derivatives can be finite where `L` is not
/// (`L = ln(1 − q)` past `q = 1` has a finite derivative on the wrong
/// branch): the step is only valid where the action itself is.
#[inline(always)]
pub(super) fn action_finite<S: Lagrangian<N>, M: DiscreteLagrangian, const N: usize>(
    system: &S,
    method: &M,
    seg: &Segment<N>,
) -> bool {
    method.fixed_step_action::<S, f64, N>(system, seg.t0, seg.h, seg.q0, seg.dq).is_finite()
}

/// `true` when the last increment `last_dq`, scaled by `ratio = |h/h_last|`
/// (sub-steps of a composition can be negative),
/// already shows that the increment `dq` is no implausible growth: then
/// [`implausible_growth`] is `false` whatever the prediction (its scale is at
/// least the scaled last increment, and rounding is monotone, so
/// `max|x·r| = max|x|·|r|` exactly), and the common case skips the predictor.
#[inline(always)]
fn last_rules_out_growth<const N: usize>(dq: &[f64; N], last_dq: &[f64; N], ratio: f64) -> bool {
    growth_ruled_out(max_abs(dq), last_dq, ratio)
}

/// [`last_rules_out_growth`] from `dq_max = max|dq|`.
#[inline(always)]
fn growth_ruled_out(dq_max: f64, last_dq: &[f64], ratio: f64) -> bool {
    dq_max <= 1e6 * (fold_max_abs(last_dq) * ratio)
}

/// `true` when an explicit step's increment `dq` (`dq_max = max|dq|`) from
/// `q` (`q_max = max|q|`), with the last step `(h_last, last_dq)`, is
/// certainly no [`implausible_growth`], so that the predictor is not needed.
/// First the bound of the position alone: the check's threshold is
/// `1e6·max(scale, 1e-6·max|q|)`, at least `1e6·(1e-6·max|q|)` as computed
/// (rounding is monotone), so an increment below that passes whatever the
/// scale (every step of motion away from the origin; no division). Then
/// [`last_rules_out_growth`]'s bound of the scaled last increment. Either
/// way the verdict is the full check's.
#[inline(always)]
fn explicit_growth_ruled_out(dq_max: f64, q_max: f64, h: f64, h_last: f64, last_dq: &[f64]) -> bool {
    dq_max <= 1e6 * (1e-6 * q_max) || growth_ruled_out(dq_max, last_dq, (h / h_last).abs())
}

/// `f(t, q) = ∂L/∂q(t, q, 0) = −∇V(t, q)` for a separable `L`, into `out`,
/// returning `L(t, q, 0) = −V(t, q)`: the adjoint code `#[lagrangian]` wrote
/// out where it could ([`Lagrangian::HAS_GRADIENT`]; it clears `out`
/// itself, and its forward sweep computes the value), else one first-order
/// array-dual evaluation. With the value of the start node, checked by the
/// step before (or at `start`), a finite value here makes the trapezoid
/// action `h/2 (L_k + L_{k+1})` finite, whose derivatives can be finite where
/// it is not.
#[inline(always)]
fn potential_force<S: Lagrangian<N>, const N: usize>(system: &S, t: f64, q: &[f64; N], out: &mut [f64; N]) -> f64 {
    use crate::hyperdual::DualArray;
    if S::HAS_GRADIENT {
        return system.value_gradient_q(t, q, const { &[0.0; N] }, out);
    }
    let qd: [DualArray<[f64; N]>; N] = core::array::from_fn(|i| DualArray::variable(q[i], i));
    let l = system.lagrangian(DualArray::from_re(t), qd, [DualArray::from_re(0.0); N]);
    *out = l.eps;
    l.re
}

/// What the explicit steps keep for the whole run, on the heap (at the sizes
/// reverse mode serves an inline `N × N` matrix would not fit on a thread's
/// stack): `M⁻¹` of the constant mass matrix, and the force at the current
/// node, computed by the step that reached it.
#[derive(Clone, Debug)]
pub(crate) struct ExplicitCache<const N: usize> {
    /// Shared, not copied, by a clone of the integrator: it never changes
    /// after the first explicit step, and a copy of the cache by value
    /// passes through the stack (the frame of every clone of an integrator
    /// holds room for one, taken or not: 8 MB at `N = 1000`).
    pub(crate) inverse_mass: Arc<SMatrix<f64, N, N>>,
    /// The diagonal of `M⁻¹` when `M⁻¹` is diagonal (a product with `N`
    /// entries instead of `N²`).
    pub(crate) diagonal: Option<[f64; N]>,
    /// Whether that diagonal is all ones (`M = I`, as in most particle
    /// systems): the drift then skips the product with it, which is exact
    /// and one multiplication shorter on the path from one force to the next.
    pub(crate) unit: bool,
    /// Two force buffers, `forces[k % 2]` for node `k`: a step writes the
    /// force at its end node into the one its start node's force is not in,
    /// so a failed step leaves that force intact and a successful one moves
    /// nothing.
    forces: [[f64; N]; 2],
    /// `k + 1` when `forces[k % 2]` holds `f(t_k, q_k)` for the current node
    /// `k`, `0` when no buffer does.
    node: u64,
}

impl<const N: usize> ExplicitCache<N> {
    /// Makes sure `forces[step % 2]` holds `f(t_k, q_k)` at node `step`.
    #[inline(always)]
    fn node_force<S: Lagrangian<N>>(&mut self, system: &S, step: u64, t: f64, q: &[f64; N]) {
        if self.node != step.wrapping_add(1) {
            // The node's `L` was checked by the step that reached it.
            potential_force(system, t, q, &mut self.forces[usize::from(step % 2 == 1)]);
            self.node = step.wrapping_add(1);
        }
    }

    /// The force at node `step` and the buffer for the next node's.
    #[inline(always)]
    fn forces_at(&mut self, step: u64) -> (&[f64; N], &mut [f64; N]) {
        split_forces(&mut self.forces, step)
    }

    /// The end node's force, written by the step that reached node `step`,
    /// is now the node force.
    #[inline(always)]
    fn advance(&mut self, step: u64) {
        self.node = step.wrapping_add(1);
    }

    /// The node force is unknown (the next step recomputes it, to the same
    /// bits).
    pub(crate) fn forget(&mut self) {
        self.node = 0;
    }

    /// The force at node `from` is the force at node `to` (a composed step's
    /// last sub-node is its end node).
    pub(crate) fn rekey(&mut self, from: u64, to: u64) {
        if self.node != from.wrapping_add(1) {
            self.node = 0;
            return;
        }
        if from % 2 != to % 2 {
            self.forces.swap(0, 1);
        }
        self.node = to.wrapping_add(1);
    }
}

/// The force buffer of node `step` in `forces`, and the other one.
#[inline(always)]
fn split_forces<const N: usize>(forces: &mut [[f64; N]; 2], step: u64) -> (&[f64; N], &mut [f64; N]) {
    let [a, b] = forces;
    if step % 2 == 1 { (b, a) } else { (a, b) }
}

/// The explicit steps' cache of a constant-mass system, made at the first
/// explicit step: `M⁻¹` (and its diagonal, when it is one); a singular `M`
/// is a typed failure.
// Always inlined, with the making of the cache out of line: that path
// allocates (the box, the shared `M⁻¹`), and inlined into every explicit
// step it made the whole function too large to inline, which cost a
// Kepler step 192 instructions against 166 (callgrind,
// `examples/step_profile.rs kepler trapezoid`).
#[inline(always)]
fn explicit_cache<'a, S: Lagrangian<N>, const N: usize>(
    system: &S,
    cache: &'a mut Option<Box<ExplicitCache<N>>>,
    t0: f64,
    q0: &[f64; N],
) -> Result<&'a mut ExplicitCache<N>, NewtonFailure> {
    match cache {
        Some(cache) => Ok(cache),
        empty @ None => Ok(empty.insert(new_explicit_cache(system, t0, q0)?)),
    }
}

/// The forward-mode checks of the initial data, in order: `p0` and `L`
/// finite, `∂²L/∂v²` (taken at velocity `at`) finite and accepted by
/// `regular` (which returns what it keeps of it, `None` when it is
/// singular), the energy finite. Returns `(p0, E0, kept)`.
fn checked_start<S: Lagrangian<N>, const N: usize, X>(
    system: &S,
    t0: f64,
    q0: [f64; N],
    v0: [f64; N],
    at: [f64; N],
    regular: impl FnOnce(SMatrix<f64, N, N>) -> Option<X>,
) -> Result<([f64; N], f64, X), Error> {
    let p0 = system.momentum(t0, q0, v0);
    if !crate::real::all_finite(&p0) || !system.lagrangian_value(t0, q0, v0).is_finite() {
        return Err(Error::InvalidInitialData {
            reason: "the lagrangian or its momentum is not finite at the initial data",
        });
    }
    let hessian = system.velocity_hessian(t0, q0, at);
    let kept =
        hessian.iter().all(|x| x.is_finite()).then(|| regular(hessian)).flatten().ok_or(Error::InvalidInitialData {
            reason: "∂²L/∂v² is singular at the initial data: the legendre transform is not regular",
        })?;
    let energy = system.energy(t0, q0, v0);
    if !energy.is_finite() {
        return Err(Error::InvalidInitialData { reason: "the energy is not finite at the initial data" });
    }
    Ok((p0, energy, kept))
}

/// [`explicit_cache`]'s first call, where the start did not make the cache:
/// `M⁻¹` at the start node.
#[cold]
#[inline(never)]
fn new_explicit_cache<S: Lagrangian<N>, const N: usize>(
    system: &S,
    t0: f64,
    q0: &[f64; N],
) -> Result<Box<ExplicitCache<N>>, NewtonFailure> {
    explicit_cache_of(system.velocity_hessian(t0, *q0, [0.0; N]))
        .ok_or(NewtonFailure::Singular { iterations: 0, rcond: 0.0 })
}

/// The explicit steps' cache of the constant mass matrix `mass`; `None`
/// when it is singular.
#[cold]
#[inline(never)]
fn explicit_cache_of<const N: usize>(mass: SMatrix<f64, N, N>) -> Option<Box<ExplicitCache<N>>> {
    let m = mass.try_inverse()?;
    let diagonal = (0..N).all(|i| (0..N).all(|j| i == j || m[(i, j)] == 0.0));
    let unit = diagonal && (0..N).all(|i| m[(i, i)] == 1.0);
    Some(Box::new(ExplicitCache {
        inverse_mass: Arc::new(m),
        diagonal: diagonal.then(|| core::array::from_fn(|i| m[(i, i)])),
        unit,
        forces: [[0.0; N]; 2],
        node: 0,
    }))
}

/// The node an explicit step starts from, borrowed from the integrator.
pub(super) struct ExplicitNode<'a, const N: usize> {
    pub(super) state: &'a State<N>,
    /// The Kahan compensations of `q` and `p`.
    pub(super) carry: &'a [f64; N],
    pub(super) p_carry: &'a [f64; N],
    /// The initial velocity (the predictor's guess before two steps).
    pub(super) v0: &'a [f64; N],
}

/// An explicit step that passed every check; nothing is committed yet (the
/// force at its end node waits in the cache's spare buffer).
pub(super) struct ExplicitStep<const N: usize> {
    /// The step's total increment `q_{k+1} − q_k` (before the compensation).
    pub(super) dq: [f64; N],
    pub(super) q1: [f64; N],
    pub(super) carry: [f64; N],
    pub(super) p1: [f64; N],
    pub(super) p_carry: [f64; N],
}

/// A composition of Störmer–Verlet sub-steps of sizes `γ_i h` (`weights`;
/// `[1.0]` is one trapezoid step) on `L = ½ vᵀMv − V(t, q)` with constant
/// `M`, run on local arrays and checked once:
///
/// ```text
/// Δp ← Δp + (h_{i−1} + h_i)/2 · f_i      (the closing kick of sub-step i − 1 and the opening one of i share the node)
/// δq_i = h_i M⁻¹ (p_k + Δp),   Δq ← Δq + δq_i,   f_{i+1} = f(t_{i+1}, q_k + Δq)
/// ```
///
/// with `Δp ← Δp + h_m/2 · f_{m+1}` at the end, then `q_{k+1} = q_k + Δq`
/// and `p_{k+1} = p_k + Δp` as Kahan sums with the state's compensations.
/// Every sub-node position is `q_k + (c_q + Δq)`, the operations of that
/// Kahan sum, so the last one is `q_{k+1}` bit for bit (its force is the next
/// step's `f_k`), and the momentum in each drift is `p_k + (c_p + Δp)`. The
/// partial sums `Δq`, `Δp` round relative to the step's increment, not to
/// `q` and `p`, and the state is summed once per composed step, so the
/// round-off of the nodes does not grow with the number of sub-steps.
///
/// `increments[i]` receives `δq_i` (it needs `weights.len()` entries). The growth check
/// compares `Δq` with the last step's total increment, the finiteness
/// check runs on `q_{k+1}`, `p_{k+1}` and `t1`. Changes only the caches of
/// `memory` (the inverse mass matrix; the node force stays valid for node
/// `k`, the sub-node forces go to the spare buffer).
///
/// `PLAIN` ([`Summation::Plain`], the compensations zero): the sub-steps
/// update `q` and `p` in place as a hand-written composition does,
/// `p ← p + (h_{i−1} + h_i)/2 · f_i`, `q ← q + h_i M⁻¹ p`, each sub-node
/// position rounded once, and `Δq = q_{k+1} − q_k` is formed at the end for
/// the growth check and the step's memory.
#[inline(always)]
pub(super) fn explicit_step<S: Lagrangian<N>, const N: usize, const PLAIN: bool>(
    system: &S,
    memory: &mut OnePointMemory<N>,
    node: ExplicitNode<'_, N>,
    h: f64,
    t1: f64,
    weights: &[f64],
    increments: &mut [[f64; N]],
) -> Result<ExplicitStep<N>, NewtonFailure> {
    let State { step, t: t0, q: ref q0, p: ref p0 } = *node.state;
    let (qc, pc) = (node.carry, node.p_carry);
    let cache = explicit_cache(system, &mut memory.explicit, t0, q0)?;
    cache.node_force(system, step, t0, q0);
    let ExplicitCache { inverse_mass, diagonal, unit, forces, .. } = cache;
    let (f0, f) = split_forces(forces, step);
    let start = SubstepStart { q0, p0, qc, pc, t0, t1, h };
    // The mass matrix is chosen once per step, not per sub-step.
    let (dq, mut dp, q, closing, l1) = match diagonal {
        // `M = I`: the product with its ones is exact and skipped.
        Some(_) if *unit => substeps::<S, N, PLAIN>(system, &start, (f0, f), weights, increments, |mv, hi, out| {
            for j in 0..N {
                out[j] = mv[j] * hi;
            }
        }),
        // A diagonal `M⁻¹` skips the products with its zeros, which add
        // exact zeros (only the sign of a zero increment can differ).
        Some(d) => substeps::<S, N, PLAIN>(system, &start, (f0, f), weights, increments, |mv, hi, out| {
            for j in 0..N {
                out[j] = (d[j] * mv[j]) * hi;
            }
        }),
        None => substeps::<S, N, PLAIN>(system, &start, (f0, f), weights, increments, |mv, hi, out| {
            // By reference: by value the `N × N` matrix would be copied.
            #[allow(clippy::op_ref)]
            let v = &**inverse_mass * SVector::from(*mv) * hi;
            *out = v.into();
        }),
    };
    // The closing kick's force: `f_{k+1}` (`f_k` after no sub-step).
    let f: &[f64; N] = f;
    let (mut carry, mut p1, mut p_carry) = ([0.0; N], [0.0; N], [0.0; N]);
    let (mut q_bad, mut p_bad) = (0, 0);
    for j in 0..N {
        q_bad |= nan_bits(q[j]);
        if PLAIN {
            // `dp` holds the momentum itself (see `substeps`).
            p1[j] = dp[j] + closing * f[j];
        } else {
            // `q` holds `q0 + (qc + dq)`: the Kahan sum's new value.
            carry[j] = (qc[j] + dq[j]) - (q[j] - q0[j]);
            dp[j] += closing * f[j];
            let u = pc[j] + dp[j];
            p1[j] = p0[j] + u;
            p_carry[j] = u - (p1[j] - p0[j]);
        }
        p_bad |= nan_bits(p1[j]);
    }
    if let Some(last) = &memory.previous
        && !explicit_growth_ruled_out(fold_max_abs(&dq), fold_max_abs(q0), h, last.h, &last.dq)
    {
        let mut predicted = [0.0; N];
        let earlier = memory.earlier.as_ref().map(|(h, dq)| (*h, &dq[..]));
        super::predict_into(h, Some((last.h, &last.dq[..])), earlier, node.v0, &mut predicted);
        if implausible_growth(&dq, &predicted, &last.dq.map(|x| x * (h / last.h)), q0) {
            return Err(NewtonFailure::Rejected { iterations: 0, reason: IMPLAUSIBLE_GROWTH });
        }
    }
    if is_non_finite(q_bad | p_bad | nan_bits(t1) | nan_bits(l1)) {
        let quantity = super::first_non_finite(!is_non_finite(q_bad), !is_non_finite(p_bad), t1.is_finite());
        return Err(NewtonFailure::NonFinite { iterations: 0, quantity: quantity.unwrap_or("lagrangian") });
    }
    Ok(ExplicitStep { dq, q1: q, carry, p1, p_carry })
}

/// Replaces the state `(state, carry, p_carry)` by the checked explicit step
/// `taken` of size `h` ending at `t1`, in place, and updates the memory (the
/// last two steps, the node force) and the counters (no Newton iteration).
#[inline(always)]
pub(super) fn commit_explicit<const N: usize>(
    memory: &mut OnePointMemory<N>,
    (state, carry, p_carry, stats): (&mut State<N>, &mut [f64; N], &mut [f64; N], &mut Stats),
    h: f64,
    t1: f64,
    taken: &ExplicitStep<N>,
) {
    let step = state.step + 1;
    if let Some(cache) = memory.explicit.as_deref_mut() {
        cache.advance(step);
    }
    match (&memory.previous, &mut memory.earlier) {
        (Some(last), Some((h_earlier, dq_earlier))) => {
            *h_earlier = last.h;
            *dq_earlier = last.dq;
        }
        (Some(last), earlier) => *earlier = Some((last.h, last.dq)),
        (None, earlier) => *earlier = None,
    }
    match &mut memory.previous {
        Some(last) => {
            last.t0 = state.t;
            last.h = h;
            last.q0 = state.q;
            last.dq = taken.dq;
        }
        None => memory.previous = Some(Segment { t0: state.t, h, q0: state.q, dq: taken.dq }),
    }
    state.step = step;
    state.t = t1;
    state.q = taken.q1;
    state.p = taken.p1;
    *carry = taken.carry;
    *p_carry = taken.p_carry;
    stats.steps += 1;
    stats.last = NewtonReport { iterations: 0, residual_norm: 0.0, correction_norm: 0.0 };
}

/// `∂A/∂q_k|_{q_{k+1}}` and the Jacobian `∂²A/∂q_k∂q_{k+1}` of a rule with
/// the quadrature points `points` (weight `w` each, see
/// [`distinct`](super::tape_step::distinct)) on the segment `seg`, from the
/// macro's gradient code run on dual numbers with one lane per coordinate
/// (forward over reverse):
///
/// ```text
/// ∂A/∂q_k|_{q_{k+1}} = Σ_j w h [(1 − c_j) L_q − h⁻¹ L_v](x_j),   x_j = (t_k + c_j h, q_k + c_j Δq, Δq/h)
/// ```
///
/// and its derivative in `q_{k+1}` from the seeds `δq = c_j e_i`,
/// `δv = h⁻¹ e_i`. The same quantities as the hyper-dual sweep of `A`
/// (`derivatives::step_derivatives`), which carries the whole `N × N` block
/// through every operation of `L`; here the gradient code carries `N`
/// lanes, and only through the operations that depend on `q` or `v`.
/// Last, `Σ_j L(x_j)`, which the gradient code computes on the way.
#[inline(always)]
fn gradient_linearization<S: Lagrangian<N>, const N: usize>(
    system: &S,
    points: [f64; 2],
    seg: &Segment<N>,
    mut impulse_slope: Option<&mut SMatrix<f64, N, N>>,
) -> ([f64; N], SMatrix<f64, N, N>, [f64; N], f64) {
    let Segment { t0, h, q0, dq } = *seg;
    let inv_h = h.recip();
    let (evaluated, w) = super::tape_step::distinct(points);
    // The weight of `L_v`: `w h · h⁻¹`, the derivative of the action as
    // computed (`v = Δq·h⁻¹`).
    let b_v = w * (h * inv_h);
    let (mut d_q0, mut jacobian) = ([0.0; N], SMatrix::<f64, N, N>::zeros());
    let mut dp = [0.0; N];
    let mut lagrangian = 0.0;
    let wh = w * h;
    for (n, &j) in evaluated.iter().enumerate() {
        let c = points[j];
        let a_q = w * (h * (1.0 - c));
        let seeded = |x: f64, i: usize, scale: f64| {
            let mut x = DualArray::<[f64; N]>::from_re(x);
            x.eps[i] = scale;
            x
        };
        let q: [DualArray<[f64; N]>; N] =
            core::array::from_fn(|i| seeded(super::tape_step::point_position(c, q0[i], dq[i]), i, c));
        let v: [DualArray<[f64; N]>; N] = core::array::from_fn(|i| seeded(dq[i] * inv_h, i, inv_h));
        let (mut gq, mut gv) = ([DualArray::from_re(0.0); N], [DualArray::from_re(0.0); N]);
        let t = DualArray::from_re(super::tape_step::point_time(c, t0, h));
        let l = system.value_gradient_qv_scalar(t, &q, &v, &mut gq, &mut gv).re;
        // The first point's terms start the sums (`0 + x` is an IEEE
        // addition on Newton's chain of dependent operations).
        let first = n == 0;
        lagrangian = if first { l } else { lagrangian + l };
        for i in 0..N {
            let d = a_q * gq[i].re - b_v * gv[i].re;
            d_q0[i] = if first { d } else { d_q0[i] + d };
            for k in 0..N {
                let e = a_q * gq[i].eps[k] - b_v * gv[i].eps[k];
                jacobian[(i, k)] = if first { e } else { jacobian[(i, k)] + e };
            }
        }
        if let Some(slope) = impulse_slope.as_deref_mut() {
            // The impulse as `gradient_momentum_change` sums it (the same
            // bits), and its derivative in the increment.
            for i in 0..N {
                let d = wh * gq[i].re;
                dp[i] = if first { d } else { dp[i] + d };
                for k in 0..N {
                    let e = wh * gq[i].eps[k];
                    slope[(i, k)] = if first { e } else { slope[(i, k)] + e };
                }
            }
        }
    }
    (d_q0, jacobian, dp, lagrangian)
}

/// The residual part `∂A/∂q_k` of [`gradient_linearization`] alone, from the
/// macro's `f64` gradient code: the same operations on the same numbers, so
/// the same bits as the dual sweep's real parts. And the impulse
/// `Σ_j w h L_q(q_j)` (where [`Impulse::LINEARISED`]; zeros otherwise).
#[inline(always)]
fn gradient_residual<S: Lagrangian<N>, const N: usize>(
    system: &S,
    points: [f64; 2],
    seg: &Segment<N>,
) -> ([f64; N], [f64; N]) {
    let Segment { t0, h, q0, dq } = *seg;
    let inv_h = h.recip();
    let (evaluated, w) = super::tape_step::distinct(points);
    let b_v = w * (h * inv_h);
    let v: [f64; N] = dq.map(|d| d * inv_h);
    let (mut d_q0, mut dp) = ([0.0; N], [0.0; N]);
    let wh = w * h;
    for (n, &j) in evaluated.iter().enumerate() {
        let c = points[j];
        let a_q = w * (h * (1.0 - c));
        let q: [f64; N] = core::array::from_fn(|i| super::tape_step::point_position(c, q0[i], dq[i]));
        let (mut gq, mut gv) = ([0.0; N], [0.0; N]);
        system.gradient_qv(super::tape_step::point_time(c, t0, h), &q, &v, &mut gq, &mut gv);
        for i in 0..N {
            let d = a_q * gq[i] - b_v * gv[i];
            d_q0[i] = if n == 0 { d } else { d_q0[i] + d };
            if Impulse::<N>::LINEARISED {
                dp[i] = if n == 0 { wh * gq[i] } else { dp[i] + wh * gq[i] };
            }
        }
    }
    (d_q0, dp)
}

/// The impulse `I(Δq) = Σ_j w h L_q(q_j, Δq/h)` of a step taken from the
/// macro's gradient code: the momentum change `p_{k+1} − p_k =
/// ∂A/∂q_k + ∂A/∂q_{k+1}` once the DEL holds. Newton's linearisations
/// evaluate it at each iterate beside the residual (one multiply-add per
/// coordinate and point), and the fresh ones its derivative `I'` in the
/// increment (`N²` more, from the dual parts they carry), so that at the
/// solution `Δq_n = Δq_{n−1} + δ` it is `I(Δq_{n−1}) + I'(Δq_F) δ`
/// (`Δq_F`: the iterate of the last fresh linearisation), without the
/// evaluation of `L_q` at `Δq_n` a step would otherwise end with.
///
/// The error of that, `I''(Δq_{n−1} − Δq_F, δ) + ½ I''(δ, δ)` to leading
/// order, is bounded a priori. Newton keeps a Jacobian only after a
/// correction below [`KEEP_BELOW`](newton::KEEP_BELOW) of the unknown, and
/// only while the kept iterations contract at least fourfold, so
/// `‖Δq_{n−1} − Δq_F‖ ≤ 2·KEEP_BELOW·‖Δq_n‖`; where `I'` changes by at most
/// its own size over a displacement of the increment's size
/// (`‖I''‖ ‖Δq‖ ≤ ‖I'‖`, which a step that resolves the motion satisfies with
/// room to spare), the error is at most
/// `‖I'δ‖ (2·KEEP_BELOW + ‖δ‖/‖Δq_n‖)`. The impulse is linearised only where
/// that is below a quarter of an ulp of the momentum's terms (on a converged
/// step at the default tolerance `δ` is a few ulps of `Δq` and it is), and
/// evaluated at `Δq_n` otherwise; where `I'` varies faster, by a factor `K`,
/// the error is at most `K/4` ulps. `tests/verification/impulse.rs` checks
/// the momentum change against the impulse evaluated at the stored
/// increment, at tolerances from `1e-14` to `1e-10`.
///
/// Beside the impulse it carries what the step checks `L` with
/// ([`lagrangian`](Self::lagrangian)), which every linearisation leaves.
pub(super) struct Impulse<const N: usize> {
    /// `I` at the last iterate evaluated.
    at: Option<[f64; N]>,
    /// `I'` at the iterate of the last fresh linearisation (`None`, and
    /// not initialised, where not [`LINEARISED`](Self::LINEARISED)).
    slope: Option<SMatrix<f64, N, N>>,
    /// The correction made from the last iterate.
    correction: [f64; N],
    /// Finite exactly where `L` is finite at the rule's points of an
    /// iterate (up to overflow of a sum of finite values): from the
    /// gradient code, `Σ_j L(x_j)` at the iterate of the last fresh
    /// linearisation, whose forward sweep on dual numbers computes `L`'s
    /// transcendental functions anyway (the `f64` residuals of a kept
    /// Jacobian skip those the derivatives do not need, such as `cos` beside
    /// `sin`, and leave it); the action `h Σ_j w L(x_j)` at the last iterate
    /// otherwise. Newton keeps a Jacobian only after corrections below
    /// [`KEEP_BELOW`](newton::KEEP_BELOW) of the increment that contract
    /// fourfold, so that iterate is within `2·KEEP_BELOW·‖Δq‖` of the last
    /// (as for the impulse above), and that one within Newton's tolerance
    /// of the solution: `L` is checked within about a five-hundredth of the
    /// step's motion of the rule's points. NaN before the first
    /// linearisation, which is always fresh.
    pub(super) lagrangian: f64,
}

impl<const N: usize> Impulse<N> {
    /// Carried through Newton only for small systems: `N²` operations per
    /// fresh linearisation and at the end, against one evaluation of `L_q`
    /// saved per step.
    pub(super) const LINEARISED: bool = N <= 4;

    pub(super) fn new() -> Self {
        Self { at: None, slope: None, correction: [0.0; N], lagrangian: f64::NAN }
    }

    /// `I` evaluated at an iterate, and `I'` when the linearisation there
    /// is fresh.
    #[inline(always)]
    fn evaluated(&mut self, value: [f64; N], slope: Option<SMatrix<f64, N, N>>) {
        if Self::LINEARISED {
            self.at = Some(value);
            if slope.is_some() {
                self.slope = slope;
            }
        }
    }

    /// `I` at `dq`, the increment Newton returned after the last
    /// correction, or `None` where it is to be evaluated there. `p_scale`:
    /// `max|p_k|`.
    #[inline(always)]
    fn at_solution(&self, dq: &[f64; N], p_scale: f64) -> Option<[f64; N]> {
        let (value, slope) = (self.at?, self.slope.as_ref()?);
        let change = slope * SVector::from(self.correction);
        let dq_max = max_abs(dq);
        let error = change.amax() * (2.0 * newton::KEEP_BELOW * dq_max + max_abs(&self.correction));
        // NaN anywhere: not within, evaluated.
        let within = error <= 0.25 * f64::EPSILON * p_scale.max(max_abs(&value)) * dq_max;
        if !within {
            return None;
        }
        Some(core::array::from_fn(|i| value[i] + change[i]))
    }
}

/// The momentum change `∂A/∂q_k + ∂A/∂q_{k+1} = Σ_j w h L_q(x_j)` (at fixed
/// increment) of the rule with the quadrature points `points` on `seg`,
/// from the macro's `f64` gradient code in `q` (see [`gradient_linearization`]).
#[inline(always)]
fn gradient_momentum_change<S: Lagrangian<N>, const N: usize>(
    system: &S,
    points: [f64; 2],
    seg: &Segment<N>,
) -> [f64; N] {
    let Segment { t0, h, q0, dq } = *seg;
    let inv_h = h.recip();
    let (evaluated, w) = super::tape_step::distinct(points);
    let v: [f64; N] = dq.map(|d| d * inv_h);
    let mut dp = [0.0; N];
    for (n, &j) in evaluated.iter().enumerate() {
        let c = points[j];
        let at: [f64; N] = core::array::from_fn(|i| super::tape_step::point_position(c, q0[i], dq[i]));
        let mut gq = [0.0; N];
        system.gradient_q(super::tape_step::point_time(c, t0, h), &at, &v, &mut gq);
        let wh = w * h;
        for i in 0..N {
            dp[i] = if n == 0 { wh * gq[i] } else { dp[i] + wh * gq[i] };
        }
    }
    dp
}

/// What the sub-steps of [`explicit_step`] start from.
struct SubstepStart<'a, const N: usize> {
    q0: &'a [f64; N],
    p0: &'a [f64; N],
    qc: &'a [f64; N],
    pc: &'a [f64; N],
    t0: f64,
    t1: f64,
    h: f64,
}

/// The sub-steps of [`explicit_step`] from the force `f_k` at the start, with
/// `drift(p, h_i, out)` writing `h_i M⁻¹ p`: `(Δq, Δp, q_{k+1}, h_m/2)`, `Δp`
/// still without its closing kick `h_m/2 · f_{k+1}`. `forces` is `f_k` and
/// the buffer that receives `f_{k+1}`; the sub-nodes' forces stay local.
/// `PLAIN` ([`Summation::Plain`]): `p ← p + (h_{i−1} + h_i)/2 · f_i`,
/// `q ← q + h_i M⁻¹ p` in place, the way a hand-written composition steps,
/// and the second value is the momentum `p` before the closing kick, not
/// `Δp`; `Δq = q_{k+1} − q_k` is formed at the end.
#[inline(always)]
fn substeps<S: Lagrangian<N>, const N: usize, const PLAIN: bool>(
    system: &S,
    start: &SubstepStart<'_, N>,
    (f0, f_end): (&[f64; N], &mut [f64; N]),
    weights: &[f64],
    increments: &mut [[f64; N]],
    drift: impl Fn(&[f64; N], f64, &mut [f64; N]),
) -> ([f64; N], [f64; N], [f64; N], f64, f64) {
    let SubstepStart { q0, p0, qc, pc, t0, t1, h } = *start;
    // `dp` is `Δp` from the node, or under `PLAIN` the momentum itself.
    let (mut dq, mut dp, mut q) = ([0.0; N], if PLAIN { *p0 } else { [0.0; N] }, *q0);
    let mut f = *f0;
    // Half the last sub-step: its closing kick joins the next opening one.
    let mut half = 0.0;
    let mut elapsed = 0.0;
    // `L(t, q, 0)` at the last sub-node (`q_{k+1}`); the start node's after
    // no sub-step, checked by the step that reached it.
    let mut l_end = 0.0;
    // `increments` has room for every sub-step (`Composition::check`).
    let m = weights.len().min(increments.len());
    let mut mv = [0.0; N];
    for i in 0..m {
        let gamma = weights[i];
        let hi = gamma * h;
        let kick = half + 0.5 * hi;
        for j in 0..N {
            dp[j] += kick * f[j];
            if !PLAIN {
                mv[j] = p0[j] + (pc[j] + dp[j]);
            }
        }
        let slot = &mut increments[i];
        drift(if PLAIN { &dp } else { &mv }, hi, slot);
        for j in 0..N {
            if PLAIN {
                q[j] += slot[j];
            } else {
                dq[j] += slot[j];
                q[j] = q0[j] + (qc[j] + dq[j]);
            }
        }
        elapsed += gamma;
        let ti = if i + 1 == m { t1 } else { t0 + elapsed * h };
        l_end = potential_force(system, ti, &q, &mut f);
        half = 0.5 * hi;
    }
    *f_end = f;
    if PLAIN {
        dq = core::array::from_fn(|j| q[j] - q0[j]);
    }
    (dq, dp, q, half, l_end)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The explicit steps' shortcuts never pass an increment the full
    /// `implausible_growth` would refuse, and both verdicts occur.
    #[test]
    fn the_explicit_growth_shortcut_agrees_with_the_full_check() {
        let mut next = crate::real::uniform_stream(0x2545_f491_4f6c_dd1d_u64);
        let (mut refused, mut shortcut) = (0, 0);
        for case in 0..20_000 {
            let scale = [0.0, 1e-9, 1e-3, 1.0][case % 4];
            let q: [f64; 3] = core::array::from_fn(|_| scale * next());
            let last: [f64; 3] = core::array::from_fn(|_| 1e-6 * next());
            let predicted: [f64; 3] = core::array::from_fn(|_| 1e-6 * next());
            let size = 10f64.powf(6.0 * next() + (case % 3) as f64 - 1.0);
            let dq: [f64; 3] = core::array::from_fn(|_| size * next());
            let (h, h_last) = (0.01 * (1.0 + next()), 0.01 * (1.0 + next()));
            let scaled = last.map(|x| x * (h / h_last));
            let full = implausible_growth(&dq, &predicted, &scaled, &q);
            if explicit_growth_ruled_out(max_abs(&dq), max_abs(&q), h, h_last, &last) {
                assert!(!full, "case {case}: the shortcut passed a refused increment");
                shortcut += 1;
            }
            refused += usize::from(full);
        }
        assert!(refused > 100 && shortcut > 100, "{refused} refused, {shortcut} by the shortcut");
    }
}
