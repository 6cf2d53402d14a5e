//! Symmetric compositions of the trapezoid rule: high-order variational
//! integrators from the second-order one.
//!
//! ```text
//! Φ_h = Ψ_{γ_m h} ∘ … ∘ Ψ_{γ_1 h},   Ψ = the trapezoid step,   Σ γ_i = 1,   γ_i = γ_{m+1−i}
//! ```
//!
//! Each sub-step is a variational (symplectic, momentum-preserving) map, so
//! the composition is one too: its discrete Lagrangian is the sum of the
//! sub-steps' actions with the intermediate nodes eliminated. On a system the
//! macro proves `½ vᵀMv − V(t, q)` with constant `M` the sub-steps are
//! explicit Störmer–Verlet (no Newton); otherwise each one is solved by
//! Newton like any trapezoid step. Coefficients (facts from the papers):
//!
//! * [`Composition::YOSHIDA4`]: 3 stages, order 4, `γ_1 = γ_3 = 1/(2 − 2^{1/3})`
//!   (Yoshida, *Construction of higher order symplectic integrators*, Phys.
//!   Lett. A 150, 1990; also Suzuki and Forest–Ruth).
//! * [`Composition::YOSHIDA6`]: 7 stages, order 6, Yoshida's "solution A" (same paper).
//! * [`Composition::KAHAN_LI8`]: 15 stages, order 8 (Kahan & Li,
//!   *Composition constants for raising the orders of unconventional schemes
//!   for ordinary differential equations*, Math. Comp. 66, 1997; the set
//!   `s15odr8` of Hairer, Lubich & Wanner, *Geometric Numerical
//!   Integration*, §V.3.2).
//!
//! Fixed steps only (energy-preserving steps are refused with
//! `Error::Unsupported`); forces enter each sub-step (discrete
//! Lagrange–d'Alembert), so a composition of forced sub-steps is forced
//! consistently, at order 2 in the forces' quadrature.

use super::method::{F64Readouts, Method, sealed};
use super::one_point::{ExplicitNode, commit_explicit, explicit_step};
use super::sparse::{LastSubstep, Stepper};
use super::{Integrator, OnePointMemory, StepPolicy, Summation};
use crate::dense::{Hermite, Node};
use crate::derivatives::{self, Segment};
use crate::discrete::Trapezoid;
use crate::error::Error;
use crate::mechanics::DiscreteMechanics;
use crate::state::State;
use crate::symplectic::{self, TangentMap};
use crate::system::Lagrangian;

/// The largest number of stages of the built-in compositions.
const MAX_STAGES: usize = 15;

/// A symmetric composition of trapezoid steps with weights `γ_1 … γ_m`.
///
/// On a system whose mass matrix the macro proves constant the trapezoid
/// step is Störmer–Verlet, and the composition an explicit method of the
/// composition's order. A harmonic oscillator over one period with
/// Kahan–Li's order-8 composition:
///
/// ```
/// # use lagrangian_runtime::{Composition, Integrator, Lagrangian, Scalar};
/// /// `L = ½v² − ½q²`.
/// struct Oscillator;
/// impl Lagrangian<1> for Oscillator {
///     const AUTONOMOUS: bool = true;
///     const CYCLIC: [bool; 1] = [false];
///     fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 1], v: [D; 1]) -> D {
///         (v[0] * v[0] - q[0] * q[0]) * 0.5
///     }
/// }
///
/// let h = 2.0 * std::f64::consts::PI / 20.0;
/// let mut sim = Integrator::new(Oscillator, Composition::KAHAN_LI8, h).start(0.0, [1.0], [0.0])?;
/// sim.run(20, |_| {})?;
/// // Order 8 with 20 steps per period: the phase error is about 1e-7.
/// assert!((sim.state().q[0] - 1.0).abs() < 1e-6);
/// assert_eq!(Composition::KAHAN_LI8.order(), 8);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Composition {
    weights: &'static [f64],
    order: u32,
}

