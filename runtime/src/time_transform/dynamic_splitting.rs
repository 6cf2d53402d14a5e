//! The explicit time-transformed splitting of `splitting.rs` on a
//! run-time-sized system `L = ½ vᵀMv − V(t, q)` with a constant mass matrix
//! (a [`DynLagrangian`] stated by `Vec<f64>` coordinates).
//!
//! The same method: the drift `q += h f'(T + p_t + c) M⁻¹p`,
//! `t += h f'(T + p_t + c)` and the kick `p −= h f'(c − V) ∇V`,
//! `p_t −= h f'(c − V) ∂_t V` of `Γ = f(T + p_t + c) − f(c − V)`, in the
//! order and with the merged half-flows of [`stages`], the same shift `c`,
//! the same checks at the end node ([`ClockBounds`]), the same floor on the
//! time step and the same landing in physical time. What differs is where
//! the numbers come from: the state is on the heap, `M⁻¹p` is a solve with
//! `M` factored once at the start (banded where `#[lagrangian]` proved a
//! band, a product with its reciprocals where `M` is diagonal), and `∇V`
//! comes from the system's generated gradient code or one reverse sweep of
//! the tape, so that a step costs `O(N)` on a banded system (as the run-time
//! explicit compositions do) where the compile-time driver takes dual
//! numbers of `N` lanes and a dense `M⁻¹`.

use super::splitting::{
    ClockBounds, Fault, Flow, LEAPFROG, LeapfrogForm, SplittingStats, TimeFunction, homogeneous_attraction,
    shift_with_margin, stages,
};
use crate::error::{Argument, Error};
use crate::integrator::{Composition, ConstantMass, Sliced, Stats};
use crate::newton::{Breakdown, NewtonOptions};
use crate::real::all_finite;
use crate::root::Bracket;
use crate::state::PhasePoint;
use crate::system::DynLagrangian;
use crate::tape::{Tape, Var};
use num_dual::Dual64;
use std::sync::Arc;

mod stepping;

/// A point of the extended phase space `(q, t; p, p_t)` on the heap, with
/// `V`, `∇V` and `∂_t V` there once a kick has computed them.
#[derive(Debug)]
struct Point {
    /// `(k, t, q, p)`: the step in `s`, the time reported (a landed target's
    /// after a landing), the positions and momenta.
    state: PhasePoint,
    /// Physical time of the phase, with the compensation of its sum.
    t: f64,
    t_carry: f64,
    /// The momentum of time, `−H` on the exact flow.
    p_t: f64,
    /// `∂L/∂q = −∇V` at `q` (valid when `potential` is `Some`).
    force: Vec<f64>,
    /// `(V, ∂_t V)` at `(t, q)`, when computed.
    potential: Option<(f64, f64)>,
    /// `T(p)`, when a drift has computed it (a drift leaves `p` as it is).
    kinetic: Option<f64>,
}

/// `clone_from` reuses the buffers: a step copies its start into a trial
/// point without allocating.
impl Clone for Point {
    fn clone(&self) -> Self {
        Self {
            state: self.state.clone(),
            t: self.t,
            t_carry: self.t_carry,
            p_t: self.p_t,
            force: self.force.clone(),
            potential: self.potential,
            kinetic: self.kinetic,
        }
    }

    fn clone_from(&mut self, source: &Self) {
        self.state.clone_from(&source.state);
        (self.t, self.t_carry, self.p_t) = (source.t, source.t_carry, source.p_t);
        // `∇V` is read only where `V` is known.
        if source.potential.is_some() {
            self.force.clone_from(&source.force);
        }
        (self.potential, self.kinetic) = (source.potential, source.kinetic);
    }
}

/// The buffers of the flows: the velocity `M⁻¹p`, the zeros the potential
/// is evaluated at, the tape of `∇V`, the dual numbers of `∂_t V`.
#[derive(Debug)]
struct Scratch {
    velocity: Vec<f64>,
    zero: Vec<f64>,
    zero_vars: Vec<Var>,
    dual_q: Vec<Dual64>,
    dual_zero: Vec<Dual64>,
    tape: Tape,
}

