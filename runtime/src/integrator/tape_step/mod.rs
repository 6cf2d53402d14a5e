//! The slice-based core of reverse-mode steps, shared by the const-size
//! integrator's reverse path (`sparse.rs`) and the run-time-sized
//! [`DynIntegrator`](crate::DynIntegrator) (`dynamic.rs`).
//!
//! ```text
//! record  A(q_k, Δq, h)  on the tape          (t_k a constant, Δq = q_{k+1} − q_k)
//! g = ∇A                 one reverse sweep    (O(ops))
//! H·S                    second-order sweep   (O(K·ops), K seed directions on Δq)
//! r   = p_k + ∂A/∂q_k|_{q_{k+1}} = p_k + g_{q_k} − g_{Δq}
//! J   = ∂r/∂Δq           = H_{q_k,Δq} − H_{Δq,Δq}
//! p_{k+1} = p_k + g_{q_k}|_{Δq}               (the momentum change at fixed increment)
//! E_{k+1} = −∂A/∂t_{k+1} = −g_h               (the discrete energy of the step)
//! ```
//!
//! Everything here works on slices of a length known at run time: the
//! state, the tape and the matrices live on the heap, and nothing on the
//! stack grows with the number of coordinates. A system and its discrete
//! Lagrangian enter only through [`TapeModel`] (`L` and the step action on
//! tape numbers), so both integrators take the same steps: the same
//! predictor input, Newton convergence rule, plausibility check, Kahan sums
//! and failure values.
//!
//! The parts: `implicit.rs` (the Newton step on the tape), `explicit.rs`
//! (Störmer–Verlet and the fused substeps of compositions for separable
//! systems), `directional.rs` (derivatives at the rule's points by seeded
//! dual lanes), `legendre.rs` (momentum, energy and velocity at a node, the
//! potential force, the discrete energy of a step), `galerkin.rs` (the
//! Galerkin rules' step at a run-time size), `forcing.rs` and
//! `galerkin_forces.rs` (the discrete forces of the one-point rules and of
//! the Galerkin rules), `energy.rs` (the energy equation of a trial step
//! and its slope, for energy-preserving steps at a run-time size); this
//! file holds the buffers they share and the growth check.

use super::{IMPLAUSIBLE_GROWTH, implausible_growth};
use crate::banded::{LinearSolveError, StepMatrix, StepSolver};
use crate::hyperdual::DualArray;
use crate::newton::{Breakdown, NewtonFailure, NewtonReport};
use crate::real::fold_max_abs;
use crate::structure::{Coupling, Pattern};
use crate::system::Scalar;
use crate::tape::{Seeds, Tape, TapeError, Var};
use num_dual::Dual64;
use std::sync::Arc;

mod directional;
mod energy;
mod explicit;
mod forcing;
mod galerkin;
mod galerkin_energy;
mod galerkin_forces;
mod galerkin_rule;
mod implicit;
mod legendre;
mod node_probes;

use directional::Directional;
use forcing::Forcing;

pub(crate) use directional::{distinct, point_position, point_time};
pub(crate) use energy::{EnergyBuffers, EnergyTerms};
pub(crate) use explicit::Mass;
pub(crate) use forcing::generalized_force;
pub(crate) use galerkin::{GalerkinWork, Rule};
pub(crate) use legendre::{energy, legendre, momentum, step_energy, velocity, velocity_derivatives, watch_energy_jump};

