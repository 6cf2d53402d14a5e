//! The explicit steps of separable systems with a constant mass matrix:
//! Störmer–Verlet (the trapezoid rule's explicit form) and the fused
//! substeps of compositions, with the mass matrix factored once.

use super::legendre::{Assembled, potential_force, potential_force_finite, velocity_derivatives};
use super::{
    Composed, ComposedScratch, Growth, LastSubstep, Node, SparseWork, TAPE_FAILED, Taken, TapeModel, breakdown,
    mass_bandwidth, zeroed,
};
use crate::banded::{LinearSolveError, StepSolver};
use crate::newton::{Breakdown, NewtonFailure, NewtonReport};
use crate::real::{is_non_finite, kahan_add as kahan, nan_bits};
use std::sync::Arc;

impl SparseWork {
    /// The velocity `M⁻¹ p` of the momentum `p` with the factored constant
    /// mass matrix of the explicit path, as its drift applies it, written
    /// into `v`; `false` (and `v` unspecified) before the first explicit
    /// step has factored `M`, or if the solve fails. For
    /// `L = ½ vᵀMv − V(t, q)` this is the inverse Legendre map exactly,
    /// without the Newton iteration and the second-order sweep that a
    /// general `L` needs at every node (three quarters of a `solve` with an
    /// event on a chain of 1 000 masses).
    pub(crate) fn constant_mass_velocity(&self, p: &[f64], v: &mut [f64]) -> bool {
        self.mass.as_deref().is_some_and(|mass| mass.velocity_into(p, v).is_ok())
    }

    /// The explicit (Störmer–Verlet) step of the trapezoid rule on a
    /// separable system with constant mass: `M` factored once (banded when
    /// proven, a division when diagonal), `∂L/∂q` from the system's adjoint
    /// code or one reverse sweep per step, reused at the next node. Clears
    /// [`energy`](Self::energy) on success (a Verlet step's discrete energy is
    /// computed on request); keeps the node force of `node` on failure.
    pub(crate) fn verlet_step(
        &mut self,
        model: &dyn TapeModel,
        node: &Node<'_>,
        h: f64,
        t1: f64,
        growth: &Growth<'_>,
        min_rcond: f64,
    ) -> Result<Taken, NewtonFailure> {
        let f0 = self.explicit_node(model, node, min_rcond)?;
        let dq = self.buffer();
        let mut taken = self.taken(dq, NewtonReport { iterations: 0, residual_norm: 0.0, correction_norm: 0.0 });
        let mut f1 = self.buffer();
        let outcome = match node.plain {
            false => self.verlet_into::<false>(model, node, h, t1, growth, &f0, &mut taken, &mut f1),
            true => self.verlet_into::<true>(model, node, h, t1, growth, &f0, &mut taken, &mut f1),
        };
        match outcome {
            Ok(()) => {
                self.node_force = Some((node.step + 1, f1));
                self.recycle(f0);
                self.energy = None;
                Ok(taken)
            }
            Err(failure) => {
                self.node_force = Some((node.step, f0));
                self.recycle(f1);
                self.recycle_taken(taken);
                Err(failure)
            }
        }
    }

    /// What every explicit step needs first: the constant mass matrix
    /// (factored at the first one; a singular one is a typed failure) and
    /// the force at `node` (the cached one when it is that node's, which the
    /// caller puts back or replaces).
    pub(super) fn explicit_node(
        &mut self,
        model: &dyn TapeModel,
        node: &Node<'_>,
        min_rcond: f64,
    ) -> Result<Vec<f64>, NewtonFailure> {
        let n = self.n;
        if self.mass.is_none() {
            let mass = Mass::factored(model, node.t, &node.q[..n], min_rcond).map_err(|b| b.at(0))?;
            self.mass = Some(Arc::new(mass));
        }
        match self.node_force.take() {
            Some((k, f)) if k == node.step => Ok(f),
            stale => {
                let mut f = match stale {
                    Some((_, f)) => f,
                    None => self.buffer(),
                };
                match potential_force(model, &mut self.tape, &self.zero, node.t, node.q, &mut f) {
                    Ok(()) => Ok(f),
                    Err(_) => {
                        self.recycle(f);
                        Err(NewtonFailure::Rejected { iterations: 0, reason: TAPE_FAILED })
                    }
                }
            }
        }
    }

