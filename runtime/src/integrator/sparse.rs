//! Large systems: one-point steps whose derivatives come from a tape swept in
//! reverse, and whose Newton systems are banded (or dense) on the heap.
//!
//! The step itself (recording the action, Newton with banded or dense
//! solves, the explicit Störmer–Verlet path, the Legendre map, the energy)
//! lives in `tape_step.rs` on slices, shared with the run-time-sized
//! [`DynIntegrator`](crate::DynIntegrator); this file adapts a const-size
//! system and its discrete Lagrangian to it ([`Fixed`]) and keeps the
//! integrator's `[f64; N]` state.
//!
//! Why: the forward-mode array hyper-duals of the small-system path carry an
//! `N × N` block in every intermediate value, so an `L` with `O(N)` operations
//! costs `O(N³)` per Newton iteration and overflows the stack near `N = 64`.
//! Reverse mode's gradient costs `O(ops)` and its Jacobian `O(K·ops)`, where
//! the number of seed directions `K` is `2b + 1` when the macro proved the
//! Hessian of `L` banded with bandwidth `b` ([`Lagrangian::COUPLING`]).
//!
//! Not here yet (typed refusals at `start`): forces and dissipation,
//! energy-preserving steps, Galerkin rules, double-double. The tangent map
//! (a dense `2N × 2N` matrix) is not offered for these systems.

pub(crate) use super::tape_step::LastSubstep;
use super::tape_step::{self, Composed, Growth, Guess, Node, SparseWork, Taken, TapeModel};
use super::{Integrator, OnePointMemory, Stats, StepPolicy, Summation};
use crate::derivatives::Segment;
use crate::discrete::DiscreteLagrangian;
use crate::error::Error;
use crate::newton::{NewtonFailure, NewtonOptions, NewtonReport};
use crate::state::State;
use crate::structure::Coupling;
use crate::system::{Lagrangian, Scalar};
use crate::tape::Var;

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
    /// when it can: where a midpoint step costs the same in both modes, for
    /// a banded FPU-β chain and a dense `N`-link pendulum alike
    /// (`examples/step_profile.rs`, cases `chainN` and `nlinkN` with
    /// `midpoint-forward` and `midpoint-reverse`, compare them).
    pub const REVERSE_MIN_N: usize = 10;

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
    pub(crate) fn check<const N: usize, T: crate::real::Real>(self) -> Result<(), Error<T>> {
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

/// A const-size system and its discrete Lagrangian as the shared
/// reverse-mode core sees them: slices copied into `[Var; N]` arrays (16
/// bytes per entry) for the user's `L` and the rule's action.
pub(crate) struct Fixed<'a, S, M, const N: usize> {
    pub(crate) system: &'a S,
    pub(crate) method: &'a M,
}