/// `1/(2 − 2^{1/3})` and `−2^{1/3}/(2 − 2^{1/3})`.
const Y4: [f64; 3] = [1.351_207_191_959_657_8, -1.702_414_383_919_315_5, 1.351_207_191_959_657_8];

const Y6: [f64; 7] = [
    0.784_513_610_477_560,
    0.235_573_213_359_357,
    -1.177_679_984_178_87,
    1.315_186_320_683_906,
    -1.177_679_984_178_87,
    0.235_573_213_359_357,
    0.784_513_610_477_560,
];

// The published 20 digits (f64 rounds them).
#[allow(clippy::excessive_precision)]
const KL8: [f64; 15] = [
    0.74167036435061295345,
    -0.40910082580003159400,
    0.19075471029623837995,
    -0.57386247111608226666,
    0.29906418130365592384,
    0.33462491824529818378,
    0.31529309239676659663,
    -0.79688793935291635402,
    0.31529309239676659663,
    0.33462491824529818378,
    0.29906418130365592384,
    -0.57386247111608226666,
    0.19075471029623837995,
    -0.40910082580003159400,
    0.74167036435061295345,
];

impl Composition {
    /// Yoshida's (Suzuki's, Forest–Ruth's) 3-stage composition: order 4.
    pub const YOSHIDA4: Self = Self { weights: &Y4, order: 4 };
    /// Yoshida's 7-stage composition ("solution A"): order 6.
    pub const YOSHIDA6: Self = Self { weights: &Y6, order: 6 };
    /// Kahan & Li's 15-stage composition (`s15odr8`): order 8.
    pub const KAHAN_LI8: Self = Self { weights: &KL8, order: 8 };

    /// The sub-step weights `γ_1 … γ_m`.
    pub fn weights(&self) -> &'static [f64] {
        self.weights
    }

    /// The order of the composed map.
    pub fn order(&self) -> u32 {
        self.order
    }
}

/// What a composition keeps: the trapezoid sub-steps' memory and the
/// sub-steps of the last composed step.
#[derive(Debug)]
pub struct CompositionMemory<const N: usize> {
    /// Sub-stepped compositions: the last sub-step's memory. Fused explicit
    /// ones: the composed step as one segment `(t_k, h, q_k, Δq)` (the growth
    /// check and the predictor see whole steps), the mass matrix and the
    /// node force.
    pub(crate) inner: OnePointMemory<N>,
    /// The sub-steps of the last step (the first `stages` entries), when
    /// they were taken one by one in forward mode (reverse mode reads only
    /// the last one, `inner.previous`).
    pub(crate) substeps: [Segment<N>; MAX_STAGES],
    pub(crate) stages: usize,
    /// The size of the last composed step.
    pub(crate) last_h: Option<f64>,
    /// Fused explicit steps (see [`explicit_step`]): what rebuilds the last
    /// step's sub-steps, twice, so that a step writes into the spare one and
    /// a failed step leaves the last one intact; `None` until the first
    /// fused step.
    pub(crate) fused: Option<Box<[FusedSubsteps<N>; 2]>>,
    /// Which entry of `fused` holds the last step.
    pub(crate) fused_last: usize,
    /// Fused explicit steps in reverse mode: the last sub-step of the last
    /// step (the readouts' segment; `inner` holds whole steps), on the heap.
    pub(crate) last_fused: Option<LastSubstep>,
}

impl<const N: usize> Clone for CompositionMemory<N> {
    fn clone(&self) -> Self {
        Self {
            inner: self.inner.clone(),
            substeps: self.substeps,
            stages: self.stages,
            last_h: self.last_h,
            fused: self.fused.clone(),
            fused_last: self.fused_last,
            last_fused: self.last_fused.clone(),
        }
    }

    /// Field by field into the storage `self` has (see
    /// [`OnePointMemory`]'s `clone_from`).
    fn clone_from(&mut self, source: &Self) {
        let Self { inner, substeps, stages, last_h, fused, fused_last, last_fused } = self;
        inner.clone_from(&source.inner);
        *substeps = source.substeps;
        *stages = source.stages;
        *last_h = source.last_h;
        fused.clone_from(&source.fused);
        *fused_last = source.fused_last;
        last_fused.clone_from(&source.last_fused);
    }
}