/// What the reverse-mode step functions need of a system and its discrete
/// Lagrangian: `L` and the step action evaluated on tape numbers.
pub(crate) trait TapeModel {
    /// The coupling pattern of the Hessian of `L` (proven, or general).
    fn coupling(&self) -> Coupling;
    /// `L(t, q, v)` with `q.len() == v.len() == n`.
    fn lagrangian(&self, t: Var, q: &[Var], v: &[Var]) -> Var;
    /// The step action `A(t0, h, q0, dq)` of the discrete Lagrangian.
    fn action(&self, t0: Var, h: Var, q0: &[Var], dq: &[Var]) -> Var;
    /// `∂L/∂q(t, q, 0)` into `out` from the system's generated adjoint code,
    /// returning `true`; `false` (nothing written) when it has none and the
    /// tape must be used. `zero` is `n` zeros, the velocity, kept by the
    /// caller so that no call allocates or clears one.
    fn gradient_q(&self, t: f64, q: &[f64], zero: &[f64], out: &mut [f64]) -> bool {
        let _ = (t, q, zero, out);
        false
    }
    /// [`gradient_q`](Self::gradient_q), returning `L(t, q, 0)` from the
    /// same generated code (`None`, nothing written, when it has none).
    fn value_gradient_q(&self, t: f64, q: &[f64], zero: &[f64], out: &mut [f64]) -> Option<f64> {
        let _ = (t, q, zero, out);
        None
    }
    /// Adds `∂L/∂q(t, q, 0)` to `out` and returns whether `L(t, q, 0)` is
    /// finite, from the system's generated code (`None`, nothing written,
    /// when it has none).
    fn add_gradient_q_at_rest(&self, t: f64, q: &[f64], out: &mut [f64]) -> Option<bool> {
        let _ = (t, q, out);
        None
    }
    /// `true` when `L` does not depend explicitly on time.
    fn autonomous(&self) -> bool;
    /// The rule's quadrature points `[c_1, c_2]`:
    /// `A = (h/2) Σ_j L(t_k + c_j h, q_k + c_j Δq, Δq/h)`, one evaluation
    /// of weight `h` when they coincide. `None` for a rule of another form.
    fn points(&self) -> Option<[f64; 2]>;
    /// `true` when the `gradient_qv_*` methods are the system's generated
    /// adjoint code: Newton steps then take their derivatives from it
    /// instead of the tape.
    fn has_gradient_qv(&self) -> bool;
    // `∂L/∂q`, `∂L/∂v` (called only when `has_gradient_qv`) and `L` at
    // `(t, q, v)`, one method per scalar the step code evaluates them on
    // (on the dual types, derivatives along the seeded directions): with no
    // generic method the trait is object-safe, so the step code takes
    // `&dyn TapeModel` and is compiled once, not once for every system and
    // rule (it was a fifth to a third of the LLVM IR of the test binaries).
    // Implementors write them with `scalar_methods!`; generic code calls
    // them through `ModelScalar`.
    fn gradient_qv_f64(&self, t: f64, q: &[f64], v: &[f64], out_q: &mut [f64], out_v: &mut [f64]);
    fn gradient_qv_dual(&self, t: Dual64, q: &[Dual64], v: &[Dual64], out_q: &mut [Dual64], out_v: &mut [Dual64]);
    fn gradient_qv_lanes3(&self, t: Lanes3, q: &[Lanes3], v: &[Lanes3], out_q: &mut [Lanes3], out_v: &mut [Lanes3]);
    fn gradient_qv_lanes5(&self, t: Lanes5, q: &[Lanes5], v: &[Lanes5], out_q: &mut [Lanes5], out_v: &mut [Lanes5]);
    fn lagrangian_f64(&self, t: f64, q: &[f64], v: &[f64]) -> f64;
    fn lagrangian_dual(&self, t: Dual64, q: &[Dual64], v: &[Dual64]) -> Dual64;
    fn lagrangian_lanes3(&self, t: Lanes3, q: &[Lanes3], v: &[Lanes3]) -> Lanes3;
    fn lagrangian_lanes5(&self, t: Lanes5, q: &[Lanes5], v: &[Lanes5]) -> Lanes5;
    /// `true` when the system has applied forces `Q(t, q, v)`
    /// (`force_*`); none by default.
    fn has_force(&self) -> bool {
        false
    }
    /// `true` when the system has a Rayleigh function `R(q, v)`
    /// ([`dissipation`](Self::dissipation)); none by default.
    fn has_dissipation(&self) -> bool {
        false
    }
    /// `R(q, v)` on tape numbers (called only when
    /// [`has_dissipation`](Self::has_dissipation)).
    fn dissipation(&self, q: &[Var], v: &[Var]) -> Var {
        let _ = (q, v);
        Var::constant(0.0)
    }
    // `Q(t, q, v)` into `f` (zeros on entry), one method per scalar as for
    // `L`, called only when `has_force`; generic code calls them through
    // `ModelScalar::force`.
    fn force_f64(&self, t: f64, q: &[f64], v: &[f64], f: &mut [f64]) {
        let _ = (t, q, v, f);
    }
    fn force_dual(&self, t: Dual64, q: &[Dual64], v: &[Dual64], f: &mut [Dual64]) {
        let _ = (t, q, v, f);
    }
    fn force_lanes3(&self, t: Lanes3, q: &[Lanes3], v: &[Lanes3], f: &mut [Lanes3]) {
        let _ = (t, q, v, f);
    }
    fn force_lanes5(&self, t: Lanes5, q: &[Lanes5], v: &[Lanes5], f: &mut [Lanes5]) {
        let _ = (t, q, v, f);
    }
}

/// Three directions of derivatives carried at once.
pub(crate) type Lanes3 = DualArray<[f64; 3]>;
/// Five directions of derivatives carried at once.
pub(crate) type Lanes5 = DualArray<[f64; 5]>;

/// A scalar the step code evaluates a [`TapeModel`] on: picks the
/// model's method for the type.
pub(crate) trait ModelScalar: Scalar {
    /// `∂L/∂q` and `∂L/∂v` at `(t, q, v)`.
    fn gradient_qv(model: &dyn TapeModel, t: Self, q: &[Self], v: &[Self], out_q: &mut [Self], out_v: &mut [Self]);
    /// `L(t, q, v)`.
    fn lagrangian(model: &dyn TapeModel, t: Self, q: &[Self], v: &[Self]) -> Self;
    /// `Q(t, q, v)` into `f` (zeros on entry).
    fn force(model: &dyn TapeModel, t: Self, q: &[Self], v: &[Self], f: &mut [Self]);
}