impl<S: Lagrangian<N>, M: DiscreteLagrangian, const N: usize> TapeModel for Fixed<'_, S, M, N> {
    fn coupling(&self) -> Coupling {
        S::COUPLING
    }

    fn lagrangian(&self, t: Var, q: &[Var], v: &[Var]) -> Var {
        let (q, v): ([Var; N], [Var; N]) = (core::array::from_fn(|i| q[i]), core::array::from_fn(|i| v[i]));
        self.system.lagrangian(t, q, v)
    }

    fn action(&self, t0: Var, h: Var, q0: &[Var], dq: &[Var]) -> Var {
        let (q0, dq): ([Var; N], [Var; N]) = (core::array::from_fn(|i| q0[i]), core::array::from_fn(|i| dq[i]));
        self.method.action(self.system, t0, h, q0, dq)
    }

    fn gradient_q(&self, t: f64, q: &[f64], zero: &[f64], out: &mut [f64]) -> bool {
        let (Ok(q), Ok(zero), Ok(out)) =
            (<&[f64; N]>::try_from(q), <&[f64; N]>::try_from(zero), <&mut [f64; N]>::try_from(out))
        else {
            return false;
        };
        if S::HAS_GRADIENT {
            self.system.gradient_q(t, q, zero, out);
        }
        S::HAS_GRADIENT
    }

    fn value_gradient_q(&self, t: f64, q: &[f64], zero: &[f64], out: &mut [f64]) -> Option<f64> {
        if !S::HAS_GRADIENT {
            return None;
        }
        let (Ok(q), Ok(zero), Ok(out)) =
            (<&[f64; N]>::try_from(q), <&[f64; N]>::try_from(zero), <&mut [f64; N]>::try_from(out))
        else {
            return None;
        };
        Some(self.system.value_gradient_q(t, q, zero, out))
    }

    fn add_gradient_q_at_rest(&self, t: f64, q: &[f64], out: &mut [f64]) -> Option<bool> {
        if !S::HAS_GRADIENT {
            return None;
        }
        let (Ok(q), Ok(out)) = (<&[f64; N]>::try_from(q), <&mut [f64; N]>::try_from(out)) else {
            return None;
        };
        Some(self.system.add_gradient_q_at_rest(t, q, out))
    }

    fn autonomous(&self) -> bool {
        S::AUTONOMOUS
    }

    fn points(&self) -> Option<[f64; 2]> {
        self.method.galerkin_points().map(|(points, _)| points)
    }

    fn has_gradient_qv(&self) -> bool {
        S::HAS_GRADIENT_QV
    }

    crate::integrator::tape_step::scalar_methods!();
}

impl<S: Lagrangian<N>, M: DiscreteLagrangian, const N: usize> Fixed<'_, S, M, N> {
    fn gradient_qv_generic<D: Scalar>(&self, t: D, q: &[D], v: &[D], out_q: &mut [D], out_v: &mut [D]) {
        self.system.gradient_qv_scalar(t, q, v, out_q, out_v);
    }
    fn lagrangian_generic<D: Scalar>(&self, t: D, q: &[D], v: &[D]) -> D {
        let (q, v): ([D; N], [D; N]) = (core::array::from_fn(|i| q[i]), core::array::from_fn(|i| v[i]));
        self.system.lagrangian(t, q, v)
    }
}

/// A slice of length `N` as an array.
fn array<const N: usize>(x: &[f64]) -> [f64; N] {
    core::array::from_fn(|i| x[i])
}

impl<S: Lagrangian<N>, M: DiscreteLagrangian, const N: usize> Integrator<S, M, N> {
    /// Whether this integrator steps in reverse mode.
    #[inline(always)]
    pub(super) fn reverse(&self) -> bool {
        self.derivatives.reverse::<N>()
    }

    /// One fixed step in reverse mode: the Newton step of the shared core
    /// (`tape_step.rs`), or its explicit Störmer–Verlet step when `explicit`.
    /// A failed step leaves the integrator as it was.
    pub(super) fn sparse_step(&mut self, h: f64, t1: f64, explicit: bool) -> Result<(), Error> {
        let mut stepper = Stepper {
            system: &self.system,
            method: &self.method,
            newton: &self.newton,
            v0: &self.v0,
            energy: self.energy,
            state: &mut self.state,
            memory: &mut self.memory,
            stats: &mut self.stats,
            summation: self.summation,
        };
        stepper.step(h, t1, explicit)
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

/// What a reverse-mode step reads and writes of a const-size integrator,
/// borrowed field by field: an integrator's own (`sparse_step`), or a
/// composition's, whose trapezoid sub-steps then step its fields in place
/// instead of a sub-integrator built by value (a copy of every inline array).
pub(super) struct Stepper<'a, S, M, const N: usize> {
    pub(super) system: &'a S,
    pub(super) method: &'a M,
    pub(super) newton: &'a NewtonOptions,
    pub(super) v0: &'a [f64; N],
    /// `E_0`, which the energy watch of a discontinuous system compares the
    /// first step's with.
    pub(super) energy: f64,
    pub(super) state: &'a mut State<N>,
    pub(super) memory: &'a mut OnePointMemory<N>,
    pub(super) stats: &'a mut Stats,
    /// Under [`Summation::Plain`] the work's carries stay zero.
    pub(super) summation: Summation,
}

impl<S: Lagrangian<N>, M: DiscreteLagrangian, const N: usize> Stepper<'_, S, M, N> {
    /// One fixed step (see `Integrator::sparse_step`); a failed one changes
    /// nothing but the failure count.
    pub(super) fn step(&mut self, h: f64, t1: f64, explicit: bool) -> Result<(), Error> {
        let mut work = self.work(h)?;
        let outcome = self.advance(&mut work, h, t1, explicit);
        self.memory.sparse = Some(work);
        // The error (which holds the state) is made here, in the returned
        // value: a `Result<(), Error>` held across the line above would
        // be moved whole, both arrays of the state copied at every
        // successful step (16 000 instructions of an explicit FPU-β step
        // at `N = 1000`, callgrind).
        outcome.map_err(|failure| self.fail(h, failure))
    }