/// The sub-steps of a fused explicit step: with the composed step's start
/// `(t_k, q_k)` (kept in `inner.previous`) they rebuild every sub-step's
/// segment exactly as the step computed it.
#[derive(Clone, Debug)]
pub(crate) struct FusedSubsteps<const N: usize> {
    /// The position's Kahan compensation at the start of the step.
    carry: [f64; N],
    /// Each sub-step's increment `δq_i`.
    increments: [[f64; N]; MAX_STAGES],
}

impl<const N: usize> CompositionMemory<N> {
    /// Reverse mode, whose sub-steps step the integrator's own memory: the
    /// last sub-step of the last composed step is the inner memory's last
    /// step (`None` before the first composed step).
    fn last_substep_in_place(&self) -> Option<Segment<N>> {
        if self.stages == 0 {
            return None;
        }
        match &self.last_fused {
            Some(last) => Some(last.segment()),
            None => self.inner.previous,
        }
    }

    /// Sub-step `i` of the last composed step, made with `weights` and
    /// `summation`.
    pub(crate) fn substep(&self, i: usize, weights: &[f64], summation: Summation) -> Segment<N> {
        let (Some(fused), Some(start), Some(h)) = (&self.fused, &self.inner.previous, self.last_h) else {
            return self.substeps[i];
        };
        let FusedSubsteps { carry, increments } = &fused[self.fused_last];
        // The sub-node positions and times of `explicit_step`: `q_k + (c_q +
        // Δq)`, or summed in place under plain summation.
        let plain = summation.is_plain();
        let (mut sum, mut elapsed) = (if plain { start.q0 } else { [0.0; N] }, 0.0);
        for (step_dq, gamma) in increments[..i].iter().zip(weights) {
            for j in 0..N {
                sum[j] += step_dq[j];
            }
            elapsed += gamma;
        }
        let (t0, q0) = match i {
            0 => (start.t0, start.q0),
            _ if plain => (start.t0 + elapsed * h, sum),
            _ => (start.t0 + elapsed * h, core::array::from_fn(|j| start.q0[j] + (carry[j] + sum[j]))),
        };
        Segment { t0, h: weights[i] * h, q0, dq: increments[i] }
    }
}

impl<S: Clone, const N: usize> Integrator<S, Composition, N> {
    /// A copy of this integrator, which has not stepped yet, composed with
    /// `method`'s weights: the start (the Legendre transform, the checks of
    /// the initial data and `M⁻¹` of an explicit system) is the trapezoid
    /// rule's and does not depend on the weights, so a copy serves every
    /// order without starting again. `None` once it has stepped.
    pub(crate) fn recomposed(&self, method: Composition) -> Option<Self> {
        (self.state.step == 0 && self.stats.steps == 0).then(|| {
            let mut it = self.clone();
            it.method = method;
            it
        })
    }

    /// `M⁻¹` of the constant mass matrix of an explicit system, formed at
    /// the start; `None` for other systems.
    pub(crate) fn inverse_mass(&self) -> Option<std::sync::Arc<nalgebra::SMatrix<f64, N, N>>> {
        self.memory.inner.explicit.as_ref().map(|cache| cache.inverse_mass.clone())
    }
}

impl sealed::Sealed for Composition {}

impl Method<f64> for Composition {
    type Memory<const N: usize> = CompositionMemory<N>;

    fn method_order(&self) -> u32 {
        self.order
    }

    fn memory<const N: usize>(&self) -> CompositionMemory<N> {
        let empty = Segment { t0: 0.0, h: 0.0, q0: [0.0; N], dq: [0.0; N] };
        CompositionMemory {
            inner: <Trapezoid as Method<f64>>::memory(&Trapezoid),
            substeps: [empty; MAX_STAGES],
            stages: 0,
            last_h: None,
            fused: None,
            fused_last: 0,
            last_fused: None,
        }
    }