macro_rules! model_scalar {
    ($($ty:ty => $gradient:ident, $lagrangian:ident, $force:ident;)*) => {$(
        impl ModelScalar for $ty {
            #[inline(always)]
            fn force(model: &dyn TapeModel, t: Self, q: &[Self], v: &[Self], f: &mut [Self]) {
                model.$force(t, q, v, f)
            }

            #[inline(always)]
            fn gradient_qv(model: &dyn TapeModel, t: Self, q: &[Self], v: &[Self], out_q: &mut [Self], out_v: &mut [Self]) {
                model.$gradient(t, q, v, out_q, out_v)
            }

            #[inline(always)]
            fn lagrangian(model: &dyn TapeModel, t: Self, q: &[Self], v: &[Self]) -> Self {
                model.$lagrangian(t, q, v)
            }
        }
    )*};
}

model_scalar! {
    f64 => gradient_qv_f64, lagrangian_f64, force_f64;
    Dual64 => gradient_qv_dual, lagrangian_dual, force_dual;
    Lanes3 => gradient_qv_lanes3, lagrangian_lanes3, force_lanes3;
    Lanes5 => gradient_qv_lanes5, lagrangian_lanes5, force_lanes5;
}

/// The per-scalar methods of [`TapeModel`] for an implementor with generic
/// inherent methods `gradient_qv_generic` and `lagrangian_generic`.
macro_rules! scalar_methods {
    () => {
        fn gradient_qv_f64(&self, t: f64, q: &[f64], v: &[f64], out_q: &mut [f64], out_v: &mut [f64]) {
            self.gradient_qv_generic(t, q, v, out_q, out_v)
        }
        fn gradient_qv_dual(
            &self,
            t: num_dual::Dual64,
            q: &[num_dual::Dual64],
            v: &[num_dual::Dual64],
            out_q: &mut [num_dual::Dual64],
            out_v: &mut [num_dual::Dual64],
        ) {
            self.gradient_qv_generic(t, q, v, out_q, out_v)
        }
        fn gradient_qv_lanes3(
            &self,
            t: $crate::integrator::tape_step::Lanes3,
            q: &[$crate::integrator::tape_step::Lanes3],
            v: &[$crate::integrator::tape_step::Lanes3],
            out_q: &mut [$crate::integrator::tape_step::Lanes3],
            out_v: &mut [$crate::integrator::tape_step::Lanes3],
        ) {
            self.gradient_qv_generic(t, q, v, out_q, out_v)
        }
        fn gradient_qv_lanes5(
            &self,
            t: $crate::integrator::tape_step::Lanes5,
            q: &[$crate::integrator::tape_step::Lanes5],
            v: &[$crate::integrator::tape_step::Lanes5],
            out_q: &mut [$crate::integrator::tape_step::Lanes5],
            out_v: &mut [$crate::integrator::tape_step::Lanes5],
        ) {
            self.gradient_qv_generic(t, q, v, out_q, out_v)
        }
        fn lagrangian_f64(&self, t: f64, q: &[f64], v: &[f64]) -> f64 {
            self.lagrangian_generic(t, q, v)
        }
        fn lagrangian_dual(
            &self,
            t: num_dual::Dual64,
            q: &[num_dual::Dual64],
            v: &[num_dual::Dual64],
        ) -> num_dual::Dual64 {
            self.lagrangian_generic(t, q, v)
        }
        fn lagrangian_lanes3(
            &self,
            t: $crate::integrator::tape_step::Lanes3,
            q: &[$crate::integrator::tape_step::Lanes3],
            v: &[$crate::integrator::tape_step::Lanes3],
        ) -> $crate::integrator::tape_step::Lanes3 {
            self.lagrangian_generic(t, q, v)
        }
        fn lagrangian_lanes5(
            &self,
            t: $crate::integrator::tape_step::Lanes5,
            q: &[$crate::integrator::tape_step::Lanes5],
            v: &[$crate::integrator::tape_step::Lanes5],
        ) -> $crate::integrator::tape_step::Lanes5 {
            self.lagrangian_generic(t, q, v)
        }
    };
}
pub(crate) use scalar_methods;

/// The bandwidth of the step Jacobian `∂²A/∂q_k∂q_{k+1}` (and of `∂²L/∂v²`),
/// `None` when it is not proven banded: the widest of the three Hessian
/// blocks of `L`, since every one-point rule mixes them.
pub(crate) fn step_bandwidth(coupling: Coupling, n: usize) -> Option<usize> {
    narrower_than(coupling.overall(), n)
}

/// The bandwidth of the mass matrix `∂²L/∂v²`, `None` if not banded.
pub(crate) fn mass_bandwidth(coupling: Coupling, n: usize) -> Option<usize> {
    narrower_than(coupling.v_v, n)
}

/// A band as wide as the matrix is no band.
fn narrower_than(pattern: Pattern, n: usize) -> Option<usize> {
    pattern.bandwidth().filter(|&b| b.checked_mul(2).is_some_and(|w| w + 1 < n))
}

