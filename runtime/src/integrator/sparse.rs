//! Large systems: one-point steps whose derivatives come from a tape swept in
//! reverse, and whose Newton systems are banded (or dense) on the heap.
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
//! Why: the forward-mode array hyper-duals of the small-system path carry an
//! `N × N` block in every intermediate value, so an `L` with `O(N)` operations
//! costs `O(N³)` per Newton iteration and overflows the stack near `N = 64`.
//! Here the gradient costs `O(ops)` and the Jacobian `O(K·ops)`, where the
//! number of seed directions `K` is `2b + 1` when the macro proved the
//! Hessian of `L` banded with bandwidth `b` ([`Lagrangian::COUPLING`]): seeds
//! coloured `j mod (2b + 1)` never mix two columns that share a row of the
//! band, so each product column holds one band entry per row (compressed
//! seeding, Curtis, Powell & Reid). Without a proven band `K = N` and the
//! Jacobian is dense. The Newton systems are factored by banded LU with
//! partial pivoting (`O(N b²)`) or dense LU, both on the heap; the state
//! stays in the integrator's `[f64; N]` arrays.
//!
//! The explicit (Störmer–Verlet) path of a separable system with constant
//! mass takes the same route: `M` from one second-order sweep at the start,
//! factored once; `∂L/∂q` at `v = 0` from one reverse sweep per step.
//!
//! Not here yet (typed refusals at `start`): forces and dissipation,
//! energy-preserving steps, Galerkin rules, double-double. The tangent map
//! (a dense `2N × 2N` matrix) is not offered for these systems.

use super::{Integrator, StepPolicy, implausible_growth, kahan, non_finite};
use crate::banded::{LinearSolveError, StepMatrix, StepSolver};
use crate::derivatives::Segment;
use crate::discrete::DiscreteLagrangian;
use crate::error::Error;
use crate::integrator::IMPLAUSIBLE_GROWTH;
use crate::newton::{self, Breakdown, Linearization, NewtonFailure, NewtonReport, Unknown};
use crate::real::max_abs;
use crate::state::State;
use crate::structure::Pattern;
use crate::system::Lagrangian;
use crate::tape::{Seeds, Tape, TapeError, Var};

/// How an integrator takes the derivatives of a step and solves its Newton
/// systems.
///
/// Both modes give the same steps to round-off (the tests compare them); they
/// differ in cost and memory:
///
/// | mode | derivatives | Newton solve | cost per iteration | memory |
/// |---|---|---|---|---|
/// | forward | array hyper-duals, one evaluation | dense, on the stack | `O(N²)` per operation of `L` | `O(N²)` stack per value |
/// | reverse | a tape, one reverse and one second-order sweep | banded (proven band) or dense LU, on the heap | `O(K)` per operation, `K = 2b + 1` or `N` | `O(ops)` heap |
///
/// Forward mode is faster for the smallest systems and has every capability;
/// reverse mode scales to large ones (a chain of 10 000 masses) but supports
/// only fixed steps of the one-point rules (midpoint, trapezoid, α-β, and
/// their compositions) in `f64` without forces for now — other combinations
/// are refused at `start` with [`Error::Unsupported`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Derivatives {
    /// Reverse mode above [`Derivatives::FORWARD_MAX_N`] coordinates, and
    /// from [`Derivatives::REVERSE_MIN_N`] for Newton steps it supports
    /// (fixed steps without forces; the explicit Störmer–Verlet path stays in
    /// forward mode up to `FORWARD_MAX_N`); forward mode otherwise.
    #[default]
    Automatic,
    /// Forward mode (array hyper-duals); refused above
    /// [`Derivatives::FORWARD_MAX_N`] coordinates, where its values would
    /// not fit on a thread's stack.
    Forward,
    /// Reverse mode (a tape) at any size.
    Reverse,
}

impl Derivatives {
    /// The largest system [`Derivatives::Automatic`] steps in forward mode
    /// and [`Derivatives::Forward`] accepts.
    pub const FORWARD_MAX_N: usize = 32;