    fn check(&self) -> Result<(), &'static str> {
        let sum: f64 = self.weights.iter().sum();
        if self.weights.is_empty() || self.weights.len() > MAX_STAGES || (sum - 1.0).abs() > 1e-12 {
            return Err("a composition needs 1 to 15 sub-step weights summing to 1");
        }
        Ok(())
    }

    fn supports<S: Lagrangian<N>, const N: usize>(&self, policy: &StepPolicy) -> Result<(), Error> {
        match policy {
            StepPolicy::Fixed => Ok(()),
            StepPolicy::EnergyPreserving(_) => Err(Error::Unsupported {
                what: "energy-preserving steps with a composition: its sub-steps have fixed ratios; use fixed steps",
            }),
        }
    }

    fn prefers_reverse<S: Lagrangian<N>, const N: usize>(&self, policy: &StepPolicy) -> bool {
        <Trapezoid as Method<f64>>::prefers_reverse::<S, N>(&Trapezoid, policy)
    }

    fn supports_derivatives<S: Lagrangian<N>, const N: usize>(
        &self,
        reverse: bool,
        policy: &StepPolicy,
    ) -> Result<(), Error> {
        <Trapezoid as Method<f64>>::supports_derivatives::<S, N>(&Trapezoid, reverse, policy)
    }

    fn legendre<S: Lagrangian<N>, const N: usize>(
        system: &S,
        t0: f64,
        q0: [f64; N],
        v0: [f64; N],
    ) -> Result<([f64; N], f64), Error> {
        <Trapezoid as Method<f64>>::legendre(system, t0, q0, v0)
    }

    fn start_memory<S: Lagrangian<N>, const N: usize>(
        &self,
        system: &S,
        t0: f64,
        q0: [f64; N],
        v0: [f64; N],
        memory: &mut CompositionMemory<N>,
    ) -> Result<([f64; N], f64), Error> {
        <Trapezoid as Method<f64>>::start_memory(&Trapezoid, system, t0, q0, v0, &mut memory.inner)
    }

    fn fixed_step<S: Lagrangian<N>, const N: usize>(
        it: &mut Integrator<S, Self, N>,
        h: f64,
        t1: f64,
    ) -> Result<(), Error> {
        // Explicit sub-steps in forward mode are fused (the energy watch of a
        // discontinuous system needs every sub-step's energy: sub-stepped).
        // As a constant: the fused code is not compiled for other systems.
        if const { Integrator::<S, Trapezoid, N>::EXPLICIT && !S::DISCONTINUOUS && !super::sparse::too_large_for_forward(N) }
            && !it.derivatives.reverse::<N>()
        {
            return fused_step(it, h, t1);
        }
        // `if const` on its own: codegen can skip the sub-integrator below for large N.
        if const { super::sparse::too_large_for_forward(N) } {
            return sparse_step(it, h, t1);
        }
        if it.derivatives.reverse::<N>() {
            return sparse_step(it, h, t1);
        }
        let before = it.state;
        let saved = (it.memory.inner.previous, it.memory.inner.earlier);
        let mut sub = Integrator {
            system: &it.system,
            method: Trapezoid,
            h,
            newton: it.newton,
            state: it.state,
            carry: it.carry,
            p_carry: it.p_carry,
            policy: StepPolicy::Fixed,
            fallback: it.fallback,
            energy: it.energy,
            energy_carry: it.energy_carry,
            time_error: it.time_error,
            watched_energy: it.watched_energy,
            // Moved out and back (it holds the reverse-mode work on the heap).
            memory: core::mem::replace(&mut it.memory.inner, <Trapezoid as Method<f64>>::memory(&Trapezoid)),
            v0: it.v0,
            clock: it.clock,
            stats: it.stats,
            derivatives: it.derivatives,
            summation: it.summation,
        };
        let mut substeps = it.memory.substeps;
        let stages = it.method.weights.len();
        let mut elapsed = 0.0;
        for (i, gamma) in it.method.weights.iter().enumerate() {
            let hi = gamma * h;
            elapsed += gamma;
            let ti = if i + 1 == stages { t1 } else { before.t + elapsed * h };
            if let Err(e) = sub.step_by(hi, ti) {
                // The node memory as it was; the heap caches (mass matrix,
                // reverse-mode work) stay, the node force (of a sub-node) does
                // not: the next step recomputes it, to the same bits.
                let Integrator { memory, .. } = sub;
                it.memory.inner = OnePointMemory { previous: saved.0, earlier: saved.1, ..memory };
                if let Some(cache) = it.memory.inner.explicit.as_deref_mut() {
                    cache.forget();
                }
                if let Some(work) = it.memory.inner.sparse.as_mut() {
                    work.forget_node_force();
                }
                it.stats.failed_steps += 1;
                return Err(e.at_state(before));
            }
            if let Some(seg) = sub.memory.previous {
                substeps[i] = seg;
            }
        }
        let Integrator { state, carry, p_carry, mut memory, stats, watched_energy, .. } = sub;
        // The explicit path's cached force belongs to the composed node now.
        if let Some(cache) = memory.explicit.as_deref_mut() {
            cache.rekey(state.step, before.step + 1);
        }
        if let Some(work) = memory.sparse.as_mut() {
            work.rekey_node_force(before.step + 1);
        }
        it.state = State { step: before.step + 1, ..state };
        it.carry = carry;
        it.p_carry = p_carry;
        it.watched_energy = watched_energy;
        it.memory.inner = memory;
        it.memory.substeps = substeps;
        it.memory.stages = stages;
        it.memory.last_h = Some(h);
        it.stats.steps += 1;
        it.stats.newton_iterations = stats.newton_iterations;
        it.stats.last = stats.last;
        // The energy watch of a discontinuous system saw every sub-step.
        it.stats.largest_energy_jump = stats.largest_energy_jump;
        it.stats.largest_energy_jump_at = stats.largest_energy_jump_at;
        Ok(())
    }

    fn last_step_size<const N: usize>(memory: &CompositionMemory<N>) -> Option<f64> {
        memory.last_h
    }

    /// The discrete energy of the last trapezoid sub-step (the energy the
    /// composed step ends with); the energy of the initial data at `k = 0`.
    fn discrete_energy<S: Lagrangian<N>, const N: usize>(it: &Integrator<S, Self, N>) -> f64 {
        if const { super::sparse::too_large_for_forward(N) } || it.derivatives.reverse::<N>() {
            return match it.memory.last_substep_in_place() {
                Some(last) => super::sparse::step_energy(&it.system, &Trapezoid, &last),
                None => it.energy,
            };
        }
        match it.memory.stages {
            0 => it.system.energy(it.state.t, it.state.q, it.v0),
            m => {
                let last = it.memory.substep(m - 1, it.method.weights, it.summation);
                -derivatives::end_time_derivative(&it.system, &Trapezoid, &last)
            }
        }
    }
}