impl Scratch {
    fn new(n: usize) -> Self {
        Self {
            velocity: vec![0.0; n],
            zero: vec![0.0; n],
            zero_vars: vec![Var::constant(0.0); n],
            dual_q: vec![Dual64::from_re(0.0); n],
            dual_zero: vec![Dual64::from_re(0.0); n],
            tape: Tape::new(),
        }
    }
}

/// A copy has buffers of its own and a fresh tape (a tape holds no state
/// between evaluations).
impl Clone for Scratch {
    fn clone(&self) -> Self {
        Self::new(self.zero.len())
    }

    fn clone_from(&mut self, source: &Self) {
        if self.zero.len() != source.zero.len() {
            *self = source.clone();
        }
    }
}

/// Why a step cannot be taken: a fault of the splitting's flows, or the
/// tape of `∇V` failed (which the runtime's use cannot provoke).
enum StepFault {
    Flow(Fault<f64>),
    Tape,
}

impl From<Fault<f64>> for StepFault {
    fn from(fault: Fault<f64>) -> Self {
        Self::Flow(fault)
    }
}

/// The explicit time-transformed splitting of a run-time-sized separable
/// system: uniform steps `σ` in `s`, adaptive steps `dt ≈ σ f'(c − V)` in
/// physical time, symplectic in `(q, t, p, p_t)`, of order 2 (the leapfrog)
/// or that of the composition. It is the driver of `Problem<S, Dyn>` with
/// [`Scheme::Splitting`](crate::problem::Scheme::Splitting), and takes the
/// steps the compile-time [`ExplicitAdaptive`](super::ExplicitAdaptive)
/// takes, with its defaults (drift–kick–drift, the default shift `c` and
/// floor), its checks and its errors (see there).
#[derive(Clone, Debug)]
pub struct RunTimeSplitting<S> {
    system: S,
    function: TimeFunction,
    sigma: f64,
    weights: &'static [f64],
    order: u32,
    form: LeapfrogForm,
    shift: f64,
    /// `M`, factored once and shared by copies.
    mass: Arc<ConstantMass>,
    clocks: ClockBounds,
    /// The current node.
    node: Point,
    /// The end of the step being tried, and the best trial of a landing.
    trial: Point,
    best: Point,
    scratch: Scratch,
    stats: Stats,
    split: SplittingStats,
    floor: f64,
    /// `(step, t_end)` after landing on `t_end`.
    landed: Option<(u64, f64)>,
    last_dt: Option<f64>,
}