/// The Newton matrix for a step pattern with bandwidth `bandwidth` (`None`:
/// general): banded or dense by the banded module's measured rule.
fn step_matrix(n: usize, bandwidth: Option<usize>) -> Result<StepSolver, LinearSolveError> {
    StepSolver::for_pattern(n, bandwidth.map_or(Pattern::General, |b| Pattern::banded(n, b)))
}

/// A zeroed buffer of `len` numbers, or `TooLarge` instead of an abort.
fn zeroed(len: Option<usize>, n: usize) -> Result<Vec<f64>, LinearSolveError> {
    let too_large = LinearSolveError::TooLarge { n, per_column: len.unwrap_or(usize::MAX) / n.max(1) };
    let len = len.ok_or(too_large)?;
    let mut v = Vec::new();
    v.try_reserve_exact(len).map_err(|_| too_large)?;
    v.resize(len, 0.0);
    Ok(v)
}

/// Assembles `(i, j) ↦ entry` from `band` (row `i`'s `2b + 1` entries around
/// the diagonal, or the whole row when `bandwidth` is `None`) into `m`, then
/// factors it, refusing a singular or badly conditioned matrix.
fn assemble_and_factor(
    m: &mut StepSolver,
    n: usize,
    bandwidth: Option<usize>,
    band: &[f64],
    min_rcond: f64,
) -> Result<(), Breakdown> {
    let width = bandwidth.map_or(n, |b| 2 * b + 1);
    m.clear();
    for i in 0..n {
        let row = &band[i * width..(i + 1) * width];
        match bandwidth {
            Some(b) => {
                for (c, &x) in row.iter().enumerate() {
                    // Column i + c − b, skipping slots outside the matrix.
                    if let Some(j) = (i + c).checked_sub(b).filter(|&j| j < n) {
                        m.add(i, j, x).map_err(breakdown)?;
                    }
                }
            }
            None => {
                for (j, &x) in row.iter().enumerate() {
                    m.add(i, j, x).map_err(breakdown)?;
                }
            }
        }
    }
    m.factor(min_rcond).map_err(breakdown)?;
    Ok(())
}

/// A linear-algebra failure as a Newton breakdown.
pub(crate) fn breakdown(e: LinearSolveError) -> Breakdown {
    match e {
        LinearSolveError::Singular { rcond, .. } => Breakdown::Singular(rcond),
        LinearSolveError::NonFinite { quantity } => Breakdown::NonFinite(quantity),
        LinearSolveError::TooLarge { .. } => {
            Breakdown::Rejected("the buffers of a step of this size cannot be allocated")
        }
        _ => Breakdown::Rejected("the step matrix could not be assembled (internal error: please report)"),
    }
}

/// A tape failure as a Newton breakdown (none is expected: the runtime
/// never nests recordings, and generated code keeps no `Var`).
fn tape_breakdown(_: TapeError) -> Breakdown {
    Breakdown::Rejected(
        "the derivative tape failed (a recording inside `lagrangian`, or a value kept from another evaluation)",
    )
}

/// Why a step whose tape failed after Newton is refused.
const TAPE_FAILED: &str = "the derivative tape failed";

/// The seeds of the second-order sweep on the inputs `columns`.
fn seeds(columns: core::ops::Range<usize>, bandwidth: Option<usize>) -> Seeds<'static> {
    match bandwidth {
        Some(b) => Seeds::banded(columns, b),
        None => Seeds::dense(columns),
    }
}

/// The node a step starts from: `(k, t_k, q_k, p_k)` and the Kahan
/// compensations of `q_k` and `p_k`.
pub(crate) struct Node<'a> {
    pub(crate) step: u64,
    pub(crate) t: f64,
    pub(crate) q: &'a [f64],
    pub(crate) p: &'a [f64],
    pub(crate) q_carry: &'a [f64],
    pub(crate) p_carry: &'a [f64],
    /// [`Summation::Plain`](crate::Summation::Plain): the compensations are
    /// zero and stay so; a step neither reads them nor writes the
    /// [`Taken`] ones (the caller keeps its zeros).
    pub(crate) plain: bool,
}

/// What a step knows of the motion so far: the predicted increment, and the
/// last increment scaled to this step's size (`None` at the first step).
pub(crate) struct Guess<'a> {
    pub(crate) predictor: &'a [f64],
    pub(crate) last: Option<&'a [f64]>,
}

impl Guess<'_> {
    /// Refuses an increment `dq` from `q` that is implausibly large against
    /// the predicted and the last one (see [`implausible_growth`]).
    fn check(&self, dq: &[f64], q: &[f64], iterations: usize) -> Result<(), NewtonFailure> {
        match self.last {
            Some(last) if implausible_growth(dq, self.predictor, last, q) => {
                Err(NewtonFailure::Rejected { iterations, reason: IMPLAUSIBLE_GROWTH })
            }
            _ => Ok(()),
        }
    }
}

/// What the explicit step's growth check needs: the last increment and the
/// factor `h / h_last` that scales it to this step (`None` at the first
/// step), and the predictor, written out only when the cheap bound cannot
/// decide (see `SparseWork::growth_check`).
pub(crate) struct Growth<'a> {
    pub(crate) last: Option<(&'a [f64], f64)>,
    pub(crate) predict: &'a dyn Fn(&mut [f64]),
}