    /// The reverse-mode work, taken out of the memory (made at the first
    /// step); the caller puts it back.
    fn work(&mut self, h: f64) -> Result<Box<SparseWork>, Error> {
        match self.memory.sparse.take() {
            Some(work) => Ok(work),
            None => match SparseWork::new(N, S::COUPLING) {
                Ok(work) => Ok(Box::new(work)),
                Err(_) => {
                    let reason = "the step matrix of this size cannot be allocated";
                    Err(self.fail(h, NewtonFailure::Rejected { iterations: 0, reason }))
                }
            },
        }
    }

    /// One composed step of explicit trapezoid sub-steps of sizes `γ_i h`
    /// (`weights`), fused (`SparseWork::verlet_composed`) and committed
    /// once: the memory then holds whole steps, as forward mode's fused
    /// compositions do, and `last_substep` receives the last sub-step (the
    /// readouts' segment). A failed step changes nothing but the failure
    /// count.
    pub(super) fn composed_step(
        &mut self,
        h: f64,
        t1: f64,
        weights: &[f64],
        last_substep: &mut Option<LastSubstep>,
    ) -> Result<(), Error> {
        let mut work = self.work(h)?;
        let [q_carry, p_carry] = core::mem::take(&mut work.carries);
        let outcome = {
            let model = Fixed { system: self.system, method: self.method };
            let State { step, t, ref q, ref p } = *self.state;
            let plain = self.summation.is_plain();
            let node = Node { step, t, q, p, q_carry: &q_carry, p_carry: &p_carry, plain };
            // The predictor only when the growth check needs it.
            let predict = |out: &mut [f64]| out.copy_from_slice(&self.predict(h));
            let last = self.memory.previous.as_ref().map(|last| (&last.dq[..], h / last.h));
            let growth = Growth { last, predict: &predict };
            work.verlet_composed(&model, &node, h, t1, weights, &growth, self.newton.min_rcond)
        };
        let Composed { taken, last } = match outcome {
            Ok(composed) => composed,
            Err(failure) => {
                work.carries = [q_carry, p_carry];
                self.memory.sparse = Some(work);
                return Err(self.fail(h, failure));
            }
        };
        let Taken { dq: total, q1, q_carry: q_carry1, p1, p_carry: p_carry1, report } = taken;
        self.commit(&total, &q1, &p1, report, h, t1);
        let [q_carry, p_carry] = self.swap_carries(&mut work, [q_carry, p_carry], [q_carry1, p_carry1]);
        // The last sub-step's buffers are kept, not copied.
        if let Some(old) = last_substep.replace(last) {
            work.recycle(old.q0);
            work.recycle(old.dq);
        }
        for buffer in [total, q1, p1, q_carry, p_carry] {
            work.recycle(buffer);
        }
        self.memory.sparse = Some(work);
        Ok(())
    }