impl F64Readouts for Composition {
    fn constant_mass_velocity<S: Lagrangian<N>, const N: usize>(it: &Integrator<S, Self, N>) -> Option<[f64; N]> {
        let mut v = [0.0; N];
        it.memory.inner.sparse.as_ref()?.constant_mass_velocity(&it.state.p, &mut v).then_some(v)
    }

    fn velocity_guess<S: Lagrangian<N>, const N: usize>(it: &Integrator<S, Self, N>) -> [f64; N] {
        if const { super::sparse::too_large_for_forward(N) } || it.derivatives.reverse::<N>() {
            return match it.memory.last_substep_in_place() {
                Some(last) => last.dq.map(|x| x / last.h),
                None => it.v0,
            };
        }
        match it.memory.stages {
            0 => it.v0,
            m => {
                let last = it.memory.substep(m - 1, it.method.weights, it.summation);
                last.dq.map(|x| x / last.h)
            }
        }
    }

    /// The product of the sub-steps' tangent maps.
    fn tangent_map<S: Lagrangian<N>, const N: usize>(it: &Integrator<S, Self, N>) -> Option<TangentMap<N>> {
        let m = it.memory.stages;
        // Not offered in reverse mode (a dense 2N × 2N matrix).
        if const { super::sparse::too_large_for_forward(N) } || m == 0 || it.derivatives.reverse::<N>() {
            return None;
        }
        let weights = it.method.weights;
        let mut product =
            symplectic::tangent_map(&it.system, &Trapezoid, &it.memory.substep(0, weights, it.summation))?.matrix();
        for i in 1..m {
            let seg = it.memory.substep(i, weights, it.summation);
            product = symplectic::tangent_map(&it.system, &Trapezoid, &seg)?.matrix() * product;
        }
        let block = |r: usize, c: usize| nalgebra::SMatrix::<f64, N, N>::from_fn(|a, b| product[(r + a, c + b)]);
        Some(TangentMap { dq_dq: block(0, 0), dq_dp: block(0, N), dp_dq: block(N, 0), dp_dp: block(N, N) })
    }