    /// A composition of explicit Störmer–Verlet sub-steps of sizes `γ_i h`
    /// (`weights`) fused into one step on the work's buffers, checked and
    /// returned once: the slice form of forward mode's fused composed step
    /// (`one_point.rs`, `explicit_step`), with the same operations in the
    /// same order,
    ///
    /// ```text
    /// Δp ← Δp + (h_{i−1} + h_i)/2 · f_i,   δq_i = h_i M⁻¹ (p_k + (c_p + Δp)),
    /// Δq ← Δq + δq_i,   f_{i+1} = f(t_{i+1}, q_k + (c_q + Δq)),
    /// ```
    ///
    /// then `Δp ← Δp + h_m/2 · f_{m+1}` and `q_{k+1}`, `p_{k+1}` as Kahan
    /// sums of `Δq`, `Δp` with the node's compensations. The growth check
    /// compares `Δq` with the last (composed) step's increment, its early
    /// bound decided in the last pass as in
    /// [`verlet_into`](Self::verlet_into). Returns the
    /// composed step and its last sub-step `(t, h_m, q, δq_m)` (the readouts'
    /// segment); keeps the node force of `node` on failure, and on success
    /// the end node's force for the next step.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn verlet_composed(
        &mut self,
        model: &dyn TapeModel,
        node: &Node<'_>,
        h: f64,
        t1: f64,
        weights: &[f64],
        growth: &Growth<'_>,
        min_rcond: f64,
    ) -> Result<Composed, NewtonFailure> {
        let f0 = self.explicit_node(model, node, min_rcond)?;
        let dq = self.buffer();
        let mut taken = self.taken(dq, NewtonReport { iterations: 0, residual_norm: 0.0, correction_norm: 0.0 });
        let (mut f, mut dp, mut last_q0, mut last_dq) = (self.buffer(), self.buffer(), self.buffer(), self.buffer());
        let scratch = ComposedScratch { f: &mut f, dp: &mut dp, last_q0: &mut last_q0, last_dq: &mut last_dq };
        match self.composed_into(model, node, (h, t1), weights, growth, &f0, &mut taken, scratch) {
            Ok((t0_last, h_last)) => {
                self.node_force = Some((node.step + 1, f));
                self.recycle(f0);
                self.recycle(dp);
                self.energy = None;
                Ok(Composed { taken, last: LastSubstep { t0: t0_last, h: h_last, q0: last_q0, dq: last_dq } })
            }
            Err(failure) => {
                self.node_force = Some((node.step, f0));
                for buffer in [f, dp, last_q0, last_dq] {
                    self.recycle(buffer);
                }
                self.recycle_taken(taken);
                Err(failure)
            }
        }
    }

    /// The sub-steps of [`verlet_composed`](Self::verlet_composed) from the
    /// node force `f0`, into `out`; returns the last sub-step's start time
    /// and size. `scratch.f` ends with the force at the end node. Under
    /// [`Summation::Plain`](crate::Summation::Plain) (`node.plain`) the
    /// sub-steps update `q` and `p` in place in `out.q1` and `out.p1`,
    /// `p ← p + (h_{i−1} + h_i)/2 · f_i`, `q ← q + h_i M⁻¹ p`, as a
    /// hand-written composition steps (forward mode's `substeps`, same
    /// operations in the same order), and `Δq = q_{k+1} − q_k` is formed at
    /// the end for the growth check.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn composed_into(
        &mut self,
        model: &dyn TapeModel,
        node: &Node<'_>,
        (h, t1): (f64, f64),
        weights: &[f64],
        growth: &Growth<'_>,
        f0: &[f64],
        out: &mut Taken,
        scratch: ComposedScratch<'_>,
    ) -> Result<(f64, f64), NewtonFailure> {
        let (n, plain) = (self.n, node.plain);
        let ComposedScratch { f, dp, last_q0, last_dq } = scratch;
        let (q0, p0) = (&node.q[..n], &node.p[..n]);
        // Compensated: `p` is each drift's momentum `p_k + (c_p + Δp)`, `dp`
        // holds `Δp` and `q` the end node; plain: `p` and `q` are the running
        // momentum and position, and `dp` a copy of `p` for a solve.
        let (dq, q, p) = (&mut out.dq[..n], &mut out.q1[..n], &mut out.p1[..n]);
        let (f, dp, last_q0, last_dq) = (&mut f[..n], &mut dp[..n], &mut last_q0[..n], &mut last_dq[..n]);
        let f0 = &f0[..n];
        if plain {
            q.copy_from_slice(q0);
            p.copy_from_slice(p0);
        } else {
            dq.fill(0.0);
            dp.fill(0.0);
        }
        let velocity = self.mass.as_deref().map_or(Velocity::Solved, Mass::velocity);
        // Half the last sub-step: its closing kick joins the next opening one.
        let (mut half, mut elapsed) = (0.0, 0.0);
        let (mut t_last, mut h_last) = (node.t, 0.0);
        // Whether `L` is finite at the end node, from its force's evaluation.
        let mut end_finite = true;
        let m = weights.len();
        if m == 1 && !plain {
            last_q0.copy_from_slice(q0);
        }
        for (i, &gamma) in weights.iter().enumerate() {
            let hi = gamma * h;
            let kick = half + 0.5 * hi;
            // The force at the sub-step's start: the node's, then the last
            // sub-node's (no copy of the node force).
            let fi: &[f64] = if i == 0 { f0 } else { f };
            if plain {
                for j in 0..n {
                    p[j] += kick * fi[j];
                }
                // A solve works in place: `p` must stay, so it gets a copy.
                if let Velocity::Solved = velocity {
                    dp.copy_from_slice(p);
                    self.sub_drift(velocity, dp, hi, last_dq)?;
                } else {
                    self.sub_drift(velocity, p, hi, last_dq)?;
                }
                if i + 1 == m {
                    // The last sub-step's start, for the readouts.
                    last_q0.copy_from_slice(q);
                    // The end node's force is added to zeros; the last
                    // sub-node's was read by the kick above.
                    for j in 0..n {
                        q[j] += last_dq[j];
                        f[j] = 0.0;
                    }
                } else {
                    for j in 0..n {
                        q[j] += last_dq[j];
                    }
                }
            } else {
                let (qc0, pc0) = (&node.q_carry[..n], &node.p_carry[..n]);
                for j in 0..n {
                    dp[j] += kick * fi[j];
                    p[j] = p0[j] + (pc0[j] + dp[j]);
                }
                self.sub_drift(velocity, p, hi, last_dq)?;
                // The sub-nodes' positions go to `last_q0`, which then holds
                // the last sub-step's start; the end node's to `q`.
                if i + 1 == m {
                    // The end node's force is added to zeros; the last
                    // sub-node's was read by the kick above.
                    for j in 0..n {
                        dq[j] += last_dq[j];
                        q[j] = q0[j] + (qc0[j] + dq[j]);
                        f[j] = 0.0;
                    }
                } else {
                    for j in 0..n {
                        dq[j] += last_dq[j];
                        last_q0[j] = q0[j] + (qc0[j] + dq[j]);
                    }
                }
            }
            elapsed += gamma;
            let ti = if i + 1 == m { t1 } else { node.t + elapsed * h };
            if i + 1 < m {
                t_last = ti;
            } else {
                h_last = hi;
            }
            let at: &[f64] = if plain || i + 1 == m { q } else { last_q0 };
            let forced = if i + 1 == m {
                potential_force_finite(model, &mut self.tape, &self.zero, ti, at, f).map(|x| end_finite = x)
            } else {
                potential_force(model, &mut self.tape, &self.zero, ti, at, f)
            };
            if forced.is_err() {
                return Err(NewtonFailure::Rejected { iterations: 0, reason: TAPE_FAILED });
            }
            half = 0.5 * hi;
        }
        let (mut q_bad, mut p_bad, mut beyond) = (0, 0, 0);
        // The growth check's early bound, decided in the last pass (see
        // `verlet_into`).
        let bound = self.growth_bound(growth, q0);
        if plain {
            for j in 0..n {
                dq[j] = q[j] - q0[j];
                beyond |= beyond_bits(bound, dq[j]);
                q_bad |= nan_bits(q[j]);
                p[j] += half * f[j];
                p_bad |= nan_bits(p[j]);
            }
        } else {
            let (qc0, pc0) = (&node.q_carry[..n], &node.p_carry[..n]);
            let (qc1, pc1) = (&mut out.q_carry[..n], &mut out.p_carry[..n]);
            for j in 0..n {
                beyond |= beyond_bits(bound, dq[j]);
                // `q` holds `q_k + (c_q + Δq)`: the Kahan sum's new value.
                qc1[j] = (qc0[j] + dq[j]) - (q[j] - q0[j]);
                q_bad |= nan_bits(q[j]);
                dp[j] += half * f[j];
                let (sum, carry) = kahan(p0[j], pc0[j], dp[j]);
                p[j] = sum;
                pc1[j] = carry;
                p_bad |= nan_bits(sum);
            }
        }
        if beyond_bound(beyond) {
            self.growth_check_at(growth, &out.dq, node.q)?;
        }
        let quantity =
            crate::integrator::first_non_finite(!is_non_finite(q_bad), !is_non_finite(p_bad), t1.is_finite())
                .or_else(|| (!end_finite).then_some("lagrangian"));
        match quantity {
            Some(quantity) => Err(NewtonFailure::NonFinite { iterations: 0, quantity }),
            None => Ok((t_last, h_last)),
        }
    }

    /// A sub-step's drift `out = h_i M⁻¹ v` from the momentum `v` (solved in
    /// place when `M` takes a banded or dense solve, read otherwise).
    pub(super) fn sub_drift(
        &self,
        velocity: Velocity<'_>,
        v: &mut [f64],
        hi: f64,
        out: &mut [f64],
    ) -> Result<(), NewtonFailure> {
        let n = out.len();
        let v = &mut v[..n];
        match velocity {
            Velocity::Unit => {
                for j in 0..n {
                    out[j] = v[j] * hi;
                }
            }
            Velocity::Diagonal(d) => {
                let d = &d[..n];
                for j in 0..n {
                    out[j] = (d[j] * v[j]) * hi;
                }
            }
            Velocity::Solved => {
                if let Some(mass) = &self.mass {
                    mass.assembled.solve(v).map_err(|e| breakdown(e).at(0))?;
                }
                for j in 0..n {
                    out[j] = v[j] * hi;
                }
            }
        }
        Ok(())
    }

    /// The Verlet step given the force `f0` at the node, into `out`, and the
    /// force at the new node into `f1`: the half kick, the mass solve and
    /// the drift in one pass when `M` is diagonal, the other half kick in
    /// one more, each with its Kahan sum. The finiteness checks are ORs of
    /// [`nan_bits`] in those passes (branch-free, so the passes vectorise);
    /// which value failed is found again only on failure. The drift pass
    /// also compares every `|Δq_i|` with the growth check's early bound at a
    /// lower bound of `max|q_k|` ([`growth_bound`](Self::growth_bound)):
    /// only an increment beyond it takes the passes over `Δq` and `q_k` of
    /// the maxima.
    ///
    /// `PLAIN` ([`Summation::Plain`](crate::Summation::Plain)): the
    /// compensations are neither read nor written, the sums rounded once.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn verlet_into<const PLAIN: bool>(
        &mut self,
        model: &dyn TapeModel,
        node: &Node<'_>,
        h: f64,
        t1: f64,
        growth: &Growth<'_>,
        f0: &[f64],
        out: &mut Taken,
        f1: &mut [f64],
    ) -> Result<(), NewtonFailure> {
        let n = self.n;
        let half = 0.5 * h;
        let plain = PLAIN;
        let (q0, p0, f0) = (&node.q[..n], &node.p[..n], &f0[..n]);
        // Under plain summation the compensations are neither read nor
        // written (`q0`, `p0` stand in for them, unused).
        let (qc0, pc0) = if plain { (q0, p0) } else { (&node.q_carry[..n], &node.p_carry[..n]) };
        let (dq, q1, qc1) = (&mut out.dq[..n], &mut out.q1[..n], &mut out.q_carry[..n]);
        // The drift's momentum `(p_k + (h/2) f_k) + c_p`, before `M⁻¹`.
        let rhs = |i: usize| if plain { p0[i] + half * f0[i] } else { (p0[i] + half * f0[i]) + pc0[i] };
        let velocity = self.mass.as_deref().map_or(Velocity::Solved, Mass::velocity);
        if let Velocity::Solved = velocity {
            for i in 0..n {
                dq[i] = rhs(i);
            }
            if let Some(mass) = &self.mass {
                mass.assembled.solve(dq).map_err(|e| breakdown(e).at(0))?;
            }
        }
        // The growth check's early bound, decided in the drift pass against
        // a lower bound of `max|q_k|` (see `SparseWork::growth_bound`).
        let bound = self.growth_bound(growth, q0);
        let (q_bad, beyond) =
            drift_pass::<PLAIN>((h, half, bound), [p0, f0, pc0], velocity, (q0, qc0), (dq, q1, qc1), &mut f1[..n]);
        if is_non_finite(q_bad) && !matches!(velocity, Velocity::Solved) {
            // What the banded solve's checks would refuse, as it would
            // (found again only on failure).
            let v = |i: usize| match velocity {
                Velocity::Diagonal(d) => d[i] * rhs(i),
                _ => rhs(i),
            };
            let quantity = match ((0..n).all(|i| rhs(i).is_finite()), (0..n).all(|i| v(i).is_finite())) {
                (false, _) => Some("right-hand side"),
                (true, false) => Some("solution"),
                (true, true) => None,
            };
            if let Some(quantity) = quantity {
                return Err(breakdown(LinearSolveError::NonFinite { quantity }).at(0));
            }
        }
        if beyond_bound(beyond) {
            self.growth_check_at(growth, &out.dq, node.q)?;
        }
        // `L` at the end node from the force's evaluation: finite there and
        // at the start node (checked by the step before, or at `start`), it
        // makes the trapezoid action finite, whose derivatives can be finite
        // where it is not. The generated code adds the force to `f1`, which
        // the drift pass cleared.
        let end_finite = match potential_force_finite(model, &mut self.tape, &self.zero, t1, &out.q1, f1) {
            Ok(finite) => finite,
            Err(_) => return Err(NewtonFailure::Rejected { iterations: 0, reason: TAPE_FAILED }),
        };
        let (f1, p1, pc1) = (&f1[..n], &mut out.p1[..n], &mut out.p_carry[..n]);
        let mut p_bad = 0;
        if plain {
            for i in 0..n {
                p1[i] = p0[i] + half * (f0[i] + f1[i]);
                p_bad |= nan_bits(p1[i]);
            }
        } else {
            for i in 0..n {
                let (sum, carry) = kahan(p0[i], pc0[i], half * (f0[i] + f1[i]));
                p1[i] = sum;
                pc1[i] = carry;
                p_bad |= nan_bits(sum);
            }
        }
        let quantity =
            crate::integrator::first_non_finite(!is_non_finite(q_bad), !is_non_finite(p_bad), t1.is_finite())
                .or_else(|| (!end_finite).then_some("lagrangian"));
        match quantity {
            Some(quantity) => Err(NewtonFailure::NonFinite { iterations: 0, quantity }),
            None => Ok(()),
        }
    }
}