    /// The step of [`step`](Self::step) on `work`, committed on success; on
    /// failure nothing changes and the failure is returned.
    fn advance(&mut self, work: &mut SparseWork, h: f64, t1: f64, explicit: bool) -> Result<(), NewtonFailure> {
        // The carries out of the work while it steps; put back, or replaced
        // by the step's, below.
        let [q_carry, p_carry] = core::mem::take(&mut work.carries);
        // The last step's discrete energy, read before an explicit step clears it.
        let before = work.energy.unwrap_or(self.energy);
        let outcome = self.try_step(work, h, t1, explicit, (&q_carry, &p_carry));
        let (taken, energy) = match outcome {
            Ok(taken) => taken,
            Err(failure) => {
                work.carries = [q_carry, p_carry];
                return Err(failure);
            }
        };
        // An explicit step computes no energy; a discontinuous system's watch
        // takes it from the new segment (one reverse sweep).
        let energy = match energy {
            None if S::DISCONTINUOUS => {
                let seg = Segment { t0: self.state.t, h, q0: self.state.q, dq: array(&taken.dq) };
                Some(step_energy(self.system, self.method, &seg))
            }
            energy => energy,
        };
        if let (true, Some(after)) = (S::DISCONTINUOUS, energy) {
            tape_step::watch_energy_jump(self.stats, before, after, t1);
        }
        if !explicit || S::DISCONTINUOUS {
            work.energy = energy;
        }
        let Taken { dq, q1, q_carry: q_carry1, p1, p_carry: p_carry1, report } = taken;
        self.commit(&dq, &q1, &p1, report, h, t1);
        let [q_carry, p_carry] = self.swap_carries(work, [q_carry, p_carry], [q_carry1, p_carry1]);
        for buffer in [dq, q1, p1, q_carry, p_carry] {
            work.recycle(buffer);
        }
        Ok(())
    }

    /// Puts the step's new compensations `taken` into the work in place of
    /// the node's `old` and returns the buffers to recycle: `old` then, or,
    /// under [`Summation::Plain`] (whose steps leave `taken` unwritten), the
    /// step's, the node's zeros staying.
    fn swap_carries(&self, work: &mut SparseWork, old: [Vec<f64>; 2], taken: [Vec<f64>; 2]) -> [Vec<f64>; 2] {
        // The work's carries were taken out for the step (they are `old`).
        let (kept, freed) = match self.summation {
            Summation::Compensated => (taken, old),
            Summation::Plain => (old, taken),
        };
        work.carries = kept;
        freed
    }

    /// The step of [`advance`](Self::advance) from the node
    /// with the Kahan compensations `carries`, nothing changed yet.
    fn try_step(
        &self,
        work: &mut SparseWork,
        h: f64,
        t1: f64,
        explicit: bool,
        carries: (&[f64], &[f64]),
    ) -> Result<(Taken, Option<f64>), NewtonFailure> {
        let model = Fixed { system: self.system, method: self.method };
        let State { step, t, ref q, ref p } = *self.state;
        let node = Node { step, t, q, p, q_carry: carries.0, p_carry: carries.1, plain: self.summation.is_plain() };
        if explicit {
            // The predictor only when the growth check needs it.
            let predict = |out: &mut [f64]| out.copy_from_slice(&self.predict(h));
            let last = self.memory.previous.as_ref().map(|last| (&last.dq[..], h / last.h));
            let growth = Growth { last, predict: &predict };
            work.verlet_step(&model, &node, h, t1, &growth, self.newton.min_rcond).map(|taken| (taken, None))
        } else {
            let predictor = self.predict(h);
            let last = self.memory.previous.map(|last| last.dq.map(|x| x * (h / last.h)));
            let guess = Guess { predictor: &predictor, last: last.as_ref().map(|x| &x[..]) };
            work.newton_step(&model, &node, h, t1, &guess, self.newton).map(|(taken, e)| (taken, Some(e)))
        }
    }