    /// The sum of the sub-steps' forcing impulses.
    fn forcing_impulse<S: Lagrangian<N>, const N: usize>(
        it: &Integrator<S, Self, N>,
        symmetry: &(impl crate::noether::Generator<N> + ?Sized),
    ) -> Option<f64> {
        let m = it.memory.stages;
        if const { super::sparse::too_large_for_forward(N) } || it.derivatives.reverse::<N>() {
            // Reverse mode refuses forces at `start`: no impulse.
            return (m > 0).then_some(0.0);
        }
        (m > 0).then(|| {
            (0..m)
                .map(|i| {
                    let seg = it.memory.substep(i, it.method.weights, it.summation);
                    crate::noether::forcing_impulse(&it.system, &Trapezoid, &seg, symmetry)
                })
                .sum()
        })
    }

    /// The sub-steps are not kept as one interpolant: dense output is the
    /// cubic Hermite through both nodes of the composed step.
    type Native<const N: usize> = Hermite<N>;

    fn native<S: Lagrangian<N>, const N: usize>(
        _: &Integrator<S, Self, N>,
        start: &Node<N>,
        end: &Node<N>,
    ) -> Hermite<N> {
        Hermite::cubic(start, end)
    }
}

/// A composed step in reverse mode: the trapezoid sub-steps step the
/// integrator's own fields ([`Stepper`]), with no sub-integrator and no
/// copies of the sub-steps (the readouts need only the last one, which is
/// `inner.previous`). A failed sub-step puts back the node, the last two
/// segments and the carries as they were before the composed step.
fn sparse_step<S: Lagrangian<N>, const N: usize>(
    it: &mut Integrator<S, Composition, N>,
    h: f64,
    t1: f64,
) -> Result<(), Error> {
    if const { Integrator::<S, Trapezoid, N>::EXPLICIT && !S::DISCONTINUOUS } {
        return sparse_fused_step(it, h, t1);
    }
    let before = it.state;
    let saved = (it.memory.inner.previous, it.memory.inner.earlier);
    if let Some(work) = it.memory.inner.sparse.as_mut() {
        work.save_carries();
    }
    // The sub-steps count into a copy: a composed step is one step.
    let mut stats = it.stats;
    let weights = it.method.weights;
    let mut elapsed = 0.0;
    for (i, gamma) in weights.iter().enumerate() {
        elapsed += gamma;
        let ti = if i + 1 == weights.len() { t1 } else { before.t + elapsed * h };
        let mut stepper = Stepper {
            system: &it.system,
            method: &Trapezoid,
            newton: &it.newton,
            v0: &it.v0,
            energy: it.energy,
            state: &mut it.state,
            memory: &mut it.memory.inner,
            stats: &mut stats,
            summation: it.summation,
        };
        if let Err(e) = stepper.step(gamma * h, ti, Integrator::<S, Trapezoid, N>::EXPLICIT) {
            it.state = before;
            (it.memory.inner.previous, it.memory.inner.earlier) = saved;
            if let Some(work) = it.memory.inner.sparse.as_mut() {
                // The node force of a sub-node: the next step recomputes it, to the same bits.
                work.forget_node_force();
                work.restore_carries();
            }
            it.stats.failed_steps += 1;
            return Err(e.at_state(before));
        }
    }
    if let Some(work) = it.memory.inner.sparse.as_mut() {
        // The cached node force belongs to the composed node now.
        work.rekey_node_force(before.step + 1);
        work.discard_saved_carries();
    }
    it.state.step = before.step + 1;
    it.memory.stages = weights.len();
    it.memory.last_h = Some(h);
    it.stats.steps += 1;
    it.stats.newton_iterations = stats.newton_iterations;
    it.stats.last = stats.last;
    // The energy watch of a discontinuous system saw every sub-step.
    it.stats.largest_energy_jump = stats.largest_energy_jump;
    it.stats.largest_energy_jump_at = stats.largest_energy_jump_at;
    Ok(())
}