/// A step that converged and whose published values are finite; nothing of
/// the caller's state has changed yet.
pub(crate) struct Taken {
    pub(crate) dq: Vec<f64>,
    pub(crate) q1: Vec<f64>,
    pub(crate) q_carry: Vec<f64>,
    pub(crate) p1: Vec<f64>,
    pub(crate) p_carry: Vec<f64>,
    pub(crate) report: NewtonReport,
}

/// A fused composed explicit step ([`SparseWork::verlet_composed`]): the
/// composed step, and its last sub-step (the readouts' segment).
pub(crate) struct Composed {
    pub(crate) taken: Taken,
    pub(crate) last: LastSubstep,
}

/// The last sub-step `(t, h, q, δq)` of a fused composed step, on the heap
/// (its buffers are handed over by the step, not copied).
#[derive(Debug)]
pub(crate) struct LastSubstep {
    pub(crate) t0: f64,
    pub(crate) h: f64,
    pub(crate) q0: Vec<f64>,
    pub(crate) dq: Vec<f64>,
}

impl Clone for LastSubstep {
    fn clone(&self) -> Self {
        Self { t0: self.t0, h: self.h, q0: self.q0.clone(), dq: self.dq.clone() }
    }

    fn clone_from(&mut self, source: &Self) {
        (self.t0, self.h) = (source.t0, source.h);
        self.q0.clone_from(&source.q0);
        self.dq.clone_from(&source.dq);
    }
}

/// The buffers of [`SparseWork::composed_into`] besides the step's own: the
/// running force, `Δp`, and the last sub-step's start and increment.
struct ComposedScratch<'a> {
    f: &'a mut Vec<f64>,
    dp: &'a mut Vec<f64>,
    last_q0: &'a mut Vec<f64>,
    last_dq: &'a mut Vec<f64>,
}

/// The heap-side work of reverse-mode steps: the tape and the buffers of its
/// sweeps (scratch, rebuilt when cloned), and what persists between steps.
#[derive(Debug)]
pub(crate) struct SparseWork {
    n: usize,
    bandwidth: Option<usize>,
    tape: Tape,
    /// The tape's inputs `(q_k, Δq, h)` (empty until the tape is used:
    /// Newton steps from the gradient code do not need it, nor `products`
    /// and `end`).
    inputs: Vec<f64>,
    gradient: Vec<f64>,
    /// `H·S`, inputs × directions.
    products: Vec<f64>,
    /// The blocks `∂²A/∂q_k∂Δq` and `∂²A/∂Δq²` in band (or dense row) storage.
    mixed: Vec<f64>,
    end: Vec<f64>,
    jacobian: StepSolver,
    /// `E_{k+1} = −∂A/∂t_{k+1}` of the last step, when it was computed.
    pub(crate) energy: Option<f64>,
    /// Explicit path: the factored constant mass matrix, shared by clones
    /// (it never changes once factored, and a `solve` refreshes a copy of
    /// the integrator before every step).
    mass: Option<Arc<Mass>>,
    /// Explicit path: `(k, ∂L/∂q(t_k, q_k, 0))`.
    node_force: Option<(u64, Vec<f64>)>,
    /// Explicit path: the zero velocity of `∂L/∂q(t, q, 0)`, for the
    /// generated gradient and on the tape.
    zero: (Vec<f64>, Vec<Var>),
    /// Length-`n` buffers handed out for [`Taken`] and forces and given back
    /// by the integrators after a commit, so that steps do not allocate.
    spare: Vec<Vec<f64>>,
    /// The buffers of Newton steps from the generated gradient code (empty
    /// until the first such step).
    directional: Directional,
    /// The buffers of the discrete forces (empty until the first forced step).
    forcing: Forcing,
    /// A const-size integrator's Kahan compensations of `q_k` and `p_k` in
    /// reverse mode (its inline `carry` and `p_carry` stay zero): on the
    /// heap, a step's new ones are swapped in, not copied (see
    /// `sparse.rs`). Zero at the start, like the integrator's.
    pub(crate) carries: [Vec<f64>; 2],
    /// [`carries`](Self::carries) as [`save_carries`](Self::save_carries)
    /// found them, for a composed step to restore on failure.
    saved_carries: Option<[Vec<f64>; 2]>,
    /// The coordinate of the largest `|q|` when the growth check last took
    /// the maxima: its `|q_k|` is the lower bound of `max|q_k|` of
    /// [`growth_bound`](Self::growth_bound) (a hint: any coordinate gives a
    /// bound that decides the same verdict).
    growth_index: usize,
}

/// How many spare buffers [`SparseWork`] keeps: a step takes at most eight,
/// and a composed step keeps two saved carries.
const SPARE_BUFFERS: usize = 12;