impl<S: DynLagrangian + Clone> RunTimeSplitting<S> {
    /// Starts the splitting with time function `function`, the leapfrog
    /// composed by `composition` (order 2 without one) and step `sigma` in
    /// `s`, at `(t0, q0, v0)` with `p = M v0` and `p_t = −H(t0, q0, p)`.
    ///
    /// Refuses, as the compile-time size does: with [`Error::NotSeparable`]
    /// a system not proven `½ vᵀMv − V(t, q)` with constant `M`, one with
    /// forces or dissipation, and a singular `M`; with
    /// [`Error::Unsupported`] one with holonomic constraints; with
    /// [`Error::InvalidSetting`] a step or exponent that cannot work; with
    /// [`Error::WrongLength`] and [`Error::InvalidInitialData`] data of the
    /// wrong length, not finite, or at a singularity of `V` or `M`; with
    /// [`Error::TimeFunctionArgument`] a start where `c − V(t0, q0)` is not
    /// positive.
    pub(crate) fn start(
        system: S,
        function: TimeFunction,
        composition: Option<Composition>,
        sigma: f64,
        (t0, q0, v0): (f64, &[f64], &[f64]),
    ) -> Result<Self, Error> {
        if system.constraint_count() != 0 {
            return Err(Error::Unsupported { what: "time transformation of a system with holonomic constraints" });
        }
        if !S::SEPARABILITY.has_constant_mass() {
            return Err(Error::NotSeparable {
                reason: "the splitting needs `L = ½ vᵀMv − V(t, q)` with a constant mass matrix `M` \
                         (`Separability::ConstantMass`, proven by `#[lagrangian]`)",
            });
        }
        if S::HAS_FORCE || S::HAS_DISSIPATION {
            return Err(Error::NotSeparable { reason: "the splitting does not take forces or dissipation" });
        }
        if !(sigma.is_finite() && sigma > 0.0) {
            return Err(Error::InvalidSetting { reason: "the step in `s` must be finite and positive" });
        }
        let alpha = function.exponent();
        if !(alpha.is_finite() && alpha > 0.0) {
            return Err(Error::InvalidSetting { reason: "the exponent α must be finite and positive" });
        }
        let n = system.dimension();
        Error::check_run_time_data(n, t0, q0, v0)?;
        let mut scratch = Scratch::new(n);
        let v = -system.lagrangian(t0, q0, &scratch.zero);
        if !v.is_finite() {
            return Err(Error::InvalidInitialData {
                reason: "the potential V(t0, q0) is not finite: the initial state is at a singularity of V, \
                         where the time function's argument c − V is not defined",
            });
        }
        let model = Sliced::new(&system, [0.5, 0.5]);
        let mass = ConstantMass::factored(&model, t0, q0, NewtonOptions::default().min_rcond).map_err(|b| match b {
            Breakdown::Singular(_) => Error::NotSeparable { reason: "the mass matrix `M = ∂²L/∂v²` is singular" },
            Breakdown::NonFinite(_) => Error::InvalidInitialData {
                reason: "the mass matrix `M = ∂²L/∂v²` is not finite at the initial state (a singularity of L)",
            },
            Breakdown::Rejected(_) => {
                Error::Unsupported { what: "a system this large: its mass matrix cannot be allocated" }
            }
        })?;
        // `p = ∂L/∂v = M v0`.
        let (p, _) = crate::integrator::tape_legendre(&model, t0, q0, v0)
            .map_err(|reason| Error::InvalidInitialData { reason })?;
        let kinetic = kinetic_energy(&mass, &p, &mut scratch.velocity)
            .ok_or(Error::InvalidInitialData { reason: "t0, q0 and v0 must be finite" })?;
        let energy = kinetic + v;
        let mut node = Point {
            state: PhasePoint { step: 0, t: t0, q: q0.to_vec(), p },
            t: t0,
            t_carry: 0.0,
            p_t: -energy,
            force: vec![0.0; n],
            potential: None,
            kinetic: None,
        };
        let gravitating = energy < 0.0
            && homogeneous_attraction(v, |scale| {
                let q: Vec<f64> = q0.iter().map(|x| x * scale).collect();
                -system.lagrangian(t0, &q, &scratch.zero)
            });
        let shift = if gravitating {
            0.0
        } else {
            potential_gradient(&system, &mut scratch, &mut node).map_err(|_| Error::InvalidInitialData {
                reason: "the gradient of the potential cannot be taken at the initial state",
            })?;
            // `q·∇V = −q·∂L/∂q`.
            let virial = q0.iter().zip(&node.force).fold(0.0, |s, (&q, &f)| s - q * f);
            shift_with_margin(kinetic, v, virial)
        };
        let x = shift - v;
        if !(x.is_finite() && x > 0.0) {
            return Err(Error::TimeFunctionArgument {
                state: node.state.clone(),
                which: Argument::Potential,
                value: x,
            });
        }
        let g0 = function.derivative(x);
        let clocks = ClockBounds::new(alpha, kinetic + node.p_t + shift, x);
        let floor = sigma * g0 * 1e-8;
        if !(floor.is_finite() && floor > 0.0) {
            return Err(Error::InvalidSetting { reason: "the smallest time step must be finite and positive" });
        }
        let (weights, order) = composition.map_or((&LEAPFROG[..], 2), |c| (c.weights(), c.order()));
        Ok(Self {
            system,
            function,
            sigma,
            weights,
            order,
            form: LeapfrogForm::default(),
            shift,
            mass: Arc::new(mass),
            clocks,
            trial: node.clone(),
            best: node.clone(),
            node,
            scratch,
            stats: Stats::default(),
            split: SplittingStats::default(),
            floor,
            landed: None,
            last_dt: None,
        })
    }

    /// The physical state at the current node: `step` counts steps in `s`,
    /// and `t` is exactly the target after a landing.
    pub fn state(&self) -> &PhasePoint {
        &self.node.state
    }

    /// The system.
    pub fn system(&self) -> &S {
        &self.system
    }

    /// Work counters: steps in `s` (the gradient evaluations and landing
    /// trials are in [`splitting_stats`](Self::splitting_stats)).
    pub fn stats(&self) -> &Stats {
        &self.stats
    }