/// The factored constant mass matrix of the explicit path, and the
/// reciprocals of its diagonal when it is a banded matrix of bandwidth 0:
/// the solve is then one product per entry, done in the step's own loop.
#[derive(Clone, Debug)]
pub(crate) struct Mass {
    assembled: Assembled,
    inverse_diagonal: Option<Vec<f64>>,
    /// `M = I` (the diagonal is all ones): the drift skips the product.
    unit: bool,
}

impl Mass {
    pub(super) fn new(assembled: Assembled) -> Self {
        let inverse_diagonal: Option<Vec<f64>> = match (&assembled.matrix, assembled.bandwidth) {
            (StepSolver::Banded(_), Some(0)) => Some(assembled.band.iter().map(|d| d.recip()).collect()),
            _ => None,
        };
        // A reciprocal that overflows (a subnormal mass) leaves the banded
        // solve to divide.
        let inverse_diagonal = inverse_diagonal.filter(|d| d.iter().all(|x| x.is_finite()));
        let unit = inverse_diagonal.as_ref().is_some_and(|d| d.iter().all(|&x| x == 1.0));
        Self { assembled, inverse_diagonal, unit }
    }

    /// The constant mass matrix `M = ∂²L/∂v²` of `model` at `(t, q)` (at
    /// rest), assembled banded where the coupling proves a band, and
    /// factored; a singular or badly conditioned one (reciprocal condition
    /// below `min_rcond`) is refused. The explicit time-transformed
    /// splitting at a run-time size applies `M⁻¹` in its drifts by it.
    pub(crate) fn factored(model: &dyn TapeModel, t: f64, q: &[f64], min_rcond: f64) -> Result<Self, Breakdown> {
        let n = q.len();
        let zero = zeroed(Some(n), n).map_err(breakdown)?;
        let (_, _, mut mass) = velocity_derivatives(model, t, q, &zero, mass_bandwidth(model.coupling(), n))?;
        mass.factor_in_place(min_rcond)?;
        Ok(Self::new(mass))
    }