impl Clone for SparseWork {
    fn clone(&self) -> Self {
        Self {
            n: self.n,
            bandwidth: self.bandwidth,
            tape: Tape::new(),
            inputs: self.inputs.clone(),
            gradient: self.gradient.clone(),
            products: self.products.clone(),
            mixed: self.mixed.clone(),
            end: self.end.clone(),
            jacobian: self.jacobian.clone(),
            energy: self.energy,
            mass: self.mass.clone(),
            node_force: self.node_force.clone(),
            zero: self.zero.clone(),
            spare: Vec::new(),
            directional: Directional::default(),
            forcing: Forcing::default(),
            carries: self.carries.clone(),
            saved_carries: self.saved_carries.clone(),
            growth_index: self.growth_index,
        }
    }

    /// Copies what persists between steps into the buffers `self` already
    /// has, and leaves its scratch (the tape, the step matrix, the spare
    /// and directional buffers: filled afresh by every step) as it is: a
    /// `solve` that may have to go back refreshes its copy of the
    /// integrator this way before every step, without allocating.
    fn clone_from(&mut self, source: &Self) {
        if (self.n, self.bandwidth) != (source.n, source.bandwidth) {
            *self = source.clone();
            return;
        }
        self.inputs.clone_from(&source.inputs);
        self.gradient.clone_from(&source.gradient);
        self.products.clone_from(&source.products);
        self.mixed.clone_from(&source.mixed);
        self.end.clone_from(&source.end);
        self.energy = source.energy;
        self.mass.clone_from(&source.mass);
        match (&mut self.node_force, &source.node_force) {
            (Some((k, f)), Some((source_k, source_f))) => {
                *k = *source_k;
                f.clone_from(source_f);
            }
            (to, from) => to.clone_from(from),
        }
        self.zero.0.clone_from(&source.zero.0);
        self.zero.1.clone_from(&source.zero.1);
        self.carries.clone_from(&source.carries);
        match (&mut self.saved_carries, &source.saved_carries) {
            (Some(to), Some(from)) => to.clone_from(from),
            (to, from) => to.clone_from(from),
        }
        self.growth_index = source.growth_index;
    }
}

impl SparseWork {
    /// Work for the steps of a system with `n` coordinates and the given
    /// coupling: the action's inputs are `(q_k, Δq, h)`, the seeds sit on
    /// `Δq`. A size whose buffers cannot be allocated is an error, not an
    /// abort.
    pub(crate) fn new(n: usize, coupling: Coupling) -> Result<Self, LinearSolveError> {
        let bandwidth = step_bandwidth(coupling, n);
        let width = bandwidth.map_or(n, |b| 2 * b + 1);
        let inputs = n.checked_mul(2).and_then(|x| x.checked_add(1));
        Ok(Self {
            n,
            bandwidth,
            tape: Tape::new(),
            inputs: Vec::new(),
            gradient: zeroed(inputs, n)?,
            products: Vec::new(),
            mixed: zeroed(n.checked_mul(width), n)?,
            end: Vec::new(),
            jacobian: step_matrix(n, bandwidth)?,
            energy: None,
            mass: None,
            node_force: None,
            zero: (vec![0.0; n], vec![Var::constant(0.0); n]),
            spare: Vec::new(),
            directional: Directional::default(),
            forcing: Forcing::default(),
            carries: [zeroed(Some(n), n)?, zeroed(Some(n), n)?],
            saved_carries: None,
            growth_index: 0,
        })
    }

    /// A length-`n` buffer of unspecified contents (a spare one if any).
    fn buffer(&mut self) -> Vec<f64> {
        self.spare.pop().unwrap_or_else(|| vec![0.0; self.n])
    }

    /// Gives a buffer back for later steps (dropped unless it has length `n`
    /// and there is room).
    pub(crate) fn recycle(&mut self, buffer: Vec<f64>) {
        if buffer.len() == self.n && self.spare.len() < SPARE_BUFFERS {
            self.spare.push(buffer);
        }
    }

    /// Gives the buffers of a step back (a step the caller did not commit,
    /// or one whose values it copied).
    pub(crate) fn recycle_taken(&mut self, taken: Taken) {
        let Taken { dq, q1, q_carry, p1, p_carry, .. } = taken;
        for buffer in [dq, q1, q_carry, p1, p_carry] {
            self.recycle(buffer);
        }
    }

    /// Keeps a copy of [`carries`](Self::carries) for
    /// [`restore_carries`](Self::restore_carries) (a composed step's
    /// sub-steps advance them before the composed step is known to succeed).
    pub(crate) fn save_carries(&mut self) {
        let mut saved = [self.buffer(), self.buffer()];
        for (copy, carry) in saved.iter_mut().zip(&self.carries) {
            copy.copy_from_slice(carry);
        }
        self.discard_saved_carries();
        self.saved_carries = Some(saved);
    }

    /// Puts back the carries [`save_carries`](Self::save_carries) kept, or
    /// zeros (those of an integrator's start) when it kept none.
    pub(crate) fn restore_carries(&mut self) {
        match self.saved_carries.take() {
            Some(saved) => {
                for buffer in core::mem::replace(&mut self.carries, saved) {
                    self.recycle(buffer);
                }
            }
            None => self.carries.iter_mut().for_each(|c| c.fill(0.0)),
        }
    }