    /// The splitting's own counters, as the compile-time driver's.
    pub fn splitting_stats(&self) -> SplittingStats {
        self.split
    }

    /// The order in `σ` of one step.
    pub fn order(&self) -> u32 {
        self.order
    }

    /// The shift `c`.
    pub fn shift(&self) -> f64 {
        self.shift
    }

    /// `p_t`, the momentum of time: `−H` on the exact flow, constant for an
    /// autonomous `L`.
    pub fn time_momentum(&self) -> f64 {
        self.node.p_t
    }

    /// The velocity `v = M⁻¹p`.
    pub fn velocity(&self) -> Result<Vec<f64>, Error> {
        let mut v = vec![0.0; self.node.state.p.len()];
        self.mass
            .velocity_into(&self.node.state.p, &mut v)
            .map_err(|_| Error::InvalidInitialData { reason: "the momenta are not finite" })?;
        Ok(v)
    }

    /// The energy `H = ½ pᵀM⁻¹p + V(t, q)` at the current node (the
    /// physical time of the phase).
    pub fn energy(&self) -> Result<f64, Error> {
        let v = self.velocity()?;
        let kinetic = 0.5 * self.node.state.p.iter().zip(&v).fold(0.0, |s, (p, v)| s + p * v);
        Ok(kinetic - self.system.lagrangian(self.node.t, &self.node.state.q, &self.scratch.zero))
    }

    /// `−p_t`: the energy the steps keep for an autonomous `L` (no kick
    /// changes `p_t`), the initial energy `H(t0, q0, p0)` plus the work of
    /// `∂_t V` otherwise.
    pub fn discrete_energy(&self) -> f64 {
        -self.node.p_t
    }

    /// One step of `σ` in `s`; refused, with the stepper unchanged, as
    /// [`ExplicitAdaptive::step`](super::ExplicitAdaptive::step) is.
    pub fn step(&mut self) -> Result<&PhasePoint, Error> {
        let evaluations = self.advance(self.sigma)?;
        self.split.gradient_evaluations += evaluations;
        self.commit(false)?;
        Ok(&self.node.state)
    }

    /// One step of `σ` in `s`, or, when it would pass `target`, the partial
    /// step that ends on it; a no-op at or beyond `target`.
    pub(crate) fn step_toward(&mut self, target: f64) -> Result<(), Error> {
        if self.node.state.t >= target {
            return Ok(());
        }
        let evaluations = self.advance(self.sigma)?;
        self.split.gradient_evaluations += evaluations;
        if self.trial.t <= target { self.commit(false) } else { self.land(target) }
    }

    /// The error of a fault, carrying the node's state.
    fn fail(&self, fault: StepFault, h: f64) -> Error {
        let state = self.node.state.clone();
        match fault {
            StepFault::Flow(Fault::Argument(which, value)) => Error::TimeFunctionArgument { state, which, value },
            StepFault::Flow(Fault::Clocks(factor)) => Error::OrbitLost { state, factor },
            StepFault::Tape => Error::StepRejected { state, h, iterations: 0, reason: "the derivative tape failed" },
        }
    }

    /// The composed step of size `h` from the node into `trial`; changes
    /// nothing else. Returns the number of gradient evaluations.
    fn advance(&mut self, h: f64) -> Result<u64, Error> {
        self.trial.clone_from(&self.node);
        let flows = Flows {
            system: &self.system,
            mass: &self.mass,
            function: self.function,
            shift: self.shift,
            clocks: &self.clocks,
        };
        let mut evaluations = 0;
        let outcome = flows.step(self.form, self.weights, h, &mut self.trial, &mut self.scratch, &mut evaluations);
        match outcome {
            Ok(true) => Ok(evaluations),
            Ok(false) => Err(Error::NonFinite { state: self.node.state.clone(), h, iterations: 0, quantity: "state" }),
            Err(fault) => Err(self.fail(fault, h)),
        }
    }