    /// The smallest system [`Derivatives::Automatic`] steps in reverse mode
    /// when it can: measured (`examples`-style timing of an FPU-β chain and
    /// coupled pendula, midpoint, one run under load), reverse mode's Newton
    /// step is faster from `N = 8` (5.6 against 7.8 µs; at `N = 4`, 2.7
    /// against 0.65 µs) and 40 times faster at `N = 32` (23 against 911 µs).
    pub const REVERSE_MIN_N: usize = 8;

    /// Whether a system of `N` coordinates is stepped in reverse mode (after
    /// `start` resolved `Automatic`; unresolved, `Automatic` answers by size
    /// alone).
    pub(crate) const fn reverse<const N: usize>(self) -> bool {
        match self {
            Derivatives::Automatic => N > Self::FORWARD_MAX_N,
            Derivatives::Forward => false,
            Derivatives::Reverse => true,
        }
    }

    /// Refuses forward mode for systems too large for it.
    pub(crate) fn check<const N: usize, T: crate::real::Real>(self) -> Result<(), Error<N, T>> {
        if self == Derivatives::Forward && N > Self::FORWARD_MAX_N {
            return Err(Error::Unsupported {
                what: "forward-mode derivatives above `Derivatives::FORWARD_MAX_N` coordinates (their N×N parts would overflow the stack); use `Derivatives::Automatic` or `Reverse`",
            });
        }
        Ok(())
    }
}

/// Whether `n` coordinates are beyond forward mode. Used as `if const {
/// too_large_for_forward(N) }` in front of every forward-mode path: the
/// condition is a constant after monomorphization, so codegen can skip the
/// forward-mode code (whose `N × N` values are never needed there) for large
/// `N`. Compile time still grows faster than `N` at the test profile's
/// `opt-level = 2` (a test stepping an FPU chain: 14 s at `N = 200`, 56 s at
/// `N = 2000`, minutes beyond), which is why very large systems need a size
/// known at run time.
pub(crate) const fn too_large_for_forward(n: usize) -> bool {
    n > Derivatives::FORWARD_MAX_N
}

/// Why a system or a configuration has no reverse-mode step yet, if so.
pub(crate) fn unsupported<S: Lagrangian<N>, const N: usize>(policy: &StepPolicy) -> Option<&'static str> {
    if S::HAS_FORCE || S::HAS_DISSIPATION {
        return Some(
            "forces or dissipation with reverse-mode derivatives (systems larger than `Derivatives::FORWARD_MAX_N`)",
        );
    }
    if let StepPolicy::EnergyPreserving(_) = policy {
        return Some(
            "energy-preserving steps with reverse-mode derivatives (systems larger than `Derivatives::FORWARD_MAX_N`)",
        );
    }
    None
}

/// The bandwidth of the step Jacobian `∂²A/∂q_k∂q_{k+1}` (and of `∂²L/∂v²`),
/// `None` when it is not proven banded: the widest of the three Hessian
/// blocks of `L`, since every one-point rule mixes them.
const fn step_bandwidth<S: Lagrangian<N>, const N: usize>() -> Option<usize> {
    match S::COUPLING.overall().bandwidth() {
        // A band as wide as the matrix is no band.
        Some(b) if 2 * b + 1 < N => Some(b),
        _ => None,
    }
}

/// The bandwidth of the constant mass matrix `∂²L/∂v²`, `None` if not banded.
const fn mass_bandwidth<S: Lagrangian<N>, const N: usize>() -> Option<usize> {
    match S::COUPLING.v_v.bandwidth() {
        Some(b) if 2 * b + 1 < N => Some(b),
        _ => None,
    }
}

