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

use core::cell::RefCell;

use num_dual::Dual64;

use super::{IMPLAUSIBLE_GROWTH, Stats, implausible_growth};
use crate::banded::{LinearSolveError, StepMatrix, StepSolver};
use crate::hyperdual::DualArray;
use crate::newton::{self, Breakdown, Jacobian, Linearization, NewtonFailure, NewtonOptions, NewtonReport, Unknown};
use crate::real::{all_finite, max_abs};
use crate::real::{fold_max_abs, is_non_finite, kahan_add as kahan, kahan_into, nan_bits};
use crate::structure::{Coupling, Pattern};
use crate::system::Scalar;
use crate::tape::{Seeds, Tape, TapeError, Var};

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
    /// `true` when `L` does not depend explicitly on time.
    fn autonomous(&self) -> bool;
    /// The rule's quadrature points `[c_1, c_2]`:
    /// `A = (h/2) Σ_j L(t_k + c_j h, q_k + c_j Δq, Δq/h)`, one evaluation
    /// of weight `h` when they coincide. `None` for a rule of another form.
    fn points(&self) -> Option<[f64; 2]>;
    /// `true` when [`gradient_qv`](Self::gradient_qv) is the system's
    /// generated adjoint code, generic over the scalar: Newton steps then
    /// take their derivatives from it instead of the tape.
    fn has_gradient_qv(&self) -> bool;
    /// `∂L/∂q` and `∂L/∂v` at `(t, q, v)` on any scalar (on `Dual64`, the
    /// Hessian-vector products along the seeded direction). Called only when
    /// [`has_gradient_qv`](Self::has_gradient_qv).
    fn gradient_qv<D: Scalar>(&self, t: D, q: &[D], v: &[D], out_q: &mut [D], out_v: &mut [D]);
    /// `L(t, q, v)` on any scalar.
    fn lagrangian_scalar<D: Scalar>(&self, t: D, q: &[D], v: &[D]) -> D;
}

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
#[derive(Clone, Debug)]
pub(crate) struct LastSubstep {
    pub(crate) t0: f64,
    pub(crate) h: f64,
    pub(crate) q0: Vec<f64>,
    pub(crate) dq: Vec<f64>,
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
    /// Explicit path: the factored constant mass matrix.
    mass: Option<Mass>,
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
    /// A const-size integrator's Kahan compensations of `q_k` and `p_k` in
    /// reverse mode (its inline `carry` and `p_carry` stay zero): on the
    /// heap, a step's new ones are swapped in, not copied (see
    /// `sparse.rs`). Zero at the start, like the integrator's.
    pub(crate) carries: [Vec<f64>; 2],
    /// [`carries`](Self::carries) as [`save_carries`](Self::save_carries)
    /// found them, for a composed step to restore on failure.
    saved_carries: Option<[Vec<f64>; 2]>,
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
            carries: self.carries.clone(),
            saved_carries: self.saved_carries.clone(),
        }
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
            carries: [zeroed(Some(n), n)?, zeroed(Some(n), n)?],
            saved_carries: None,
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

    /// Records the action `A(q_k, Δq, h)` at `t_k = t0` on the tape
    /// ([`tape_buffers`](Self::tape_buffers) must have been called).
    fn record_action<Mo: TapeModel>(
        &mut self,
        model: &Mo,
        t0: f64,
        h: f64,
        q0: &[f64],
        dq: &[f64],
    ) -> Result<f64, TapeError> {
        let n = self.n;
        self.inputs[..n].copy_from_slice(q0);
        self.inputs[n..2 * n].copy_from_slice(dq);
        self.inputs[2 * n] = h;
        self.tape.record(&self.inputs, |x: &[Var]| model.action(Var::constant(t0), x[2 * n], &x[..n], &x[n..2 * n]))
    }

    /// One implicit step of size `h` from `node`, ending at time `t1`:
    /// Newton on the DEL with banded or dense solves, then the momentum
    /// change and the step's discrete energy (returned with the step) from
    /// one more reverse sweep.
    pub(crate) fn newton_step<Mo: TapeModel>(
        &mut self,
        model: &Mo,
        node: &Node<'_>,
        h: f64,
        t1: f64,
        guess: &Guess<'_>,
        options: &NewtonOptions,
    ) -> Result<(Taken, f64), NewtonFailure> {
        let (dq, report) = self.solve(model, node, h, guess, options)?;
        let n = self.n;
        // The momentum change at fixed increment, the step's energy and
        // whether its action is finite.
        let (energy, action_finite) = match directional_points(model) {
            Some(points) => {
                self.directional.momentum_and_energy(model, node.t, h, points, node.q, &dq, &mut self.gradient[..n])
            }
            None => {
                let swept = match self.tape_buffers() {
                    Ok(()) => self
                        .record_action(model, node.t, h, node.q, &dq)
                        .and_then(|action| self.tape.gradient(&mut self.gradient).map(|()| action)),
                    Err(_) => Err(TapeError::TooLarge),
                };
                let Ok(action) = swept else {
                    self.recycle(dq);
                    return Err(NewtonFailure::Rejected { iterations: report.iterations, reason: TAPE_FAILED });
                };
                (-self.gradient[2 * n], action.is_finite())
            }
        };
        if !action_finite {
            self.recycle(dq);
            return Err(NewtonFailure::NonFinite { iterations: report.iterations, quantity: "lagrangian" });
        }
        let mut taken = self.taken(dq, report);
        if node.plain {
            let (q0, p0, dp) = (&node.q[..n], &node.p[..n], &self.gradient[..n]);
            let (dq, q1, p1) = (&taken.dq[..n], &mut taken.q1[..n], &mut taken.p1[..n]);
            for i in 0..n {
                q1[i] = q0[i] + dq[i];
                p1[i] = p0[i] + dp[i];
            }
        } else {
            kahan_into(node.q, node.q_carry, &taken.dq, &mut taken.q1, &mut taken.q_carry);
            kahan_into(node.p, node.p_carry, &self.gradient[..n], &mut taken.p1, &mut taken.p_carry);
        }
        if let Some(quantity) = super::non_finite(t1, &taken.q1, &taken.p1) {
            self.recycle_taken(taken);
            return Err(NewtonFailure::NonFinite { iterations: report.iterations, quantity });
        }
        Ok((taken, energy))
    }

    /// Newton on `r(Δq) = p_k + ∂A/∂q_k = 0` with banded or dense solves:
    /// the residual and the Jacobian from the generated gradient code on
    /// dual numbers (forward over reverse) when the system has it and the
    /// rule has quadrature points, from the tape otherwise. No iteration
    /// allocates: the iterate and the correction are the work's buffers.
    fn solve<Mo: TapeModel>(
        &mut self,
        model: &Mo,
        node: &Node<'_>,
        h: f64,
        guess: &Guess<'_>,
        options: &NewtonOptions,
    ) -> Result<(Vec<f64>, NewtonReport), NewtonFailure> {
        let n = self.n;
        let (q0, p0, pc) = (node.q, node.p, node.p_carry);
        let bandwidth = self.bandwidth;
        let min_rcond = options.min_rcond;
        // Newton's rounding floor for the increment: that of the positions.
        let q_floor = 4.0 * f64::EPSILON * max_abs(q0);
        let points = directional_points(model);
        if points.is_some() {
            self.directional.allocate(n, bandwidth, model.autonomous()).map_err(|e| breakdown(e).at(0))?;
        }
        let mut x = self.buffer();
        x.copy_from_slice(&guess.predictor[..n]);
        let (x, correction) = (RefCell::new(x), RefCell::new(self.buffer()));
        // The condition estimate (a few solves, 1.5–3.6 times a banded
        // factor+solve) on the first iteration of the step only: the Jacobian
        // barely changes within a step; later iterations still refuse a zero
        // or non-finite pivot.
        let mut first = true;
        let linearize = |iterate: &Slot<'_>, jacobian: Jacobian| -> Result<Linearization<Slot<'_>>, Breakdown> {
            let x = iterate.0.borrow();
            let mut r = correction.borrow_mut();
            // `r` first holds `∂A/∂q_k|_{q_{k+1}}`, then the residual.
            match points {
                // A kept Jacobian: the residual alone, in `f64`.
                Some(points) if jacobian == Jacobian::Kept => {
                    self.directional.residual(model, node.t, h, points, q0, &x, &mut r)
                }
                Some(points) => {
                    self.directional.linearize(model, node.t, h, points, q0, &x, bandwidth, &mut r, &mut self.mixed)
                }
                None => self.tape_linearize(model, node.t, h, q0, &x, &mut r, jacobian)?,
            }
            let mut scale = max_abs(p0);
            for i in 0..n {
                let d_q0 = r[i];
                r[i] = (p0[i] + d_q0) + pc[i];
                scale = scale.max(d_q0.abs());
            }
            if !r.iter().all(|x| x.is_finite()) {
                return Err(Breakdown::NonFinite("residual"));
            }
            // Where Newton lets it, the factors of the last iterate's
            // Jacobian are kept (simplified Newton; the first request of a
            // solve is always for a fresh one).
            if jacobian == Jacobian::Fresh {
                let rcond_floor = if first { min_rcond } else { 0.0 };
                first = false;
                assemble_and_factor(&mut self.jacobian, n, bandwidth, &self.mixed, rcond_floor)?;
            }
            let residual_norm = max_abs(&r);
            self.jacobian.solve(&mut r).map_err(breakdown)?;
            for x in r.iter_mut() {
                *x = -*x;
            }
            let lin = Linearization::new(Slot(&correction), residual_norm).cancelling(scale).floor(q_floor);
            Ok(if jacobian == Jacobian::Kept { lin.kept() } else { lin })
        };
        let solved = newton::solve(Slot(&x), options, linearize).map(|(_, report)| report);
        self.recycle(correction.into_inner());
        let dq = x.into_inner();
        let checked = solved.and_then(|report| guess.check(&dq, q0, report.iterations).map(|()| report));
        match checked {
            Ok(report) => Ok((dq, report)),
            Err(failure) => {
                self.recycle(dq);
                Err(failure)
            }
        }
    }

    /// The tape's linearisation at the increment `dq`: `∂A/∂q_k|_{q_{k+1}} =
    /// g_{q_k} − g_{Δq}` into `d_q0` and, for a fresh `jacobian`,
    /// `J = ∂²A/∂q_k∂Δq − ∂²A/∂Δq²` into `mixed`, from one recording and one
    /// compressed second-order sweep (a kept one: one reverse sweep, no
    /// second-order products).
    #[allow(clippy::too_many_arguments)]
    fn tape_linearize<Mo: TapeModel>(
        &mut self,
        model: &Mo,
        t0: f64,
        h: f64,
        q0: &[f64],
        dq: &[f64],
        d_q0: &mut [f64],
        jacobian: Jacobian,
    ) -> Result<(), Breakdown> {
        let n = self.n;
        let seeds = seeds(n..2 * n, self.bandwidth);
        self.tape_buffers().map_err(breakdown)?;
        self.record_action(model, t0, h, q0, dq).map_err(tape_breakdown)?;
        match jacobian {
            Jacobian::Kept => self.tape.gradient(&mut self.gradient),
            Jacobian::Fresh => self.tape.hessian_product(&seeds, &mut self.gradient, &mut self.products),
        }
        .map_err(tape_breakdown)?;
        let g = &self.gradient;
        for i in 0..n {
            d_q0[i] = g[i] - g[n + i];
        }
        if jacobian == Jacobian::Kept {
            return Ok(());
        }
        // J = ∂²A/∂q_k∂Δq − ∂²A/∂Δq², entry by entry of the pattern.
        seeds.recover(&self.products, 0..n, &mut self.mixed).map_err(tape_breakdown)?;
        seeds.recover(&self.products, n..2 * n, &mut self.end).map_err(tape_breakdown)?;
        for (a, b) in self.mixed.iter_mut().zip(&self.end) {
            *a -= b;
        }
        Ok(())
    }

    /// A [`Taken`] around the increment `dq`, its other buffers spare ones.
    fn taken(&mut self, dq: Vec<f64>, report: NewtonReport) -> Taken {
        let (q1, q_carry, p1, p_carry) = (self.buffer(), self.buffer(), self.buffer(), self.buffer());
        Taken { dq, q1, q_carry, p1, p_carry, report }
    }

    /// The explicit (Störmer–Verlet) step of the trapezoid rule on a
    /// separable system with constant mass: `M` factored once (banded when
    /// proven, a division when diagonal), `∂L/∂q` from the system's adjoint
    /// code or one reverse sweep per step, reused at the next node. Clears
    /// [`energy`](Self::energy) on success (a Verlet step's discrete energy is
    /// computed on request); keeps the node force of `node` on failure.
    pub(crate) fn verlet_step<Mo: TapeModel>(
        &mut self,
        model: &Mo,
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
            false => self.verlet_into::<_, false>(model, node, h, t1, growth, &f0, &mut taken, &mut f1),
            true => self.verlet_into::<_, true>(model, node, h, t1, growth, &f0, &mut taken, &mut f1),
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
    fn explicit_node<Mo: TapeModel>(
        &mut self,
        model: &Mo,
        node: &Node<'_>,
        min_rcond: f64,
    ) -> Result<Vec<f64>, NewtonFailure> {
        let n = self.n;
        if self.mass.is_none() {
            let zero = zeroed(Some(n), n).map_err(|e| breakdown(e).at(0))?;
            let (_, _, mut mass) =
                velocity_derivatives(model, node.t, node.q, &zero, mass_bandwidth(model.coupling(), n))
                    .map_err(|b| b.at(0))?;
            mass.factor_in_place(min_rcond).map_err(|b| b.at(0))?;
            self.mass = Some(Mass::new(mass));
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
    /// compares `Δq` with the last (composed) step's increment. Returns the
    /// composed step and its last sub-step `(t, h_m, q, δq_m)` (the readouts'
    /// segment); keeps the node force of `node` on failure, and on success
    /// the end node's force for the next step.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn verlet_composed<Mo: TapeModel>(
        &mut self,
        model: &Mo,
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
    fn composed_into<Mo: TapeModel>(
        &mut self,
        model: &Mo,
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
        let velocity = self.mass.as_ref().map_or(Velocity::Solved, Mass::velocity);
        // Half the last sub-step: its closing kick joins the next opening one.
        let (mut half, mut elapsed) = (0.0, 0.0);
        let (mut t_last, mut h_last) = (node.t, 0.0);
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
                }
                for j in 0..n {
                    q[j] += last_dq[j];
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
                let x: &mut [f64] = if i + 1 == m { &mut *q } else { &mut *last_q0 };
                for j in 0..n {
                    dq[j] += last_dq[j];
                    x[j] = q0[j] + (qc0[j] + dq[j]);
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
            if potential_force(model, &mut self.tape, &self.zero, ti, at, f).is_err() {
                return Err(NewtonFailure::Rejected { iterations: 0, reason: TAPE_FAILED });
            }
            half = 0.5 * hi;
        }
        let (mut q_bad, mut p_bad) = (0, 0);
        if plain {
            for j in 0..n {
                dq[j] = q[j] - q0[j];
                q_bad |= nan_bits(q[j]);
                p[j] += half * f[j];
                p_bad |= nan_bits(p[j]);
            }
        } else {
            let (qc0, pc0) = (&node.q_carry[..n], &node.p_carry[..n]);
            let (qc1, pc1) = (&mut out.q_carry[..n], &mut out.p_carry[..n]);
            for j in 0..n {
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
        self.growth_check(growth, &out.dq, node.q, fold_max_abs(&out.dq), fold_max_abs(node.q))?;
        let quantity = super::first_non_finite(!is_non_finite(q_bad), !is_non_finite(p_bad), t1.is_finite())
            .or_else(|| (!potential_finite(model, &self.zero.0, t1, &out.q1[..n])).then_some("lagrangian"));
        match quantity {
            Some(quantity) => Err(NewtonFailure::NonFinite { iterations: 0, quantity }),
            None => Ok((t_last, h_last)),
        }
    }

    /// A sub-step's drift `out = h_i M⁻¹ v` from the momentum `v` (solved in
    /// place when `M` takes a banded or dense solve, read otherwise).
    fn sub_drift(&self, velocity: Velocity<'_>, v: &mut [f64], hi: f64, out: &mut [f64]) -> Result<(), NewtonFailure> {
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
    /// which value failed is found again only on failure. The maxima of the
    /// growth check take one more pass over `Δq` and `q_k`.
    ///
    /// `PLAIN` ([`Summation::Plain`](crate::Summation::Plain)): the
    /// compensations are neither read nor written, the sums rounded once.
    #[allow(clippy::too_many_arguments)]
    fn verlet_into<Mo: TapeModel, const PLAIN: bool>(
        &mut self,
        model: &Mo,
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
        let velocity = self.mass.as_ref().map_or(Velocity::Solved, Mass::velocity);
        if let Velocity::Solved = velocity {
            for i in 0..n {
                dq[i] = rhs(i);
            }
            if let Some(mass) = &self.mass {
                mass.assembled.solve(dq).map_err(|e| breakdown(e).at(0))?;
            }
        }
        let q_bad = drift_pass::<PLAIN>((h, half), [p0, f0, pc0], velocity, (q0, qc0), (dq, q1, qc1));
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
        self.growth_check(growth, &out.dq, node.q, fold_max_abs(&out.dq), fold_max_abs(node.q))?;
        if potential_force(model, &mut self.tape, &self.zero, t1, &out.q1, f1).is_err() {
            return Err(NewtonFailure::Rejected { iterations: 0, reason: TAPE_FAILED });
        }
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
        let quantity = super::first_non_finite(!is_non_finite(q_bad), !is_non_finite(p_bad), t1.is_finite())
            .or_else(|| (!potential_finite(model, &self.zero.0, t1, &out.q1[..n])).then_some("lagrangian"));
        match quantity {
            Some(quantity) => Err(NewtonFailure::NonFinite { iterations: 0, quantity }),
            None => Ok(()),
        }
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

/// The quadrature points of the forward-over-reverse Newton path, when
/// the model takes it: generated gradient code and a rule of the form
/// `A = (h/2) Σ_j L(t_k + c_j h, q_k + c_j Δq, Δq/h)`.
fn directional_points<Mo: TapeModel>(model: &Mo) -> Option<[f64; 2]> {
    if model.has_gradient_qv() { model.points() } else { None }
}

/// The points that are evaluated (one when both coincide) and their weight.
pub(super) fn distinct(points: [f64; 2]) -> (&'static [usize], f64) {
    if points[0] == points[1] { (&[0], 1.0) } else { (&[0, 1], 0.5) }
}

/// `t_k + c h`, formed as the rules' actions form it.
#[inline]
pub(super) fn point_time(c: f64, t0: f64, h: f64) -> f64 {
    if c == 0.0 {
        t0
    } else if c == 1.0 {
        t0 + h
    } else {
        t0 + h * c
    }
}

/// `q_k + c Δq`, formed as the rules' actions form it.
#[inline]
pub(super) fn point_position(c: f64, q0: f64, dq: f64) -> f64 {
    if c == 0.0 {
        q0
    } else if c == 1.0 {
        q0 + dq
    } else {
        q0 + dq * c
    }
}

/// A vector of `len` copies of `value`, or `TooLarge` instead of an abort.
fn filled<T: Clone>(len: usize, value: T) -> Result<Vec<T>, LinearSolveError> {
    let mut v = Vec::new();
    v.try_reserve_exact(len).map_err(|_| LinearSolveError::TooLarge { n: len, per_column: 1 })?;
    v.resize(len, value);
    Ok(v)
}

/// A dual number carrying [`LANES`](Self::LANES) directions at once: one
/// evaluation of the gradient code on it gives that many Hessian-vector
/// products, with the same real part as on `f64`.
trait Lanes: Scalar {
    /// How many directions one value carries.
    const LANES: usize;
    /// `re` with `scale` in direction `lane` (none: a constant).
    fn seed(re: f64, lane: Option<usize>, scale: f64) -> Self;
    /// The derivative part along direction `lane`.
    fn part(&self, lane: usize) -> f64;
}

impl Lanes for Dual64 {
    const LANES: usize = 1;

    #[inline(always)]
    fn seed(re: f64, lane: Option<usize>, scale: f64) -> Self {
        Dual64::new(re, if lane.is_some() { scale } else { 0.0 })
    }

    #[inline(always)]
    fn part(&self, _: usize) -> f64 {
        self.eps
    }
}

impl<const K: usize> Lanes for DualArray<[f64; K]> {
    const LANES: usize = K;

    #[inline(always)]
    fn seed(re: f64, lane: Option<usize>, scale: f64) -> Self {
        let mut x = Self::from_re(re);
        if let Some(lane) = lane {
            x.eps[lane] = scale;
        }
        x
    }

    #[inline(always)]
    fn part(&self, lane: usize) -> f64 {
        self.eps[lane]
    }
}

/// The seeded point and velocity of one evaluation of the gradient code on
/// the lane type `D`, and the gradients it returns.
#[derive(Clone, Debug)]
struct Seeded<D> {
    q: Vec<D>,
    v: Vec<D>,
    gq: Vec<D>,
    gv: Vec<D>,
}

impl<D> Default for Seeded<D> {
    fn default() -> Self {
        Self { q: Vec::new(), v: Vec::new(), gq: Vec::new(), gv: Vec::new() }
    }
}

impl<D: Lanes> Seeded<D> {
    /// Sizes the buffers for `n` coordinates (once).
    fn allocate(&mut self, n: usize) -> Result<(), LinearSolveError> {
        if self.q.len() != n {
            let zero = D::from(0.0);
            *self = Self { q: filled(n, zero)?, v: filled(n, zero)?, gq: filled(n, zero)?, gv: filled(n, zero)? };
        }
        Ok(())
    }
}

/// The lane type for `classes` colour classes: a matrix of bandwidth 0, 1
/// or 2 (1, 3 or 5 classes) in one evaluation per point; wider bands and
/// general patterns in chunks of five classes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Width {
    One,
    Three,
    Five,
}

impl Width {
    fn for_classes(classes: usize) -> Self {
        match classes {
            1 => Width::One,
            3 => Width::Three,
            _ => Width::Five,
        }
    }
}

/// Where the entries of the derivative columns go: the band of a matrix
/// (row `i`'s `2b + 1` entries around the diagonal) or its dense rows.
#[derive(Clone, Copy, Debug)]
struct Layout {
    n: usize,
    bandwidth: Option<usize>,
}

impl Layout {
    /// The number of colour classes: columns `j ≡ k (mod 2b + 1)` of a
    /// matrix of bandwidth `b` never share a row's band (Curtis, Powell and
    /// Reid); every column its own class without a proven band.
    fn classes(self) -> usize {
        self.bandwidth.map_or(self.n, |b| 2 * b + 1)
    }

    /// Entries per row of the storage.
    fn width(self) -> usize {
        self.bandwidth.map_or(self.n, |b| 2 * b + 1)
    }

    /// Calls `add(slot, lane)` for each entry of row `i` whose column is in
    /// the classes `first .. first + lanes` (the lane `class − first`).
    #[inline(always)]
    fn row(self, i: usize, first: usize, lanes: usize, mut add: impl FnMut(usize, usize)) {
        match self.bandwidth {
            Some(b) => {
                // Column `i + s − b` of slot `s`, its class that modulo `2b + 1`.
                let classes = 2 * b + 1;
                let mut class = (i + classes - b) % classes;
                for slot in 0..classes {
                    if let Some(lane) = class.checked_sub(first).filter(|&l| l < lanes) {
                        add(slot, lane);
                    }
                    class += 1;
                    if class == classes {
                        class = 0;
                    }
                }
            }
            None => {
                for lane in 0..lanes {
                    add(first + lane, lane);
                }
            }
        }
    }
}

/// The buffers of Newton steps from the system's generated gradient code
/// (forward over reverse): the point and the velocity seeded on dual
/// numbers and their gradients, and the `f64` values of the rule's points.
///
/// With `A = w h Σ_j L(t_k + c_j h, q_k + c_j Δq, Δq·h⁻¹)` (`w = 1` for one
/// point, `½` for two), the residual's part
/// `∂A/∂q_k|_{q_{k+1}} = Σ_j w [h (1 − c_j) L_q − h h⁻¹ L_v]` needs the
/// gradient of `L` at the points, and a column class `s` of the Jacobian
/// `J = ∂(∂A/∂q_k|_{q_{k+1}})/∂Δq` is the derivative of the same sum along
/// `s`: the gradient code on dual numbers with `q` seeded by `c_j s` and `v`
/// by `h⁻¹ s`. All `2b + 1` classes of a band up to `b = 2` travel together
/// on one vector dual number ([`Lanes`]), so each point costs one
/// evaluation; wider patterns go in chunks of five classes.
#[derive(Clone, Debug, Default)]
struct Directional {
    one: Seeded<Dual64>,
    three: Seeded<DualArray<[f64; 3]>>,
    five: Seeded<DualArray<[f64; 5]>>,
    /// `q_k + c_j Δq` of both points, one after the other.
    at: Vec<f64>,
    /// `Δq·h⁻¹`.
    velocity: Vec<f64>,
    /// `∂L/∂q`, `∂L/∂v` in `f64` after convergence.
    fq: Vec<f64>,
    fv: Vec<f64>,
}

impl Directional {
    /// Sizes the buffers for `n` coordinates and a Jacobian of the given
    /// bandwidth (once).
    fn allocate(&mut self, n: usize, bandwidth: Option<usize>, autonomous: bool) -> Result<(), LinearSolveError> {
        self.allocate_values(n, autonomous)?;
        match Width::for_classes(Layout { n, bandwidth }.classes()) {
            Width::One => self.one.allocate(n),
            Width::Three => self.three.allocate(n),
            Width::Five => self.five.allocate(n),
        }
    }

    /// Sizes what [`momentum_and_energy`](Self::momentum_and_energy) needs
    /// (once): the `f64` buffers, and `Dual64` ones for `∂L/∂t` when `L`
    /// depends on time.
    fn allocate_values(&mut self, n: usize, autonomous: bool) -> Result<(), LinearSolveError> {
        if self.velocity.len() != n {
            let two_n = n.checked_mul(2).ok_or(LinearSolveError::TooLarge { n, per_column: 2 })?;
            *self = Self {
                at: filled(two_n, 0.0)?,
                velocity: filled(n, 0.0)?,
                fq: filled(n, 0.0)?,
                fv: filled(n, 0.0)?,
                ..Self::default()
            };
        }
        if autonomous { Ok(()) } else { self.one.allocate(n) }
    }

    /// The velocity `Δq·h⁻¹` and the points `q_k + c_j Δq`.
    fn points(&mut self, points: [f64; 2], q0: &[f64], dq: &[f64], inv_h: f64) {
        let n = q0.len();
        for (v, &d) in self.velocity.iter_mut().zip(dq) {
            *v = d * inv_h;
        }
        for &j in distinct(points).0 {
            let c = points[j];
            for (i, x) in self.at[j * n..(j + 1) * n].iter_mut().enumerate() {
                *x = point_position(c, q0[i], dq[i]);
            }
        }
    }

    /// `∂A/∂q_k|_{q_{k+1}}` at the increment `dq` into `d_q0`, and the
    /// Jacobian `J` into `band` (row `i`'s `2b + 1` entries around the
    /// diagonal, or whole rows without a band). [`allocate`](Self::allocate)
    /// must have been called with this bandwidth.
    #[allow(clippy::too_many_arguments)]
    fn linearize<Mo: TapeModel>(
        &mut self,
        model: &Mo,
        t0: f64,
        h: f64,
        points: [f64; 2],
        q0: &[f64],
        dq: &[f64],
        bandwidth: Option<usize>,
        d_q0: &mut [f64],
        band: &mut [f64],
    ) {
        let n = q0.len();
        let inv_h = h.recip();
        self.points(points, q0, dq, inv_h);
        let layout = Layout { n, bandwidth };
        let step = Step { t0, h, inv_h, points, at: &self.at, velocity: &self.velocity };
        match Width::for_classes(layout.classes()) {
            Width::One => step.linearize(model, &mut self.one, layout, d_q0, band),
            Width::Three => step.linearize(model, &mut self.three, layout, d_q0, band),
            Width::Five => step.linearize(model, &mut self.five, layout, d_q0, band),
        }
    }

    /// `∂A/∂q_k|_{q_{k+1}}` at the increment `dq` alone into `d_q0`, from the
    /// `f64` gradient code: the real parts of [`linearize`](Self::linearize),
    /// summed in the same order, for the iterations that keep the Jacobian.
    #[allow(clippy::too_many_arguments)]
    fn residual<Mo: TapeModel>(
        &mut self,
        model: &Mo,
        t0: f64,
        h: f64,
        points: [f64; 2],
        q0: &[f64],
        dq: &[f64],
        d_q0: &mut [f64],
    ) {
        let n = q0.len();
        let inv_h = h.recip();
        self.points(points, q0, dq, inv_h);
        let (evaluated, w) = distinct(points);
        let b_v = w * (h * inv_h);
        d_q0.fill(0.0);
        for &j in evaluated {
            let c = points[j];
            let a_q = w * (h * (1.0 - c));
            let at = &self.at[j * n..(j + 1) * n];
            model.gradient_qv(point_time(c, t0, h), at, &self.velocity, &mut self.fq, &mut self.fv);
            for i in 0..n {
                d_q0[i] += a_q * self.fq[i] - b_v * self.fv[i];
            }
        }
    }

    /// After convergence: `∂A/∂q_k` at fixed increment (the momentum change)
    /// into `g_q0`, and the step's discrete energy `−∂A/∂h`, from the `f64`
    /// gradient code and `L` (with `∂L/∂t` on a dual number when `L`
    /// depends on time) at the points; with the energy, whether `L` is
    /// finite at every point.
    #[allow(clippy::too_many_arguments)]
    fn momentum_and_energy<Mo: TapeModel>(
        &mut self,
        model: &Mo,
        t0: f64,
        h: f64,
        points: [f64; 2],
        q0: &[f64],
        dq: &[f64],
        g_q0: &mut [f64],
    ) -> (f64, bool) {
        let n = q0.len();
        let inv_h = h.recip();
        self.points(points, q0, dq, inv_h);
        let (evaluated, w) = distinct(points);
        g_q0.fill(0.0);
        // ∂A/∂h = Σ_j w [L + c_j h ∂L/∂t − L_v·Δq·h⁻¹].
        let mut g_h = 0.0;
        let mut lagrangian_finite = true;
        for &j in evaluated {
            let c = points[j];
            let t = point_time(c, t0, h);
            let at = &self.at[j * n..(j + 1) * n];
            model.gradient_qv(t, at, &self.velocity, &mut self.fq, &mut self.fv);
            let wh = w * h;
            for (g, &f) in g_q0.iter_mut().zip(&self.fq) {
                *g += wh * f;
            }
            let (l, l_t) = if model.autonomous() {
                (model.lagrangian_scalar(t, at, &self.velocity), 0.0)
            } else {
                for i in 0..n {
                    self.one.q[i] = Dual64::from(at[i]);
                    self.one.v[i] = Dual64::from(self.velocity[i]);
                }
                let l = model.lagrangian_scalar(Dual64::new(t, 1.0), &self.one.q, &self.one.v);
                (l.re, l.eps)
            };
            let power: f64 = self.fv.iter().zip(&self.velocity).map(|(p, v)| p * v).sum();
            g_h += w * (l + c * h * l_t - power);
            lagrangian_finite &= l.is_finite();
        }
        (-g_h, lagrangian_finite)
    }
}

/// The `f64` data of one step's points, shared by the lane types.
struct Step<'a> {
    t0: f64,
    h: f64,
    inv_h: f64,
    points: [f64; 2],
    /// `q_k + c_j Δq` of both points.
    at: &'a [f64],
    /// `Δq·h⁻¹`.
    velocity: &'a [f64],
}

impl Step<'_> {
    /// [`Directional::linearize`] on the lane type `D`: per chunk of
    /// `D::LANES` classes, one evaluation of the gradient code per point.
    /// The arithmetic of each entry is that of one `Dual64` evaluation per
    /// class (the real part is the `f64` code's), summed over the points in
    /// the same order.
    fn linearize<Mo: TapeModel, D: Lanes>(
        &self,
        model: &Mo,
        seeded: &mut Seeded<D>,
        layout: Layout,
        d_q0: &mut [f64],
        band: &mut [f64],
    ) {
        let n = layout.n;
        let width = layout.width();
        let (evaluated, w) = distinct(self.points);
        // The weight of `L_v`: `w h · h⁻¹`, the derivative of the action as
        // computed (`v = Δq·h⁻¹`).
        let b_v = w * (self.h * self.inv_h);
        let classes = layout.classes();
        d_q0.fill(0.0);
        band[..n * width].fill(0.0);
        for first in (0..classes).step_by(D::LANES) {
            let lanes = D::LANES.min(classes - first);
            for &j in evaluated {
                let c = self.points[j];
                let a_q = w * (self.h * (1.0 - c));
                let at = &self.at[j * n..(j + 1) * n];
                // Seed the chunk: column `i` in lane `(i mod classes) − first`.
                let mut class: usize = 0;
                for i in 0..n {
                    let lane = class.checked_sub(first).filter(|&l| l < lanes);
                    seeded.q[i] = D::seed(at[i], lane, c);
                    seeded.v[i] = D::seed(self.velocity[i], lane, self.inv_h);
                    class += 1;
                    if class == classes {
                        class = 0;
                    }
                }
                let t = D::from(point_time(c, self.t0, self.h));
                model.gradient_qv(t, &seeded.q, &seeded.v, &mut seeded.gq, &mut seeded.gv);
                for i in 0..n {
                    let (gq, gv) = (&seeded.gq[i], &seeded.gv[i]);
                    let row = &mut band[i * width..(i + 1) * width];
                    layout.row(i, first, lanes, |slot, lane| row[slot] += a_q * gq.part(lane) - b_v * gv.part(lane));
                }
                if first == 0 {
                    for i in 0..n {
                        d_q0[i] += a_q * seeded.gq[i].re() - b_v * seeded.gv[i].re();
                    }
                }
            }
        }
    }
}

/// `∂L/∂v` and the mass matrix `∂²L/∂v²` at `(t, q, v)` from the gradient
/// code: `∂L/∂v` on `f64` into `p`, `∂²L/∂v²` by colour classes on lane
/// duals (`v` seeded, `q` constant) into `band` (the layout's storage).
/// Allocates its dual buffers (a readout, not a step).
#[allow(clippy::too_many_arguments)]
fn mass_from_gradient_code<Mo: TapeModel>(
    model: &Mo,
    t: f64,
    q: &[f64],
    v: &[f64],
    layout: Layout,
    p: &mut [f64],
    band: &mut [f64],
) -> Result<(), LinearSolveError> {
    let n = layout.n;
    let mut fq = filled(n, 0.0)?;
    model.gradient_qv(t, q, v, &mut fq, p);
    match Width::for_classes(layout.classes()) {
        Width::One => mass_lanes::<Mo, Dual64>(model, t, q, v, layout, band),
        Width::Three => mass_lanes::<Mo, DualArray<[f64; 3]>>(model, t, q, v, layout, band),
        Width::Five => mass_lanes::<Mo, DualArray<[f64; 5]>>(model, t, q, v, layout, band),
    }
}

/// The mass matrix of [`mass_from_gradient_code`] on the lane type `D`.
fn mass_lanes<Mo: TapeModel, D: Lanes>(
    model: &Mo,
    t: f64,
    q: &[f64],
    v: &[f64],
    layout: Layout,
    band: &mut [f64],
) -> Result<(), LinearSolveError> {
    let n = layout.n;
    let width = layout.width();
    let classes = layout.classes();
    let mut seeded = Seeded::<D>::default();
    seeded.allocate(n)?;
    for (x, &y) in seeded.q.iter_mut().zip(q) {
        *x = D::from(y);
    }
    band[..n * width].fill(0.0);
    for first in (0..classes).step_by(D::LANES) {
        let lanes = D::LANES.min(classes - first);
        let mut class: usize = 0;
        for i in 0..n {
            let lane = class.checked_sub(first).filter(|&l| l < lanes);
            seeded.v[i] = D::seed(v[i], lane, 1.0);
            class += 1;
            if class == classes {
                class = 0;
            }
        }
        model.gradient_qv(D::from(t), &seeded.q, &seeded.v, &mut seeded.gq, &mut seeded.gv);
        for i in 0..n {
            let gv = &seeded.gv[i];
            let row = &mut band[i * width..(i + 1) * width];
            layout.row(i, first, lanes, |slot, lane| row[slot] = gv.part(lane));
        }
    }
    Ok(())
}

/// Newton's unknown (and correction) on the heap without an allocation per
/// iteration: a buffer of the step, borrowed for the solve.
struct Slot<'a>(&'a RefCell<Vec<f64>>);

impl Unknown for Slot<'_> {
    #[inline]
    fn update(&mut self, dx: &Self) {
        let dx = dx.0.borrow();
        for (x, d) in self.0.borrow_mut().iter_mut().zip(dx.iter()) {
            *x += d;
        }
    }

    #[inline]
    fn error_ratio(&self, dx: &Self, rtol: f64, atol: f64) -> f64 {
        max_abs(&dx.0.borrow()) / (rtol * max_abs(&self.0.borrow()) + atol)
    }
}

/// The factored constant mass matrix of the explicit path, and the
/// reciprocals of its diagonal when it is a banded matrix of bandwidth 0:
/// the solve is then one product per entry, done in the step's own loop.
#[derive(Clone, Debug)]
struct Mass {
    assembled: Assembled,
    inverse_diagonal: Option<Vec<f64>>,
    /// `M = I` (the diagonal is all ones): the drift skips the product.
    unit: bool,
}

impl Mass {
    fn new(assembled: Assembled) -> Self {
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

    /// How a drift applies `M⁻¹`: skipped for `M = I`, products with the
    /// reciprocals of a diagonal (as forward mode's `M⁻¹`; a division per
    /// entry cost 0.35 µs of a 2.5 µs step at N = 1000), else the solve.
    fn velocity(&self) -> Velocity<'_> {
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
/// `qc0`. Returns the OR of the [`nan_bits`] of `q_{k+1}`.
/// `PLAIN` ([`Summation::Plain`](crate::Summation::Plain)): `c_p`, `qc0`
/// are not read, `qc1` not written, and `q_{k+1} = q_k + Δq` is rounded once.
#[inline(always)]
fn drift_pass<const PLAIN: bool>(
    (h, half): (f64, f64),
    momentum: [&[f64]; 3],
    velocity: Velocity<'_>,
    (q0, qc0): (&[f64], &[f64]),
    (dq, q1, qc1): (&mut [f64], &mut [f64], &mut [f64]),
) -> u64 {
    match velocity {
        Velocity::Unit => drift_loop::<0, PLAIN>((h, half), momentum, &[], (q0, qc0), (dq, q1, qc1)),
        Velocity::Diagonal(d) => drift_loop::<1, PLAIN>((h, half), momentum, d, (q0, qc0), (dq, q1, qc1)),
        Velocity::Solved => drift_loop::<2, PLAIN>((h, half), momentum, &[], (q0, qc0), (dq, q1, qc1)),
    }
}

/// How the drift's velocity comes from its momentum `(p_k + (h/2) f_k) + c_p`.
#[derive(Clone, Copy)]
enum Velocity<'a> {
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
fn drift_loop<const KIND: u8, const PLAIN: bool>(
    (h, half): (f64, f64),
    [p0, f0, pc0]: [&[f64]; 3],
    d: &[f64],
    (q0, qc0): (&[f64], &[f64]),
    (dq, q1, qc1): (&mut [f64], &mut [f64], &mut [f64]),
) -> u64 {
    let n = q0.len();
    // One length for every slice, so that the loop has no bounds checks.
    let d = if KIND == 1 { &d[..n] } else { q0 };
    let (p0, f0, pc0, qc0) = (&p0[..n], &f0[..n], &pc0[..n], &qc0[..n]);
    let (dq, q1, qc1) = (&mut dq[..n], &mut q1[..n], &mut qc1[..n]);
    let mut bad = 0;
    for i in 0..n {
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
    }
    bad
}

/// Records the relative change `|after − before| / |before|` of the discrete
/// energy across node `t1` in `stats` when it is the largest so far (the
/// watch of a system declared discontinuous).
pub(crate) fn watch_energy_jump(stats: &mut Stats, before: f64, after: f64, t1: f64) {
    let jump = (after - before).abs() / before.abs().max(f64::MIN_POSITIVE);
    if jump.is_finite() && jump > stats.largest_energy_jump {
        stats.largest_energy_jump = jump;
        stats.largest_energy_jump_at = t1;
    }
}

/// The discrete energy `−∂A/∂t_{k+1}` of the step `(t0, h, q0, dq)`: from
/// the system's gradient code at the rule's points when it has it, else from
/// one reverse sweep (NaN if the tape fails, which the runtime's use cannot
/// provoke, or if the buffers cannot be allocated).
pub(crate) fn step_energy<Mo: TapeModel>(model: &Mo, t0: f64, h: f64, q0: &[f64], dq: &[f64]) -> f64 {
    let n = q0.len();
    if let Some(points) = directional_points(model) {
        let mut directional = Directional::default();
        let Ok(mut g_q0) = filled(n, 0.0) else { return f64::NAN };
        if directional.allocate_values(n, model.autonomous()).is_err() {
            return f64::NAN;
        }
        return directional.momentum_and_energy(model, t0, h, points, q0, dq, &mut g_q0).0;
    }
    let mut tape = Tape::new();
    let mut inputs = Vec::with_capacity(2 * n + 1);
    inputs.extend_from_slice(q0);
    inputs.extend_from_slice(dq);
    inputs.push(h);
    let recorded = tape.record(&inputs, |x: &[Var]| model.action(Var::constant(t0), x[2 * n], &x[..n], &x[n..2 * n]));
    let mut gradient = vec![0.0; 2 * n + 1];
    match recorded.and_then(|_| tape.gradient(&mut gradient)) {
        Ok(()) => -gradient[2 * n],
        Err(_) => f64::NAN,
    }
}

/// Whether `L(t, q, 0) = −V(t, q)` of a separable system with constant
/// mass is finite at the end node `q` of an explicit step: with the start
/// node's, checked by the step before (or at `start`), it makes the
/// trapezoid action `h/2 (L_k + L_{k+1})` finite, whose derivatives can be
/// finite where it is not.
pub(super) fn potential_finite<Mo: TapeModel>(model: &Mo, zero: &[f64], t: f64, q: &[f64]) -> bool {
    model.lagrangian_scalar(t, q, zero).is_finite()
}

/// `∂L/∂q(t, q, 0) = −∇V(t, q)` of a separable system, from one reverse
/// sweep with the inputs `q`.
fn potential_force<Mo: TapeModel>(
    model: &Mo,
    tape: &mut Tape,
    zero: &(Vec<f64>, Vec<Var>),
    t: f64,
    q: &[f64],
    out: &mut [f64],
) -> Result<(), TapeError> {
    if model.gradient_q(t, q, &zero.0, out) {
        return Ok(());
    }
    tape.record(q, |x: &[Var]| model.lagrangian(Var::constant(t), x, &zero.1))?;
    tape.gradient(out)
}

/// `L`, `∂L/∂v` and `∂²L/∂v²` (assembled, not factored; banded with the
/// given bandwidth, or dense) at `(t, q, v)`: from the system's gradient
/// code (on `f64`, and by colour classes on dual numbers) when it has it,
/// else from one second-order sweep of a tape with the inputs `v`.
fn velocity_derivatives<Mo: TapeModel>(
    model: &Mo,
    t: f64,
    q: &[f64],
    v: &[f64],
    bandwidth: Option<usize>,
) -> Result<(f64, Vec<f64>, Assembled), Breakdown> {
    let n = q.len();
    let width = bandwidth.map_or(n, |b| 2 * b + 1);
    let mut gradient = zeroed(Some(n), n).map_err(breakdown)?;
    let mut band = zeroed(n.checked_mul(width), n).map_err(breakdown)?;
    let l = if model.has_gradient_qv() {
        let layout = Layout { n, bandwidth };
        mass_from_gradient_code(model, t, q, v, layout, &mut gradient, &mut band).map_err(breakdown)?;
        model.lagrangian_scalar(t, q, v)
    } else {
        let seeds = seeds(0..n, bandwidth);
        let mut tape = Tape::new();
        let qc: Vec<Var> = q.iter().map(|&x| Var::constant(x)).collect();
        let l = tape.record(v, |x: &[Var]| model.lagrangian(Var::constant(t), &qc, x)).map_err(tape_breakdown)?;
        let mut products = zeroed(n.checked_mul(seeds.directions()), n).map_err(breakdown)?;
        tape.hessian_product(&seeds, &mut gradient, &mut products).map_err(tape_breakdown)?;
        seeds.recover(&products, 0..n, &mut band).map_err(tape_breakdown)?;
        l
    };
    let matrix = step_matrix(n, bandwidth).map_err(breakdown)?;
    Ok((l, gradient, Assembled { n, matrix, band, bandwidth }))
}

/// A Hessian block read from the tape, ready to be factored.
#[derive(Clone, Debug)]
struct Assembled {
    n: usize,
    matrix: StepSolver,
    band: Vec<f64>,
    bandwidth: Option<usize>,
}

impl Assembled {
    /// Assembles and factors the block.
    fn factor_in_place(&mut self, min_rcond: f64) -> Result<(), Breakdown> {
        assemble_and_factor(&mut self.matrix, self.n, self.bandwidth, &self.band, min_rcond)
    }

    fn solve(&self, b: &mut [f64]) -> Result<(), LinearSolveError> {
        self.matrix.solve(b)
    }
}

/// The momentum `p = ∂L/∂v` and energy `E = v·p − L` at `(t, q, v)`, with a
/// check that `∂²L/∂v²` is regular there (its banded or dense LU). `Err`
/// says why the data cannot start an integration.
pub(crate) fn legendre<Mo: TapeModel>(
    model: &Mo,
    t: f64,
    q: &[f64],
    v: &[f64],
) -> Result<(Vec<f64>, f64), &'static str> {
    let n = q.len();
    let (l, p, mut hessian) = velocity_derivatives(model, t, q, v, mass_bandwidth(model.coupling(), n))
        .map_err(|_| "the lagrangian or its derivatives could not be evaluated at the initial data")?;
    if !l.is_finite() || !all_finite(&p) {
        return Err("the lagrangian or its momentum is not finite at the initial data");
    }
    if hessian.factor_in_place(0.0).is_err() {
        return Err("∂²L/∂v² is singular at the initial data: the legendre transform is not regular");
    }
    let energy = (0..n).map(|i| v[i] * p[i]).sum::<f64>() - l;
    if !energy.is_finite() {
        return Err("the energy is not finite at the initial data");
    }
    Ok((p, energy))
}

/// The energy `E = v·∂L/∂v − L` at `(t, q, v)`: `∂L/∂v` from the system's
/// gradient code when it has it, else from one reverse sweep (NaN if the
/// tape fails).
pub(crate) fn energy<Mo: TapeModel>(model: &Mo, t: f64, q: &[f64], v: &[f64]) -> f64 {
    let n = q.len();
    let mut p = vec![0.0; n];
    let swept = if model.has_gradient_qv() {
        let mut fq = vec![0.0; n];
        model.gradient_qv(t, q, v, &mut fq, &mut p);
        Ok(model.lagrangian_scalar(t, q, v))
    } else {
        let mut tape = Tape::new();
        let qc: Vec<Var> = q.iter().map(|&x| Var::constant(x)).collect();
        tape.record(v, |x: &[Var]| model.lagrangian(Var::constant(t), &qc, x))
            .and_then(|l| tape.gradient(&mut p).map(|_| l))
    };
    match swept {
        Ok(l) => (0..n).map(|i| v[i] * p[i]).sum::<f64>() - l,
        Err(_) => f64::NAN,
    }
}

/// The velocity whose momentum `∂L/∂v(t, q, v)` is `p`, by Newton's method
/// from `guess` with banded or dense solves (the inverse Legendre
/// transform). `Err` carries `(iterations, residual norm)`.
pub(crate) fn velocity<Mo: TapeModel>(
    model: &Mo,
    t: f64,
    q: &[f64],
    p: &[f64],
    guess: &[f64],
) -> Result<Vec<f64>, (usize, f64)> {
    let n = q.len();
    let options = NewtonOptions::default();
    let bandwidth = mass_bandwidth(model.coupling(), n);
    let linearize = |v: &Vec<f64>, _| -> Result<Linearization<Vec<f64>>, Breakdown> {
        let (_, m, mut hessian) = velocity_derivatives(model, t, q, v, bandwidth)?;
        let mut r: Vec<f64> = (0..n).map(|i| m[i] - p[i]).collect();
        if !r.iter().all(|x| x.is_finite()) {
            return Err(Breakdown::NonFinite("residual"));
        }
        let scale = max_abs(p).max(max_abs(&m));
        hessian.factor_in_place(options.min_rcond)?;
        let residual_norm = max_abs(&r);
        hessian.solve(&mut r).map_err(breakdown)?;
        r.iter_mut().for_each(|x| *x = -*x);
        Ok(Linearization::new(r, residual_norm).cancelling(scale))
    };
    match newton::solve(guess.to_vec(), &options, linearize) {
        Ok((v, _)) => Ok(v),
        Err(NewtonFailure::NotConverged(r)) => Err((r.iterations, r.residual_norm)),
        Err(f) => Err((f.iterations(), f64::INFINITY)),
    }
}

/// The heap vector Newton iterates on in reverse mode.
impl Unknown for Vec<f64> {
    #[inline]
    fn update(&mut self, dx: &Self) {
        for (x, d) in self.iter_mut().zip(dx) {
            *x += d;
        }
    }

    #[inline]
    fn error_ratio(&self, dx: &Self, rtol: f64, atol: f64) -> f64 {
        max_abs(dx) / (rtol * max_abs(self) + atol)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The growth check's early bound never changes the verdict of the full
    /// `implausible_growth`: increments around the threshold, positions from
    /// zero up, with and without a last increment.
    #[test]
    fn the_growth_bound_agrees_with_the_full_check() {
        let n = 5;
        let mut work = SparseWork::new(n, Coupling::GENERAL).unwrap();
        let mut seed = 0x2545_f491_4f6c_dd1d_u64;
        let mut next = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
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

    /// A chain with a position-dependent mass, kinetic coupling of
    /// neighbours and quartic springs (bandwidth 1), its gradient written by
    /// hand over any scalar.
    struct Chain;

    fn chain_lagrangian<D: Scalar>(q: &[D], v: &[D]) -> D {
        let mut l = D::from(0.0);
        for i in 0..q.len() {
            l += v[i] * v[i] * (q[i].cos() * 0.1 + 1.0) * 0.5 + q[i].cos();
            if i + 1 < q.len() {
                let e = q[i + 1] - q[i];
                l += v[i] * v[i + 1] * (q[i] - q[i + 1]).cos() * 0.2 - e.powi(4) * 0.25;
            }
        }
        l
    }

    impl TapeModel for Chain {
        fn coupling(&self) -> Coupling {
            Coupling::GENERAL
        }
        fn lagrangian(&self, _: Var, q: &[Var], v: &[Var]) -> Var {
            chain_lagrangian(q, v)
        }
        fn action(&self, _: Var, _: Var, _: &[Var], _: &[Var]) -> Var {
            unreachable!("the test steps no tape")
        }
        fn autonomous(&self) -> bool {
            true
        }
        fn points(&self) -> Option<[f64; 2]> {
            None
        }
        fn has_gradient_qv(&self) -> bool {
            true
        }
        fn gradient_qv<D: Scalar>(&self, _: D, q: &[D], v: &[D], out_q: &mut [D], out_v: &mut [D]) {
            let n = q.len();
            for i in 0..n {
                let (s, c) = q[i].sin_cos();
                out_q[i] = -(v[i] * v[i] * s * 0.05) - s;
                out_v[i] = v[i] * (c * 0.1 + 1.0);
            }
            for i in 0..n - 1 {
                let (s, c) = (q[i] - q[i + 1]).sin_cos();
                let vv = v[i] * v[i + 1] * 0.2;
                out_q[i] -= vv * s;
                out_q[i + 1] += vv * s;
                out_v[i] += v[i + 1] * c * 0.2;
                out_v[i + 1] += v[i] * c * 0.2;
                let e3 = (q[i + 1] - q[i]).powi(3);
                out_q[i] += e3;
                out_q[i + 1] -= e3;
            }
        }
        fn lagrangian_scalar<D: Scalar>(&self, _: D, q: &[D], v: &[D]) -> D {
            chain_lagrangian(q, v)
        }
    }

    /// The vector lanes give the Jacobian and residual of one `Dual64`
    /// evaluation per colour class (the path before them) bit for bit, for
    /// bands of width 3, 5 and 7 (chunks) and the dense pattern (chunks),
    /// one and two quadrature points; and the band is the Jacobian (against
    /// central differences of the residual).
    #[test]
    fn vector_lanes_give_the_per_class_jacobian_bit_for_bit() {
        let n = 23;
        let q0: Vec<f64> = (0..n).map(|i| 0.4 * (0.7 * i as f64).sin()).collect();
        let dq: Vec<f64> = (0..n).map(|i| 0.03 * (1.3 * i as f64 + 0.2).cos()).collect();
        let h = 0.05;
        for bandwidth in [Some(1), Some(2), Some(3), None] {
            for points in [[0.5, 0.5], [0.0, 1.0], [0.3, 0.3]] {
                let layout = Layout { n, bandwidth };
                let width = layout.width();
                let mut lanes = Directional::default();
                lanes.allocate(n, bandwidth, true).unwrap();
                let (mut r, mut band) = (vec![0.0; n], vec![f64::NAN; n * width]);
                lanes.linearize(&Chain, 0.0, h, points, &q0, &dq, bandwidth, &mut r, &mut band);
                // The reference: `Dual64` lanes, one class per evaluation.
                let mut one = Seeded::<Dual64>::default();
                one.allocate(n).unwrap();
                let (mut r1, mut band1) = (vec![0.0; n], vec![f64::NAN; n * width]);
                let step = Step { t0: 0.0, h, inv_h: h.recip(), points, at: &lanes.at, velocity: &lanes.velocity };
                step.linearize(&Chain, &mut one, layout, &mut r1, &mut band1);
                let case = format!("bandwidth {bandwidth:?}, points {points:?}");
                assert!(r.iter().zip(&r1).all(|(a, b)| a.to_bits() == b.to_bits()), "{case}: residual");
                assert!(band.iter().zip(&band1).all(|(a, b)| a.to_bits() == b.to_bits()), "{case}: jacobian");
                // Column j of the Jacobian by central differences.
                let (mut plus, mut minus) = (vec![0.0; n], vec![0.0; n]);
                let mut scratch = vec![0.0; n * width];
                let mut largest = 0.0f64;
                for j in 0..n {
                    let eps = 1e-6;
                    let mut x = dq.clone();
                    x[j] += eps;
                    lanes.linearize(&Chain, 0.0, h, points, &q0, &x, bandwidth, &mut plus, &mut scratch);
                    x[j] -= 2.0 * eps;
                    lanes.linearize(&Chain, 0.0, h, points, &q0, &x, bandwidth, &mut minus, &mut scratch);
                    for i in 0..n {
                        let fd = (plus[i] - minus[i]) / (2.0 * eps);
                        let entry = match bandwidth {
                            Some(b) if i.abs_diff(j) > b => 0.0,
                            Some(b) => band[i * width + j + b - i],
                            None => band[i * n + j],
                        };
                        largest = largest.max((fd - entry).abs());
                    }
                }
                // Entries are O(1/h) = O(20); differences of step 1e-6 are good to ~1e-8.
                assert!(largest < 1e-6, "{case}: {largest:e}");
            }
        }
    }
}