    /// Accepts `trial` (or, for a landing, `best`) as the next node: checks
    /// the time it advanced (not for a landing step, which may be
    /// arbitrarily short) and updates the readouts.
    fn commit(&mut self, landing: bool) -> Result<(), Error> {
        let end = if landing { &mut self.best } else { &mut self.trial };
        let dt = (end.t - self.node.t) - (end.t_carry - self.node.t_carry);
        let published = end.t - self.node.state.t;
        let floor = if landing { 0.0 } else { self.floor };
        if dt.is_nan() || dt < floor || published < 0.0 {
            return Err(Error::TimeStepCollapsed { state: self.node.state.clone(), dt: dt.min(published), floor });
        }
        end.state.step = self.node.state.step + 1;
        end.state.t = end.t;
        std::mem::swap(&mut self.node, end);
        self.stats.steps += 1;
        self.split.steps += 1;
        self.landed = None;
        self.last_dt = Some(dt);
        Ok(())
    }

    /// The partial step that ends on `target`, given that the full step
    /// (in `trial`) passes it: the compile-time driver's search, Illinois
    /// regula falsi on `(0, σ)`.
    fn land(&mut self, target: f64) -> Result<(), Error> {
        let t0 = self.node.t;
        let t_over = self.trial.t;
        let scale = target.abs().max(t0.abs()).max(f64::MIN_POSITIVE);
        let tol = 4.0 * f64::EPSILON * scale;
        if target - t0 <= tol {
            self.node.state.t = target;
            self.landed = Some((self.node.state.step, target));
            return Ok(());
        }
        let mut bracket = Bracket::new((0.0, t0 - target), (self.sigma, t_over - target));
        let mut best: Option<f64> = None;
        for _ in 0..100 {
            let s = bracket.trial();
            self.split.landing_trials += 1;
            let Ok(evaluations) = self.advance(s) else {
                bracket.refuse(s);
                continue;
            };
            self.split.gradient_evaluations += evaluations;
            let f = self.trial.t - target;
            if best.is_none_or(|b| f.abs() < b.abs()) {
                best = Some(f);
                std::mem::swap(&mut self.best, &mut self.trial);
            }
            if f.abs() <= tol {
                break;
            }
            bracket.update(s, f);
        }
        match best {
            Some(f) if f.abs() <= 64.0 * tol => {
                self.commit(true)?;
                self.node.state.t = target;
                self.landed = Some((self.node.state.step, target));
                Ok(())
            }
            best => Err(Error::Landing { target, reached: best.map_or(t0, |f| target + f) }),
        }
    }
}

/// The flows of one step, borrowed from the driver.
struct Flows<'a, S> {
    system: &'a S,
    mass: &'a ConstantMass,
    function: TimeFunction,
    shift: f64,
    clocks: &'a ClockBounds,
}