    /// The velocity `v = M⁻¹p`: a copy for `M = I`, products with the
    /// reciprocals of a diagonal, else the banded or dense solve.
    pub(crate) fn velocity_into(&self, p: &[f64], v: &mut [f64]) -> Result<(), LinearSolveError> {
        v.copy_from_slice(p);
        match self.velocity() {
            Velocity::Unit => Ok(()),
            Velocity::Diagonal(d) => {
                v.iter_mut().zip(d).for_each(|(v, d)| *v *= d);
                Ok(())
            }
            Velocity::Solved => self.assembled.solve(v),
        }
    }

    /// Whether `M = I`: `M⁻¹p` is `p` itself.
    pub(crate) fn is_unit(&self) -> bool {
        self.unit
    }

    /// How a drift applies `M⁻¹`: skipped for `M = I`, products with the
    /// reciprocals of a diagonal (as forward mode's `M⁻¹`; a division per
    /// entry cost 0.35 µs of a 2.5 µs step at N = 1000), else the solve.
    pub(super) fn velocity(&self) -> Velocity<'_> {
        match &self.inverse_diagonal {
            _ if self.unit => Velocity::Unit,
            Some(d) => Velocity::Diagonal(d),
            None => Velocity::Solved,
        }
    }
}

/// The drift of an explicit step in one pass: `Δq = h v` with the velocity
/// `v` of the momentum `(p_k + (h/2) f_k) + c_p` (`momentum = [p_k, f_k,
/// c_p]`), and `q_{k+1} = q_k + Δq` as a Kahan sum with the compensation
/// `qc0`; `cleared` (the buffer the end node's force is added to) set to
/// zero on the way: as a pass of its own, a `memset` of 8 kB at `N = 1000`,
/// it counted 8 000 instructions per step under callgrind, a store per
/// two entries here. Returns the OR of the [`nan_bits`] of `q_{k+1}`, and
/// the OR of the bits of `bound − |Δq_i|`, whose sign bit
/// ([`beyond_bound`]) is set where some `|Δq_i|` exceeds `bound` (an OR of
/// bits vectorises where a running maximum, a compare and select on
/// floats, does not; as two passes of their own the maxima counted 5 300
/// instructions per step at `N = 1000`). `PLAIN`
/// ([`Summation::Plain`](crate::Summation::Plain)): `c_p`, `qc0` are not
/// read, `qc1` not written, and `q_{k+1} = q_k + Δq` is rounded once.
#[inline(always)]
pub(super) fn drift_pass<const PLAIN: bool>(
    (h, half, bound): (f64, f64, f64),
    momentum: [&[f64]; 3],
    velocity: Velocity<'_>,
    (q0, qc0): (&[f64], &[f64]),
    (dq, q1, qc1): (&mut [f64], &mut [f64], &mut [f64]),
    cleared: &mut [f64],
) -> (u64, u64) {
    let step = (h, half, bound);
    match velocity {
        Velocity::Unit => drift_loop::<0, PLAIN>(step, momentum, &[], (q0, qc0), (dq, q1, qc1), cleared),
        Velocity::Diagonal(d) => drift_loop::<1, PLAIN>(step, momentum, d, (q0, qc0), (dq, q1, qc1), cleared),
        Velocity::Solved => drift_loop::<2, PLAIN>(step, momentum, &[], (q0, qc0), (dq, q1, qc1), cleared),
    }
}