/// The Newton matrix for a step pattern with bandwidth `bandwidth` (`None`:
/// general): banded or dense by the banded module's measured rule.
fn step_matrix(n: usize, bandwidth: Option<usize>) -> Result<StepSolver, LinearSolveError> {
    StepSolver::for_pattern(n, bandwidth.map_or(Pattern::General, |b| Pattern::banded(n, b)))
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
fn breakdown(e: LinearSolveError) -> Breakdown {
    match e {
        LinearSolveError::Singular { rcond, .. } => Breakdown::Singular(rcond),
        LinearSolveError::NonFinite { quantity } => Breakdown::NonFinite(quantity),
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

/// The seeds of the second-order sweep on the inputs `columns`.
fn seeds(columns: core::ops::Range<usize>, bandwidth: Option<usize>) -> Seeds<'static> {
    match bandwidth {
        Some(b) => Seeds::banded(columns, b),
        None => Seeds::dense(columns),
    }
}

/// The heap-side work of reverse-mode steps: the tape and the buffers of its
/// sweeps (scratch, rebuilt when cloned), and what persists between steps.
#[derive(Debug)]
pub(crate) struct SparseWork {
    tape: Tape,
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
    mass: Option<Assembled>,
    /// Explicit path: `(k, ∂L/∂q(t_k, q_k, 0))`.
    node_force: Option<(u64, Vec<f64>)>,
}

impl Clone for SparseWork {
    fn clone(&self) -> Self {
        Self {
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
        }
    }
}

impl SparseWork {
    /// Work for the steps of a system with `N` coordinates: the action's
    /// inputs are `(q_k, Δq, h)`, the seeds sit on `Δq`.
    fn new<S: Lagrangian<N>, const N: usize>() -> Result<Self, LinearSolveError> {
        let bandwidth = step_bandwidth::<S, N>();
        let width = bandwidth.map_or(N, |b| 2 * b + 1);
        let inputs = 2 * N + 1;
        let directions = seeds(N..2 * N, bandwidth).directions();
        Ok(Self {
            tape: Tape::new(),
            inputs: vec![0.0; inputs],
            gradient: vec![0.0; inputs],
            products: vec![0.0; inputs * directions],
            mixed: vec![0.0; N * width],
            end: vec![0.0; N * width],
            jacobian: step_matrix(N, bandwidth)?,
            energy: None,
            mass: None,
            node_force: None,
        })
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

    /// Records the action `A(q_k, Δq, h)` at `t_k = t0` on the tape.
    fn record_action<S, M, const N: usize>(
        &mut self,
        system: &S,
        method: &M,
        t0: f64,
        h: f64,
        q0: &[f64; N],
        dq: &[f64],
    ) -> Result<f64, TapeError>
    where
        S: Lagrangian<N>,
        M: DiscreteLagrangian,
    {
        self.inputs[..N].copy_from_slice(q0);
        self.inputs[N..2 * N].copy_from_slice(dq);
        self.inputs[2 * N] = h;
        self.tape.record(&self.inputs, |x: &[Var]| {
            let q: [Var; N] = core::array::from_fn(|i| x[i]);
            let dq: [Var; N] = core::array::from_fn(|i| x[N + i]);
            method.action(system, Var::constant(t0), x[2 * N], q, dq)
        })
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
        let amax = |v: &[f64]| v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        amax(dx) / (rtol * amax(self) + atol)
    }
}

impl<S: Lagrangian<N>, M: DiscreteLagrangian, const N: usize> Integrator<S, M, N> {
    /// Whether this integrator steps in reverse mode.
    #[inline(always)]
    pub(super) fn reverse(&self) -> bool {
        self.derivatives.reverse::<N>()
    }

    /// The reverse-mode work, created at the first step.
    fn take_work(&mut self, h: f64) -> Result<Box<SparseWork>, Error<N>> {
        match self.memory.sparse.take() {
            Some(work) => Ok(work),
            None => SparseWork::new::<S, N>().map(Box::new).map_err(|_| {
                let reason = "the step matrix of this size cannot be allocated";
                self.fail(h, NewtonFailure::Rejected { iterations: 0, reason })
            }),
        }
    }

    /// One fixed step in reverse mode (see the module docs): the same
    /// predictor, Newton convergence rule, plausibility check, Kahan sums and
    /// failure semantics as the forward-mode step.
    pub(super) fn sparse_step(&mut self, h: f64, t1: f64) -> Result<(), Error<N>> {
        let mut work = self.take_work(h)?;
        let outcome = self.sparse_advance(&mut work, h, t1);
        self.memory.sparse = Some(work);
        outcome
    }

    fn sparse_advance(&mut self, work: &mut SparseWork, h: f64, t1: f64) -> Result<(), Error<N>> {
        let State { step, t: t0, q: q0, p: p0 } = self.state;
        let (dq, report) = self.sparse_solve(work, h).map_err(|failure| self.fail(h, failure))?;
        // The momentum change at fixed increment and the step's energy.
        let swept = work
            .record_action(&self.system, &self.method, t0, h, &q0, &dq)
            .and_then(|_| work.tape.gradient(&mut work.gradient));
        if swept.is_err() {
            let reason = "the derivative tape failed";
            return Err(self.fail(h, NewtonFailure::Rejected { iterations: report.iterations, reason }));
        }
        let dp: [f64; N] = core::array::from_fn(|i| work.gradient[i]);
        let energy = -work.gradient[2 * N];
        let dq: [f64; N] = core::array::from_fn(|i| dq[i]);
        let (q1, carry) = kahan(&q0, &self.carry, &dq);
        let (p1, p_carry) = kahan(&p0, &self.p_carry, &dp);
        if let Some(quantity) = non_finite(t1, &q1, &p1) {
            self.stats.failed_steps += 1;
            return Err(Error::NonFinite { state: self.state, h, iterations: report.iterations, quantity });
        }
        if S::DISCONTINUOUS {
            let before = work.energy.unwrap_or(self.energy);
            let jump = (energy - before).abs() / before.abs().max(f64::MIN_POSITIVE);
            if jump.is_finite() && jump > self.stats.largest_energy_jump {
                self.stats.largest_energy_jump = jump;
                self.stats.largest_energy_jump_at = t1;
            }
        }
        work.energy = Some(energy);
        self.carry = carry;
        self.p_carry = p_carry;
        self.memory.earlier = self.memory.previous.map(|last| (last.h, last.dq));
        self.memory.previous = Some(Segment { t0, h, q0, dq });
        self.state = State { step: step + 1, t: t1, q: q1, p: p1 };
        self.stats.steps += 1;
        self.stats.newton_iterations += report.iterations as u64;
        self.stats.last = report;
        Ok(())
    }

    /// Newton on `r(Δq) = p_k + ∂A/∂q_k = 0` with banded or dense solves.
    fn sparse_solve(&self, work: &mut SparseWork, h: f64) -> Result<(Vec<f64>, NewtonReport), NewtonFailure> {
        let State { t: t0, q: q0, p: p0, .. } = self.state;
        let predictor = self.predict(h);
        let (system, method, min_rcond) = (&self.system, &self.method, self.newton.min_rcond);
        let pc = self.p_carry;
        let bandwidth = step_bandwidth::<S, N>();
        let seeds = seeds(N..2 * N, bandwidth);
        // The condition estimate (a few solves, 1.5–3.6 times a banded
        // factor+solve) on the first iteration of the step only: the Jacobian
        // barely changes within a step; later iterations still refuse a zero
        // or non-finite pivot.
        let mut first = true;
        let linearize = |x: &Vec<f64>| -> Result<Linearization<Vec<f64>>, Breakdown> {
            work.record_action(system, method, t0, h, &q0, x).map_err(tape_breakdown)?;
            work.tape.hessian_product(&seeds, &mut work.gradient, &mut work.products).map_err(tape_breakdown)?;
            let g = &work.gradient;
            let mut r = vec![0.0; N];
            let mut scale = max_abs(&p0);
            for i in 0..N {
                let d_q0 = g[i] - g[N + i];
                r[i] = (p0[i] + d_q0) + pc[i];
                scale = scale.max(d_q0.abs());
            }
            if !r.iter().all(|x| x.is_finite()) {
                return Err(Breakdown::NonFinite("residual"));
            }
            // J = ∂²A/∂q_k∂Δq − ∂²A/∂Δq², entry by entry of the pattern.
            seeds.recover(&work.products, 0..N, &mut work.mixed).map_err(tape_breakdown)?;
            seeds.recover(&work.products, N..2 * N, &mut work.end).map_err(tape_breakdown)?;
            for (a, b) in work.mixed.iter_mut().zip(&work.end) {
                *a -= b;
            }
            let rcond_floor = if first { min_rcond } else { 0.0 };
            first = false;
            assemble_and_factor(&mut work.jacobian, N, bandwidth, &work.mixed, rcond_floor)?;
            let residual_norm = r.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            let mut correction = r;
            work.jacobian.solve(&mut correction).map_err(breakdown)?;
            for x in correction.iter_mut() {
                *x = -*x;
            }
            Ok(Linearization { correction, residual_norm, residual_ratio: f64::INFINITY }.cancelling(scale))
        };
        let (dq, report) = newton::solve(predictor.to_vec(), &self.newton, linearize)?;
        if let Some(last) = &self.memory.previous {
            let dq_arr: [f64; N] = core::array::from_fn(|i| dq[i]);
            if implausible_growth(&dq_arr, &predictor, &last.dq.map(|x| x * (h / last.h)), &q0) {
                let reason = IMPLAUSIBLE_GROWTH;
                return Err(NewtonFailure::Rejected { iterations: report.iterations, reason });
            }
        }
        Ok((dq, report))
    }

    /// The explicit (Störmer–Verlet) step of the trapezoid rule on a
    /// separable system with constant mass, in reverse mode: `M` factored
    /// once (banded when proven), `∂L/∂q` from one reverse sweep per step,
    /// reused at the next node. Same formula, sums and failure semantics as
    /// the forward-mode explicit step.
    pub(super) fn sparse_verlet_step(&mut self, h: f64, t1: f64) -> Result<(), Error<N>> {
        let mut work = self.take_work(h)?;
        let outcome = self.sparse_verlet_advance(&mut work, h, t1);
        self.memory.sparse = Some(work);
        outcome
    }

    fn sparse_verlet_advance(&mut self, work: &mut SparseWork, h: f64, t1: f64) -> Result<(), Error<N>> {
        let State { step, t: t0, q: q0, p: p0 } = self.state;
        let tape_failed = |it: &mut Self| {
            let reason = "the derivative tape failed";
            it.fail(h, NewtonFailure::Rejected { iterations: 0, reason })
        };
        if work.mass.is_none() {
            let mass = velocity_derivatives(&self.system, t0, &q0, &[0.0; N], mass_bandwidth::<S, N>())
                .map_err(|b| self.fail(h, b.at(0)))
                .and_then(|(_, _, mut mass)| {
                    mass.factor_in_place(self.newton.min_rcond).map_err(|b| self.fail(h, b.at(0)))?;
                    Ok(mass)
                })?;
            work.mass = Some(mass);
        }
        let f0 = match work.node_force.take() {
            Some((k, f)) if k == step => f,
            _ => {
                let mut f = vec![0.0; N];
                if potential_force(&self.system, &mut work.tape, t0, &q0, &mut f).is_err() {
                    return Err(tape_failed(self));
                }
                f
            }
        };
        let half = 0.5 * h;
        let mut v: Vec<f64> = (0..N).map(|i| (p0[i] + half * f0[i]) + self.p_carry[i]).collect();
        if let Some(mass) = &work.mass
            && let Err(e) = mass.solve(&mut v)
        {
            work.node_force = Some((step, f0));
            return Err(self.fail(h, breakdown(e).at(0)));
        }
        let dq: [f64; N] = core::array::from_fn(|i| v[i] * h);
        if let Some(last) = &self.memory.previous
            && implausible_growth(&dq, &self.predict(h), &last.dq.map(|x| x * (h / last.h)), &q0)
        {
            work.node_force = Some((step, f0));
            let reason = IMPLAUSIBLE_GROWTH;
            return Err(self.fail(h, NewtonFailure::Rejected { iterations: 0, reason }));
        }
        let (q1, carry) = kahan(&q0, &self.carry, &dq);
        let mut f1 = vec![0.0; N];
        if potential_force(&self.system, &mut work.tape, t1, &q1, &mut f1).is_err() {
            work.node_force = Some((step, f0));
            return Err(tape_failed(self));
        }
        let dp: [f64; N] = core::array::from_fn(|i| half * (f0[i] + f1[i]));
        let (p1, p_carry) = kahan(&p0, &self.p_carry, &dp);
        if let Some(quantity) = non_finite(t1, &q1, &p1) {
            work.node_force = Some((step, f0));
            self.stats.failed_steps += 1;
            return Err(Error::NonFinite { state: self.state, h, iterations: 0, quantity });
        }
        work.node_force = Some((step + 1, f1));
        // The discrete energy of a Verlet step is computed on request only.
        work.energy = None;
        self.carry = carry;
        self.p_carry = p_carry;
        self.memory.earlier = self.memory.previous.map(|last| (last.h, last.dq));
        self.memory.previous = Some(Segment { t0, h, q0, dq });
        self.state = State { step: step + 1, t: t1, q: q1, p: p1 };
        self.stats.steps += 1;
        self.stats.last = NewtonReport { iterations: 0, residual_norm: 0.0, correction_norm: 0.0 };
        Ok(())
    }

    /// The discrete energy `−∂A/∂t_{k+1}` of the last step in reverse mode
    /// (one reverse sweep unless the step already recorded it); the energy
    /// of the initial data before the first step.
    pub(super) fn sparse_discrete_energy(&self) -> f64 {
        let Some(seg) = &self.memory.previous else { return self.energy };
        match self.memory.sparse.as_ref().and_then(|w| w.energy) {
            Some(e) => e,
            None => step_energy(&self.system, &self.method, seg),
        }
    }
}

/// The discrete energy `−∂A/∂t_{k+1}` of the step `seg`, from one reverse
/// sweep (NaN if the tape fails, which the runtime's use cannot provoke).
pub(crate) fn step_energy<S: Lagrangian<N>, M: DiscreteLagrangian, const N: usize>(
    system: &S,
    method: &M,
    seg: &Segment<N>,
) -> f64 {
    let mut tape = Tape::new();
    let mut inputs = Vec::with_capacity(2 * N + 1);
    inputs.extend_from_slice(&seg.q0);
    inputs.extend_from_slice(&seg.dq);
    inputs.push(seg.h);
    let recorded = tape.record(&inputs, |x: &[Var]| {
        let q: [Var; N] = core::array::from_fn(|i| x[i]);
        let dq: [Var; N] = core::array::from_fn(|i| x[N + i]);
        method.action(system, Var::constant(seg.t0), x[2 * N], q, dq)
    });
    let mut gradient = vec![0.0; 2 * N + 1];
    match recorded.and_then(|_| tape.gradient(&mut gradient)) {
        Ok(()) => -gradient[2 * N],
        Err(_) => f64::NAN,
    }
}

/// `∂L/∂q(t, q, 0) = −∇V(t, q)` of a separable system, from one reverse
/// sweep with the inputs `q`.
fn potential_force<S: Lagrangian<N>, const N: usize>(
    system: &S,
    tape: &mut Tape,
    t: f64,
    q: &[f64; N],
    out: &mut [f64],
) -> Result<(), TapeError> {
    tape.record(q, |x: &[Var]| {
        let qq: [Var; N] = core::array::from_fn(|i| x[i]);
        system.lagrangian(Var::constant(t), qq, [Var::constant(0.0); N])
    })?;
    tape.gradient(out)
}

/// `L`, `∂L/∂v` and `∂²L/∂v²` (assembled, not factored; banded with the
/// given bandwidth, or dense) at `(t, q, v)`, from one second-order sweep
/// with the inputs `v`.
fn velocity_derivatives<S: Lagrangian<N>, const N: usize>(
    system: &S,
    t: f64,
    q: &[f64; N],
    v: &[f64; N],
    bandwidth: Option<usize>,
) -> Result<(f64, Vec<f64>, Assembled), Breakdown> {
    let seeds = seeds(0..N, bandwidth);
    let mut tape = Tape::new();
    let l = tape
        .record(v, |x: &[Var]| {
            let vv: [Var; N] = core::array::from_fn(|i| x[i]);
            system.lagrangian(Var::constant(t), q.map(Var::constant), vv)
        })
        .map_err(tape_breakdown)?;
    let mut gradient = vec![0.0; N];
    let mut products = vec![0.0; N * seeds.directions()];
    tape.hessian_product(&seeds, &mut gradient, &mut products).map_err(tape_breakdown)?;
    let width = bandwidth.map_or(N, |b| 2 * b + 1);
    let mut band = vec![0.0; N * width];
    seeds.recover(&products, 0..N, &mut band).map_err(tape_breakdown)?;
    let matrix = step_matrix(N, bandwidth).map_err(breakdown)?;
    Ok((l, gradient, Assembled { n: N, matrix, band, bandwidth }))
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
/// check that `∂²L/∂v²` is regular there (its banded or dense LU), in reverse
/// mode.
pub(crate) fn legendre<S: Lagrangian<N>, const N: usize>(
    system: &S,
    t: f64,
    q: [f64; N],
    v: [f64; N],
) -> Result<([f64; N], f64), Error<N>> {
    let invalid = |reason| Error::InvalidInitialData { reason };
    let (l, p, mut hessian) = velocity_derivatives(system, t, &q, &v, mass_bandwidth::<S, N>())
        .map_err(|_| invalid("the lagrangian or its derivatives could not be evaluated at the initial data"))?;
    if !l.is_finite() || !p.iter().all(|x| x.is_finite()) {
        return Err(invalid("the lagrangian or its momentum is not finite at the initial data"));
    }
    if hessian.factor_in_place(0.0).is_err() {
        return Err(invalid("∂²L/∂v² is singular at the initial data: the legendre transform is not regular"));
    }
    let p: [f64; N] = core::array::from_fn(|i| p[i]);
    let energy = (0..N).map(|i| v[i] * p[i]).sum::<f64>() - l;
    if !energy.is_finite() {
        return Err(invalid("the energy is not finite at the initial data"));
    }
    Ok((p, energy))
}

/// The energy `E = v·∂L/∂v − L` at `(t, q, v)`, from one reverse sweep (NaN
/// if the tape fails).
pub(crate) fn energy<S: Lagrangian<N>, const N: usize>(system: &S, t: f64, q: &[f64; N], v: &[f64; N]) -> f64 {
    let mut tape = Tape::new();
    let mut p = vec![0.0; N];
    let swept = tape
        .record(v, |x: &[Var]| {
            let vv: [Var; N] = core::array::from_fn(|i| x[i]);
            system.lagrangian(Var::constant(t), q.map(Var::constant), vv)
        })
        .and_then(|l| tape.gradient(&mut p).map(|_| l));
    match swept {
        Ok(l) => (0..N).map(|i| v[i] * p[i]).sum::<f64>() - l,
        Err(_) => f64::NAN,
    }
}

/// The velocity whose momentum `∂L/∂v(t, q, v)` is `p`, by Newton's method
/// from `guess` with banded or dense solves (the inverse Legendre transform
/// in reverse mode). `Err` carries `(iterations, residual norm)`.
pub(crate) fn velocity<S: Lagrangian<N>, const N: usize>(
    system: &S,
    t: f64,
    q: &[f64; N],
    p: &[f64; N],
    guess: &[f64; N],
) -> Result<[f64; N], (usize, f64)> {
    let options = newton::NewtonOptions::default();
    let bandwidth = mass_bandwidth::<S, N>();
    let linearize = |v: &Vec<f64>| -> Result<Linearization<Vec<f64>>, Breakdown> {
        let v: [f64; N] = core::array::from_fn(|i| v[i]);
        let (_, m, mut hessian) = velocity_derivatives(system, t, q, &v, bandwidth)?;
        let mut r: Vec<f64> = (0..N).map(|i| m[i] - p[i]).collect();
        if !r.iter().all(|x| x.is_finite()) {
            return Err(Breakdown::NonFinite("residual"));
        }
        let scale = max_abs(p).max(m.iter().fold(0.0f64, |a, x| a.max(x.abs())));
        hessian.factor_in_place(options.min_rcond)?;
        let residual_norm = r.iter().fold(0.0f64, |a, x| a.max(x.abs()));
        hessian.solve(&mut r).map_err(breakdown)?;
        r.iter_mut().for_each(|x| *x = -*x);
        Ok(Linearization { correction: r, residual_norm, residual_ratio: f64::INFINITY }.cancelling(scale))
    };
    match newton::solve(guess.to_vec(), &options, linearize) {
        Ok((v, _)) => Ok(core::array::from_fn(|i| v[i])),
        Err(NewtonFailure::NotConverged(r)) => Err((r.iterations, r.residual_norm)),
        Err(f) => Err((f.iterations(), f64::INFINITY)),
    }
}