    /// Drops the carries [`save_carries`](Self::save_carries) kept.
    pub(crate) fn discard_saved_carries(&mut self) {
        for buffer in self.saved_carries.take().into_iter().flatten() {
            self.recycle(buffer);
        }
    }

    /// The cached node force now belongs to node `step` (a composed step's
    /// last sub-node is its end node).
    pub(crate) fn rekey_node_force(&mut self, step: u64) {
        if let Some((k, _)) = self.node_force.as_mut() {
            *k = step;
        }
    }

    /// Drops the cached node force and energy (after a failed composed step).
    pub(crate) fn forget_node_force(&mut self) {
        self.node_force = None;
        self.energy = None;
    }

    /// Sizes the buffers of the tape's sweeps (once, at the first step that
    /// records one): at `N = 100 000` and bandwidth 1 they are 8.8 MB that
    /// steps from the gradient code never touch.
    fn tape_buffers(&mut self) -> Result<(), LinearSolveError> {
        let n = self.n;
        if self.inputs.is_empty() {
            let width = self.bandwidth.map_or(n, |b| 2 * b + 1);
            let inputs = n.checked_mul(2).and_then(|x| x.checked_add(1));
            let directions = seeds(n..2 * n, self.bandwidth).directions();
            self.products = zeroed(inputs.and_then(|i| i.checked_mul(directions)), n)?;
            self.end = zeroed(n.checked_mul(width), n)?;
            self.inputs = zeroed(inputs, n)?;
        }
        Ok(())
    }

    /// A [`Taken`] around the increment `dq`, its other buffers spare ones.
    fn taken(&mut self, dq: Vec<f64>, report: NewtonReport) -> Taken {
        let (q1, q_carry, p1, p_carry) = (self.buffer(), self.buffer(), self.buffer(), self.buffer());
        Taken { dq, q1, q_carry, p1, p_carry, report }
    }

    /// The growth check's early bound `1e6·(1e-6·|q_j|)` at the coordinate
    /// `j` of the largest `|q|` when the maxima were last taken (`+∞` when
    /// there is no last increment and nothing is checked): rounding is
    /// monotone and `|q_j| ≤ max|q|`, so an increment whose every `|Δq_i|`
    /// is at most this bound passes [`growth_check`](Self::growth_check)'s
    /// early bound, and the maxima are taken
    /// ([`growth_check_at`](Self::growth_check_at)) only for one beyond it.
    /// A NaN bound is `−∞`, beyond which every increment is.
    fn growth_bound(&self, growth: &Growth<'_>, q: &[f64]) -> f64 {
        if growth.last.is_none() {
            return f64::INFINITY;
        }
        let bound = q.get(self.growth_index).map_or(0.0, |x| 1e6 * (1e-6 * x.abs()));
        if bound.is_nan() { f64::NEG_INFINITY } else { bound }
    }

    /// [`growth_check`](Self::growth_check) of the increment `dq` from `q`
    /// with the maxima taken here, keeping the coordinate of the largest
    /// `|q|` for the next [`growth_bound`](Self::growth_bound).
    fn growth_check_at(&mut self, growth: &Growth<'_>, dq: &[f64], q: &[f64]) -> Result<(), NewtonFailure> {
        // The first largest `|q_i|`, NaN ignored: the maximum
        // `fold_max_abs` returns.
        let (mut index, mut q_max) = (0, 0.0);
        for (i, x) in q.iter().enumerate() {
            if x.abs() > q_max {
                (index, q_max) = (i, x.abs());
            }
        }
        self.growth_index = index;
        self.growth_check(growth, dq, q, fold_max_abs(dq), q_max)
    }

    /// [`implausible_growth`] of the increment `dq` from `q`, whose largest
    /// magnitudes are `dq_max` and `q_max`. Rounding is monotone, so the
    /// check's threshold `1e6·max(scale, 1e-6·max|q|)` is at least
    /// `1e6·(1e-6·max|q|)` as computed: an increment below that bound (every
    /// step of motion away from the origin) passes without the predictor or
    /// the scaled last increment, and the verdict is the same as the full
    /// check's.
    fn growth_check(
        &mut self,
        growth: &Growth<'_>,
        dq: &[f64],
        q: &[f64],
        dq_max: f64,
        q_max: f64,
    ) -> Result<(), NewtonFailure> {
        let Some((last, factor)) = growth.last else { return Ok(()) };
        if dq_max <= 1e6 * (1e-6 * q_max) {
            return Ok(());
        }
        let (mut predicted, mut scaled) = (self.buffer(), self.buffer());
        (growth.predict)(&mut predicted);
        for (s, x) in scaled.iter_mut().zip(last) {
            *s = x * factor;
        }
        let implausible = implausible_growth(dq, &predicted, &scaled, q);
        self.recycle(predicted);
        self.recycle(scaled);
        if implausible { Err(NewtonFailure::Rejected { iterations: 0, reason: IMPLAUSIBLE_GROWTH }) } else { Ok(()) }
    }
}