/// Whether the OR of the bits of `bound − |Δq_i|` that [`drift_pass`]
/// returns has its sign bit: some `|Δq_i| > bound` (or a NaN with its sign
/// bit, which the full check then decides). `bound − |x|` is negative
/// exactly when `|x| > bound` (a difference of finite numbers is zero only
/// between equal ones, `+0` then).
#[inline(always)]
pub(super) fn beyond_bound(bits: u64) -> bool {
    bits >> 63 != 0
}

/// The bits of `bound − |x|`, OR-ed over an increment for [`beyond_bound`].
#[inline(always)]
pub(super) fn beyond_bits(bound: f64, x: f64) -> u64 {
    (bound - x.abs()).to_bits()
}

/// How the drift's velocity comes from its momentum `(p_k + (h/2) f_k) + c_p`.
#[derive(Clone, Copy)]
pub(super) enum Velocity<'a> {
    /// `M = I`: the momentum itself (the product with ones is exact and
    /// skipped).
    Unit,
    /// A diagonal `M`: the product with the reciprocals of its entries.
    Diagonal(&'a [f64]),
    /// Already in `dq`: `M⁻¹` applied by a banded or dense solve.
    Solved,
}

/// [`drift_pass`] for one [`Velocity`] (`KIND` 0, 1, 2 in its order; `d`
/// the reciprocals of the diagonal for 1): one loop per kind, which
/// vectorises.
#[inline(always)]
pub(super) fn drift_loop<const KIND: u8, const PLAIN: bool>(
    (h, half, bound): (f64, f64, f64),
    [p0, f0, pc0]: [&[f64]; 3],
    d: &[f64],
    (q0, qc0): (&[f64], &[f64]),
    (dq, q1, qc1): (&mut [f64], &mut [f64], &mut [f64]),
    cleared: &mut [f64],
) -> (u64, u64) {
    let n = q0.len();
    // One length for every slice, so that the loop has no bounds checks.
    let d = if KIND == 1 { &d[..n] } else { q0 };
    let (p0, f0, pc0, qc0) = (&p0[..n], &f0[..n], &pc0[..n], &qc0[..n]);
    let (dq, q1, qc1, cleared) = (&mut dq[..n], &mut q1[..n], &mut qc1[..n], &mut cleared[..n]);
    let (mut bad, mut beyond) = (0, 0);
    for i in 0..n {
        cleared[i] = 0.0;
        // The momentum `(p_k + (h/2) f_k) + c_p`.
        let momentum = if PLAIN { p0[i] + half * f0[i] } else { (p0[i] + half * f0[i]) + pc0[i] };
        let v = match KIND {
            0 => momentum,
            1 => d[i] * momentum,
            _ => dq[i],
        };
        let x = v * h;
        dq[i] = x;
        let sum = if PLAIN {
            q0[i] + x
        } else {
            let (sum, carry) = kahan(q0[i], qc0[i], x);
            qc1[i] = carry;
            sum
        };
        q1[i] = sum;
        bad |= nan_bits(sum);
        beyond |= beyond_bits(bound, x);
    }
    (bad, beyond)
}