impl<S: DynLagrangian> Flows<'_, S> {
    /// The composed step of size `h` on `point`, checked at its end node
    /// as the compile-time driver checks it; `Ok(false)` where the end point
    /// is not finite.
    fn step(
        &self,
        form: LeapfrogForm,
        weights: &[f64],
        h: f64,
        point: &mut Point,
        scratch: &mut Scratch,
        evaluations: &mut u64,
    ) -> Result<bool, StepFault> {
        stages(form, weights, |flow, fraction| match flow {
            Flow::Kick => self.kick(point, scratch, h * fraction, evaluations),
            Flow::Drift => self.drift(point, scratch, h * fraction),
        })?;
        let finite =
            point.t.is_finite() && all_finite(&point.state.q) && all_finite(&point.state.p) && point.p_t.is_finite();
        if !finite {
            return Ok(false);
        }
        // The end node's arguments of f' (the potential from the last
        // kick's gradient for kick–drift–kick, evaluated for drift–kick–drift).
        let kinetic = match point.kinetic {
            Some(kinetic) => kinetic,
            None => kinetic_energy(self.mass, &point.state.p, &mut scratch.velocity)
                .ok_or(Fault::Argument(Argument::Kinetic, f64::NAN))?,
        };
        let a = kinetic + point.p_t + self.shift;
        let v = match point.potential {
            Some((v, _)) => v,
            None => -self.system.lagrangian(point.t, &point.state.q, &scratch.zero),
        };
        let b = self.shift - v;
        if !(b.is_finite() && b > 0.0) {
            return Err(Fault::Argument(Argument::Potential, b).into());
        }
        self.clocks.check(a, b).map_err(Fault::Clocks)?;
        Ok(true)
    }

    /// The kick by `h`: `p −= h f'(c − V) ∇V`, `p_t −= h f'(c − V) ∂_t V`.
    fn kick(&self, point: &mut Point, scratch: &mut Scratch, h: f64, evaluations: &mut u64) -> Result<(), StepFault> {
        let (v, dt) = match point.potential {
            Some(known) => known,
            None => {
                *evaluations += 1;
                potential_gradient(self.system, scratch, point)?
            }
        };
        let x = self.shift - v;
        if !(x.is_finite() && x > 0.0) {
            return Err(Fault::Argument(Argument::Potential, x).into());
        }
        let k = h * self.function.derivative(x);
        let n = point.force.len();
        let (p, force) = (&mut point.state.p[..n], &point.force[..n]);
        // `force = −∇V`.
        for i in 0..n {
            p[i] += k * force[i];
        }
        if !S::AUTONOMOUS {
            point.p_t -= k * dt;
        }
        point.kinetic = None;
        Ok(())
    }

    /// The drift by `h`: `q += h f'(T + p_t + c) M⁻¹p`, `t += h f'(T + p_t + c)`.
    fn drift(&self, point: &mut Point, scratch: &mut Scratch, h: f64) -> Result<(), StepFault> {
        let kinetic = kinetic_energy(self.mass, &point.state.p, &mut scratch.velocity)
            .ok_or(Fault::Argument(Argument::Kinetic, f64::NAN))?;
        let x = kinetic + point.p_t + self.shift;
        if !(x.is_finite() && x > 0.0) {
            return Err(Fault::Argument(Argument::Kinetic, x).into());
        }
        let k = h * self.function.derivative(x);
        let n = scratch.velocity.len();
        // `M⁻¹p = p` for `M = I`: not copied.
        let u = if self.mass.is_unit() { &point.state.p[..n] } else { &scratch.velocity[..n] };
        let q = &mut point.state.q[..n];
        for i in 0..n {
            q[i] += k * u[i];
        }
        // Compensated sum: t grows over a long run while its steps stay small.
        let y = k - point.t_carry;
        let t = point.t + y;
        point.t_carry = (t - point.t) - y;
        point.t = t;
        point.potential = None;
        point.kinetic = Some(kinetic);
        Ok(())
    }
}

/// `T(p) = ½ p·M⁻¹p`, with `M⁻¹p` left in `velocity` (but for `M = I`);
/// `None` where `p` is not finite.
fn kinetic_energy(mass: &ConstantMass, p: &[f64], velocity: &mut [f64]) -> Option<f64> {
    let n = velocity.len();
    let u = if mass.is_unit() {
        // `M⁻¹p = p`, which the drift reads in place.
        &p[..n]
    } else {
        mass.velocity_into(p, velocity).ok()?;
        &velocity[..n]
    };
    let p = &p[..n];
    let mut k = 0.0;
    for i in 0..n {
        k += p[i] * u[i];
    }
    Some(k * 0.5)
}

/// `V`, `∂L/∂q = −∇V` (into `point.force`) and, for a time-dependent `L`,
/// `∂_t V` at the point, from the system's generated gradient code or one
/// reverse sweep of the tape (and one evaluation on dual numbers in `t`);
/// kept in `point.potential` and returned.
fn potential_gradient<S: DynLagrangian>(
    system: &S,
    scratch: &mut Scratch,
    point: &mut Point,
) -> Result<(f64, f64), StepFault> {
    let (t, q) = (point.t, &point.state.q);
    let l = if S::HAS_GRADIENT {
        system.value_gradient_q(t, q, &scratch.zero, &mut point.force)
    } else {
        let zero = &scratch.zero_vars;
        let l = scratch.tape.record(q, |x: &[Var]| system.lagrangian(Var::constant(t), x, zero));
        match l.and_then(|l| scratch.tape.gradient(&mut point.force).map(|()| l)) {
            Ok(l) => l,
            Err(_) => return Err(StepFault::Tape),
        }
    };
    let dt = if S::AUTONOMOUS {
        0.0
    } else {
        for (d, &x) in scratch.dual_q.iter_mut().zip(q) {
            *d = Dual64::from_re(x);
        }
        -system.lagrangian(Dual64::new(t, 1.0), &scratch.dual_q, &scratch.dual_zero).eps
    };
    point.potential = Some((-l, dt));
    Ok((-l, dt))
}