/// A vector of `len` copies of `value`, or `TooLarge` instead of an abort.
fn filled<T: Clone>(len: usize, value: T) -> Result<Vec<T>, LinearSolveError> {
    let mut v = Vec::new();
    v.try_reserve_exact(len).map_err(|_| LinearSolveError::TooLarge { n: len, per_column: 1 })?;
    v.resize(len, value);
    Ok(v)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::real::max_abs;

    /// The growth check's early bound never changes the verdict of the full
    /// `implausible_growth`: increments around the threshold, positions from
    /// zero up, with and without a last increment.
    #[test]
    fn the_growth_bound_agrees_with_the_full_check() {
        let n = 5;
        let mut work = SparseWork::new(n, Coupling::GENERAL).unwrap();
        let mut next = crate::real::uniform_stream(0x2545_f491_4f6c_dd1d_u64);
        let (mut rejected, mut passed) = (0, 0);
        for case in 0..4000 {
            let scale = [0.0, 1e-9, 1e-3, 1.0][case % 4];
            let q: Vec<f64> = (0..n).map(|_| scale * next()).collect();
            let last: Vec<f64> = (0..n).map(|_| 1e-6 * next()).collect();
            let predicted: Vec<f64> = (0..n).map(|_| 1e-6 * next()).collect();
            let size = 10f64.powf(6.0 * next() + (case % 3) as f64 - 1.0);
            let dq: Vec<f64> = (0..n).map(|_| size * next()).collect();
            let factor = 1.0 + next();
            let scaled: Vec<f64> = last.iter().map(|x| x * factor).collect();
            let predict = |out: &mut [f64]| out.copy_from_slice(&predicted);
            let growth = Growth { last: Some((&last, factor)), predict: &predict };
            let fast = work.growth_check(&growth, &dq, &q, max_abs(&dq), max_abs(&q)).is_err();
            assert_eq!(fast, implausible_growth(&dq, &predicted, &scaled, &q), "case {case}");
            if fast {
                rejected += 1
            } else {
                passed += 1
            }
            let first = Growth { last: None, predict: &predict };
            assert!(work.growth_check(&first, &dq, &q, max_abs(&dq), max_abs(&q)).is_ok());
        }
        // Both verdicts occur, so the comparison tested something.
        assert!(rejected > 100 && passed > 100, "{rejected} rejected, {passed} passed");
    }

    /// An increment the drift pass finds within the bound at any
    /// coordinate's `|q|` passes the early bound of the full check, so that
    /// skipping the maxima never changes a verdict; and the full check with
    /// the maxima taken agrees with `implausible_growth`.
    #[test]
    fn an_increment_within_the_drift_bound_passes_the_growth_check() {
        use explicit::{beyond_bits, beyond_bound};
        let n = 5;
        let mut work = SparseWork::new(n, Coupling::GENERAL).unwrap();
        let mut next = crate::real::uniform_stream(0x9e37_79b9_7f4a_7c15_u64);
        let (mut within, mut beyond) = (0, 0);
        for case in 0..4000 {
            let scale = [0.0, 1e-9, 1e-3, 1.0][case % 4];
            let mut q: Vec<f64> = (0..n).map(|_| scale * next()).collect();
            if case % 7 == 0 {
                q[case % n] = f64::NAN;
            }
            let last: Vec<f64> = (0..n).map(|_| 1e-6 * next()).collect();
            let predicted: Vec<f64> = (0..n).map(|_| 1e-6 * next()).collect();
            let size = scale * 10f64.powf(2.0 * next());
            let mut dq: Vec<f64> = (0..n).map(|_| size * next()).collect();
            if case % 11 == 0 {
                dq[case % n] = [f64::NAN, f64::INFINITY, -0.0][case % 3];
            }
            let factor = 1.0 + next();
            let scaled: Vec<f64> = last.iter().map(|x| x * factor).collect();
            let predict = |out: &mut [f64]| out.copy_from_slice(&predicted);
            let growth = Growth { last: Some((&last, factor)), predict: &predict };
            work.growth_index = case % n;
            let bound = work.growth_bound(&growth, &q);
            let bits = dq.iter().fold(0, |bits, &x| bits | beyond_bits(bound, x));
            if beyond_bound(bits) {
                beyond += 1;
                let full = work.growth_check_at(&growth, &dq, &q).is_err();
                assert_eq!(full, implausible_growth(&dq, &predicted, &scaled, &q), "case {case}");
                assert!(q[work.growth_index].is_nan() || q[work.growth_index].abs() == max_abs(&q), "case {case}");
            } else {
                within += 1;
                assert!(max_abs(&dq) <= 1e6 * (1e-6 * max_abs(&q)), "case {case}");
                assert!(work.growth_check(&growth, &dq, &q, max_abs(&dq), max_abs(&q)).is_ok(), "case {case}");
            }
            let first = Growth { last: None, predict: &predict };
            assert!(work.growth_check_at(&first, &dq, &q).is_ok(), "case {case}");
        }
        assert!(within > 100 && beyond > 100, "{within} within, {beyond} beyond");
    }
}