/// A composed step on a system whose trapezoid sub-steps are explicit, in
/// reverse mode: the sub-steps fused on the reverse-mode work's buffers
/// (`SparseWork::verlet_composed`, the slice form of [`fused_step`], with
/// the same operations), checked and committed once; the readouts' last
/// sub-step is kept in `last_fused`. A failed step changes nothing
/// observable.
fn sparse_fused_step<S: Lagrangian<N>, const N: usize>(
    it: &mut Integrator<S, Composition, N>,
    h: f64,
    t1: f64,
) -> Result<(), Error> {
    let weights = it.method.weights;
    let mut stepper = Stepper {
        system: &it.system,
        method: &Trapezoid,
        newton: &it.newton,
        v0: &it.v0,
        energy: it.energy,
        state: &mut it.state,
        memory: &mut it.memory.inner,
        stats: &mut it.stats,
        summation: it.summation,
    };
    stepper.composed_step(h, t1, weights, &mut it.memory.last_fused)?;
    it.memory.stages = weights.len();
    it.memory.last_h = Some(h);
    Ok(())
}

/// A composed step on a system whose trapezoid sub-steps are explicit, in
/// forward mode: the sub-steps fused into one step on local arrays
/// ([`explicit_step`]), checked and committed once, their increments kept to
/// rebuild them for the readouts. A failed step changes nothing observable.
fn fused_step<S: Lagrangian<N>, const N: usize>(
    it: &mut Integrator<S, Composition, N>,
    h: f64,
    t1: f64,
) -> Result<(), Error> {
    let weights = it.method.weights;
    let spare = 1 - it.memory.fused_last;
    let fused = it.memory.fused.get_or_insert_with(|| {
        let empty = FusedSubsteps { carry: [0.0; N], increments: [[0.0; N]; MAX_STAGES] };
        Box::new([empty.clone(), empty])
    });
    let into = &mut fused[spare];
    into.carry = it.carry;
    let node = ExplicitNode { state: &it.state, carry: &it.carry, p_carry: &it.p_carry, v0: &it.v0 };
    let (inner, increments) = (&mut it.memory.inner, &mut into.increments);
    let taken = match it.summation {
        Summation::Compensated => explicit_step::<S, N, false>(&it.system, inner, node, h, t1, weights, increments),
        Summation::Plain => explicit_step::<S, N, true>(&it.system, inner, node, h, t1, weights, increments),
    };
    let taken = match taken {
        Ok(taken) => taken,
        Err(failure) => return Err(it.fail(h, failure)),
    };
    commit_explicit(
        &mut it.memory.inner,
        (&mut it.state, &mut it.carry, &mut it.p_carry, &mut it.stats),
        h,
        t1,
        &taken,
    );
    it.memory.fused_last = spare;
    it.memory.stages = weights.len();
    it.memory.last_h = Some(h);
    Ok(())
}