    /// Replaces the state by the step `(Δq, q_{k+1}, p_{k+1})` from the
    /// current node, in place (the arrays are copied into, not moved; the
    /// carries are the caller's).
    fn commit(&mut self, dq: &[f64], q1: &[f64], p1: &[f64], report: NewtonReport, h: f64, t1: f64) {
        let memory = &mut *self.memory;
        match (&memory.previous, &mut memory.earlier) {
            (Some(last), Some((h_earlier, dq_earlier))) => {
                *h_earlier = last.h;
                dq_earlier.copy_from_slice(&last.dq);
            }
            (Some(last), earlier) => *earlier = Some((last.h, last.dq)),
            (None, earlier) => *earlier = None,
        }
        match &mut memory.previous {
            Some(last) => {
                last.t0 = self.state.t;
                last.h = h;
                last.q0.copy_from_slice(&self.state.q);
                last.dq.copy_from_slice(dq);
            }
            None => memory.previous = Some(Segment { t0: self.state.t, h, q0: self.state.q, dq: array(dq) }),
        }
        self.state.q.copy_from_slice(q1);
        self.state.p.copy_from_slice(p1);
        self.state.step += 1;
        self.state.t = t1;
        self.stats.steps += 1;
        self.stats.newton_iterations += report.iterations as u64;
        self.stats.last = report;
    }

    /// Counts a failed step and turns its failure into the error.
    fn fail(&mut self, h: f64, failure: NewtonFailure) -> Error {
        self.stats.failed_steps += 1;
        Error::from_newton(failure, *self.state, h)
    }

    /// The increment predicted for a step of size `h`.
    fn predict(&self, h: f64) -> [f64; N] {
        self.memory.predict(h, self.v0)
    }
}

impl LastSubstep {
    /// As a segment of a const-size system.
    pub(crate) fn segment<const N: usize>(&self) -> Segment<N> {
        Segment { t0: self.t0, h: self.h, q0: array(&self.q0), dq: array(&self.dq) }
    }
}

/// The discrete energy `−∂A/∂t_{k+1}` of the step `seg`, from one reverse
/// sweep (NaN if the tape fails, which the runtime's use cannot provoke).
pub(crate) fn step_energy<S: Lagrangian<N>, M: DiscreteLagrangian, const N: usize>(
    system: &S,
    method: &M,
    seg: &Segment<N>,
) -> f64 {
    tape_step::step_energy(&Fixed { system, method }, seg.t0, seg.h, &seg.q0, &seg.dq)
}

/// The momentum `p = ∂L/∂v` and energy `E = v·p − L` at `(t, q, v)`, with a
/// check that `∂²L/∂v²` is regular there (its banded or dense LU), in reverse
/// mode.
pub(crate) fn legendre<S: Lagrangian<N>, const N: usize>(
    system: &S,
    t: f64,
    q: [f64; N],
    v: [f64; N],
) -> Result<([f64; N], f64), Error> {
    // The rule is not used by the readouts of `L`; any one will do.
    let model = Fixed { system, method: &crate::Midpoint };
    let (p, energy) = tape_step::legendre(&model, t, &q, &v).map_err(|reason| Error::InvalidInitialData { reason })?;
    Ok((array(&p), energy))
}

/// The energy `E = v·∂L/∂v − L` at `(t, q, v)`, from one reverse sweep (NaN
/// if the tape fails).
pub(crate) fn energy<S: Lagrangian<N>, const N: usize>(system: &S, t: f64, q: &[f64; N], v: &[f64; N]) -> f64 {
    tape_step::energy(&Fixed { system, method: &crate::Midpoint }, t, q, v)
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
    tape_step::velocity(&Fixed { system, method: &crate::Midpoint }, t, q, p, guess).map(|v| array(&v))
}
