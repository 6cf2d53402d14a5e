//! The implicit time transformation of a run-time-sized system.
//!
//! The extended system `x = (q, t)` of `n + 1` coordinates is another
//! run-time-sized system ([`DynTimeTransformed`], a [`DynLagrangian`]),
//! stepped in `s` by the reverse-mode `DynIntegrator` with a one-point or
//! Galerkin rule ([`RuleInS`]). [`RunTimeAdaptive`] reads its steps as
//! adaptive steps in physical time, as [`Adaptive`](super::Adaptive) does at
//! a compile-time size: the physical state, velocity and energy, landing on
//! a time exactly, and the typed refusals of a density that is not finite
//! and positive, of a step that advances time by less than the floor and of
//! a step that has lost the orbit, with the stepper as it was.
//!
//! `L̃` and the extended force are formed by the functions the compile-time
//! size uses (`extended.rs`), and the curvature monitor by the same sums in
//! the same order as [`Curvature`]'s, so both sizes take the same steps to
//! round-off.
//!
//! Structure: `t` enters `L(t, …)` and `g(t, q)` together with every
//! coordinate, so the Hessian of `L̃` has a dense last row and column, and
//! the curvature monitor reads the whole Hessian of `L` in `q` (`n(n + 1)/2`
//! evaluations of `L` per evaluation of `g`, each on the tape inside every
//! evaluation of `L̃`). The extended system is stepped with general (dense)
//! Newton matrices: the monitor, not the linear algebra, sets the cost.

use core::cell::Cell;
use std::sync::Arc;

use num_dual::{Dual, HyperDual};

use super::adaptive::physical_point;
use super::builder::{DEFAULT_RTOL, default_penalty};
use super::density::Curvature;
use super::extended::{extended_force_of, penalty_term, physical_velocity};
use crate::discrete::DiscreteLagrangian;
use crate::error::{Error, Unplaced};
use crate::integrator::{DynIntegrator, DynMethod, RunTimeGalerkin, Sealed, Sliced, Stats, tape_energy, tape_velocity};
use crate::newton::NewtonOptions;
use crate::root::Bracket;
use crate::solution::RunTimeStepping;
use crate::state::PhasePoint;
use crate::system::{DynLagrangian, Scalar};

/// The points at which the readouts' model of the physical system would
/// evaluate a step (none is taken: it serves `L` at a point).
const READOUT_POINTS: [f64; 2] = [0.5, 0.5];

/// The time-transformed system of a run-time-sized system `S` with the
/// curvature monitor `g`: `L̃(x, x') = t' L(t, q, q'/t') + (t' − g)²/(2cg)`
/// in `s`, `x = (q, t)`, `n + 1` coordinates; with the force
/// `(t' F, −F·q')` of the physical generalized force `F` (Lagrange–
/// d'Alembert in `s`).
#[derive(Debug)]
pub struct DynTimeTransformed<S> {
    system: Arc<S>,
    density: Curvature,
    penalty: f64,
    /// The last density value seen that was not finite and positive; the
    /// step that met it fails (its action is NaN there).
    invalid: Cell<Option<f64>>,
}

impl<S> Clone for DynTimeTransformed<S> {
    fn clone(&self) -> Self {
        Self {
            system: Arc::clone(&self.system),
            density: self.density,
            penalty: self.penalty,
            invalid: self.invalid.clone(),
        }
    }
}

impl<S: DynLagrangian> DynTimeTransformed<S> {
    /// `g(t, q)` on any scalar.
    fn density<D: Scalar>(&self, t: D, q: &[D]) -> D {
        curvature(self.density.floor, &*self.system, t, q)
    }

    /// `g` on any scalar; NaN (and the value recorded) where it is not
    /// finite and positive, so that the step fails with a typed error.
    fn checked_density<D: Scalar>(&self, t: D, q: &[D]) -> D {
        let g = self.density(t, q);
        let re = g.re();
        if re.is_finite() && re > 0.0 {
            g
        } else {
            self.invalid.set(Some(re));
            D::from(f64::NAN)
        }
    }
}

/// The curvature monitor `(κ² + floor²)^{-1/4}`, `κ = ‖∂²L/∂q²(t, q, 0)‖_F`,
/// of a run-time-sized system: the sums of [`Curvature`]'s monitor in the
/// same order, over slices.
fn curvature<S: DynLagrangian + ?Sized, D: Scalar>(floor: f64, system: &S, t: D, q: &[D]) -> D {
    let n = q.len();
    let mut k2 = D::from(floor * floor);
    let v = vec![HyperDual::from_re(D::zero()); n];
    let mut qh: Vec<HyperDual<D>> = q.iter().map(|&x| HyperDual::from_re(x)).collect();
    let th = HyperDual::from_re(t);
    for i in 0..n {
        for j in i..n {
            qh[i].eps1 = D::one();
            qh[j].eps2 = D::one();
            let h = system.lagrangian(th, &qh, &v).eps1eps2;
            qh[i].eps1 = D::zero();
            qh[j].eps2 = D::zero();
            k2 += if i == j { h * h } else { h * h * 2.0 };
        }
    }
    k2.powf(-0.25)
}

/// The generalized force `Q − ∂R/∂v` of a run-time-sized system into `f`
/// (zeros on entry), on any scalar: `∂R/∂v` by a dual number seeded on
/// each velocity in turn.
fn generalized_force<S: DynLagrangian + ?Sized, D: Scalar>(system: &S, t: D, q: &[D], v: &[D], f: &mut [D]) {
    if S::HAS_FORCE {
        system.force(t, q, v, f);
    }
    if S::HAS_DISSIPATION {
        let qd: Vec<Dual<D>> = q.iter().map(|&x| Dual::from_re(x)).collect();
        let mut vd: Vec<Dual<D>> = v.iter().map(|&x| Dual::from_re(x)).collect();
        for i in 0..v.len() {
            vd[i].eps = D::one();
            f[i] -= system.dissipation(&qd, &vd).eps;
            vd[i].eps = D::zero();
        }
    }
}

impl<S: DynLagrangian> DynLagrangian for DynTimeTransformed<S> {
    const AUTONOMOUS: bool = true;
    const DISCONTINUOUS: bool = S::DISCONTINUOUS;
    const HAS_FORCE: bool = S::HAS_FORCE || S::HAS_DISSIPATION;

    fn dimension(&self) -> usize {
        self.system.dimension() + 1
    }

    fn lagrangian<D: Scalar>(&self, _s: D, x: &[D], w: &[D]) -> D {
        let n = x.len() - 1;
        let (q, t) = (&x[..n], x[n]);
        let g = self.checked_density(t, q);
        let mut v = vec![D::zero(); n];
        let time_rate = physical_velocity(w, &mut v);
        time_rate * self.system.lagrangian(t, q, &v) + penalty_term(time_rate, g, D::from(self.penalty))
    }

    /// Lagrange–d'Alembert in `s`: the virtual work `∫ F·(δq − v δt) dt`
    /// of the physical force is `∫ (t'F·δq − F·q' δt) ds`.
    fn force<D: Scalar>(&self, _s: D, x: &[D], w: &[D], f: &mut [D]) {
        let n = x.len() - 1;
        let (q, t) = (&x[..n], x[n]);
        let mut v = vec![D::zero(); n];
        physical_velocity(w, &mut v);
        let mut physical = vec![D::zero(); n];
        generalized_force(&*self.system, t, q, &v, &mut physical);
        extended_force_of(w, &physical, f);
    }
}

/// The method in `s` of a run-time-sized time transformation: a one-point
/// rule by its quadrature points (midpoint, trapezoid, α-β), or a Galerkin
/// rule of any degree. A public type in a private module, named only
/// inside the crate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum RuleInS {
    /// The one-point rule with these quadrature points.
    OnePoint([f64; 2]),
    /// The Galerkin rule.
    Galerkin(RunTimeGalerkin),
}

impl RuleInS {
    /// The one-point rule `method`; `None` for a rule without quadrature points.
    pub(crate) fn one_point<M: DiscreteLagrangian>(method: &M) -> Option<Self> {
        DynMethod::points(method).map(Self::OnePoint)
    }
}

impl Sealed for RuleInS {}

impl DynMethod for RuleInS {
    fn points(&self) -> Option<[f64; 2]> {
        match self {
            Self::OnePoint(points) => Some(*points),
            Self::Galerkin(_) => None,
        }
    }

    fn galerkin(&self) -> Option<RunTimeGalerkin> {
        match self {
            Self::OnePoint(_) => None,
            Self::Galerkin(rule) => Some(*rule),
        }
    }

    // The extended system is never proven separable.
    const EXPLICIT_FOR_CONSTANT_MASS: bool = false;
}

/// The integrator in `s`.
type InS<S> = DynIntegrator<DynTimeTransformed<S>, RuleInS>;

/// What the driver remembers of the motion besides the integrator in `s`.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Memory {
    /// `(step, t_end)` after landing on `t_end`: the published time is
    /// `t_end` exactly while the integrator stays at that node.
    landed: Option<(u64, f64)>,
    /// The physical time the last step advanced.
    last_dt: Option<f64>,
    /// `t'/g = 1 + c·u` at the current node (`None` where its velocity
    /// cannot be found): the reference of the lost-orbit check.
    rate: Option<f64>,
}

/// The adaptive driver in physical time of a run-time-sized system: fixed
/// steps `σ` in `s` of its [`DynTimeTransformed`] system by a
/// `DynIntegrator` (see the [module](self)). A failed step leaves it as
/// it was, and the error carries the physical state.
#[derive(Debug)]
pub struct RunTimeAdaptive<S> {
    inner: InS<S>,
    /// The integrator in `s` before the step in progress (scratch, copied
    /// into in place).
    saved: Option<Box<InS<S>>>,
    /// The physical state `(k, t, q, p)` at the current node.
    physical: PhasePoint,
    /// The physical state before the step in progress (scratch).
    start: PhasePoint,
    /// The smallest time step allowed.
    floor: f64,
    memory: Memory,
    /// `memory` before the step in progress.
    memory_start: Memory,
    /// The secant velocity of the last step: Newton's guess for the velocity.
    v_guess: Vec<f64>,
    /// `v_guess` before the step in progress (scratch).
    v_start: Vec<f64>,
}

/// A copy owns buffers of its own; `clone_from` refills those the target
/// has (a `solve` refreshes its copy before every step this way). The
/// scratch of the step in progress is not copied.
impl<S> Clone for RunTimeAdaptive<S>
where
    InS<S>: Clone,
{
    fn clone(&self) -> Self {
        Self {
            inner: self.inner.clone(),
            saved: None,
            physical: self.physical.clone(),
            start: self.start.clone(),
            floor: self.floor,
            memory: self.memory,
            memory_start: self.memory_start,
            v_guess: self.v_guess.clone(),
            v_start: self.v_start.clone(),
        }
    }

    fn clone_from(&mut self, source: &Self) {
        self.inner.clone_from(&source.inner);
        self.physical.clone_from(&source.physical);
        self.floor = source.floor;
        self.memory = source.memory;
        self.v_guess.clone_from(&source.v_guess);
    }
}

impl<S: DynLagrangian> RunTimeAdaptive<S> {
    /// Starts at `(t0, q0, v0)` (physical time and velocity) with `s = 0`,
    /// `t'(0) = g(t0, q0)` and `q'(0) = g v0`, so that `p_t = −E(t0)`; the
    /// constant `c` and the time-step floor as at a compile-time size
    /// ([`TimeTransformedBuilder::start`](super::TimeTransformedBuilder::start)),
    /// Newton's settings `newton` or those of the compile-time size
    /// (`rtol = `[`DEFAULT_RTOL`]).
    ///
    /// Fails with [`Error::InvalidSetting`] for a step `sigma` that is not
    /// finite and positive, [`Error::WrongLength`] and
    /// [`Error::InvalidInitialData`] for initial data of the wrong length
    /// or not finite, [`Error::InvalidDensity`] where `g(t0, q0)` is not
    /// finite and positive, [`Error::Unsupported`] for a system with
    /// holonomic constraints, and with the integrator's own errors in `s`.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn start(
        system: S,
        rule: RuleInS,
        density: Curvature,
        sigma: f64,
        newton: Option<NewtonOptions>,
        t0: f64,
        q0: &[f64],
        v0: &[f64],
    ) -> Result<Self, Error> {
        if system.constraint_count() != 0 {
            return Err(Error::Unsupported { what: "time transformation of a system with holonomic constraints" });
        }
        if !(sigma.is_finite() && sigma > 0.0) {
            return Err(Error::InvalidSetting { reason: "the step in `s` must be finite and positive" });
        }
        let n = system.dimension();
        Error::check_run_time_data(n, t0, q0, v0)?;
        let g0 = curvature(density.floor, &system, t0, q0);
        if !(g0.is_finite() && g0 > 0.0) {
            let state = PhasePoint { step: 0, t: t0, q: q0.to_vec(), p: vec![f64::NAN; n] };
            return Err(Error::InvalidDensity { state, value: g0 });
        }
        // The constant c is part of the method, not of the state.
        let model = Sliced::new(&system, READOUT_POINTS);
        let (l0, e0) = (system.lagrangian(t0, q0, v0), tape_energy(&model, t0, q0, v0));
        let penalty = default_penalty(l0, e0);
        let floor = 1e-8 * sigma * g0;
        if !(floor.is_finite() && floor > 0.0) {
            return Err(Error::InvalidSetting { reason: "the smallest time step must be finite and positive" });
        }
        let extended = DynTimeTransformed { system: Arc::new(system), density, penalty, invalid: Cell::new(None) };
        let x0: Vec<f64> = q0.iter().copied().chain([t0]).collect();
        let w0: Vec<f64> = v0.iter().map(|v| g0 * v).chain([g0]).collect();
        let newton = newton.unwrap_or(NewtonOptions { rtol: DEFAULT_RTOL, ..NewtonOptions::default() });
        let inner = DynIntegrator::new(extended, rule, sigma)
            .newton(newton)
            .start(0.0, &x0, &w0)
            .map_err(|e| e.map_state(physical_point))?;
        let memory = Memory { landed: None, last_dt: None, rate: None };
        let physical = PhasePoint { step: 0, t: t0, q: q0.to_vec(), p: inner.state().p[..n].to_vec() };
        let mut adaptive = Self {
            inner,
            saved: None,
            start: physical.clone(),
            physical,
            floor,
            memory,
            memory_start: memory,
            v_guess: v0.to_vec(),
            v_start: v0.to_vec(),
        };
        adaptive.memory.rate = adaptive.rate_at(adaptive.inner.state(), v0);
        Ok(adaptive)
    }

    /// The physical state `(k, t_k, q_k, p_k)`; `k` counts steps in `s`.
    pub fn state(&self) -> &PhasePoint {
        &self.physical
    }

    /// The state in `s`: `s_k` as time, `x = (q, t)`, momenta `(p, p_t)`.
    pub fn extended_state(&self) -> &PhasePoint {
        self.inner.state()
    }

    /// `p_t = −E + u`, the momentum of time: conserved to round-off for an
    /// autonomous `L` without forces (the curvature monitor reads `t` only
    /// through `L`).
    pub fn time_momentum(&self) -> f64 {
        *self.inner.state().p.last().unwrap_or(&f64::NAN)
    }

    /// The discrete energy of the steps in `s`, `−p_t`: under the time
    /// transformation the momentum of time plays the part of the energy
    /// that a step's action conserves.
    pub fn discrete_energy(&self) -> f64 {
        -self.time_momentum()
    }

    /// The physical system.
    pub fn system(&self) -> &S {
        &self.inner.system().system
    }

    /// Work counters of the steps in `s` (landing trials not counted).
    pub fn stats(&self) -> &Stats {
        self.inner.stats()
    }

    /// The physical velocity `v` with `∂L/∂v(t, q, v) = p` (Newton on the
    /// tape from the last step's secant velocity).
    pub fn velocity(&self) -> Result<Vec<f64>, Error> {
        let PhasePoint { t, q, p, .. } = &self.physical;
        let model = Sliced::new(self.system(), READOUT_POINTS);
        tape_velocity(&model, *t, q, p, &self.v_guess).map_err(|(iterations, residual_norm)| Error::InverseLegendre {
            state: self.physical.clone(),
            iterations,
            residual_norm,
        })
    }

    /// The physical energy `E_L(t, q, v)` at the current state.
    pub fn energy(&self) -> Result<f64, Error> {
        let v = self.velocity()?;
        Ok(self.energy_at(self.physical.t, &self.physical.q, &v))
    }

    /// `E_L(t, q, v)` of the physical system (NaN where its sweep fails).
    fn energy_at(&self, t: f64, q: &[f64], v: &[f64]) -> f64 {
        tape_energy(&Sliced::new(self.system(), READOUT_POINTS), t, q, v)
    }

    /// One step of `σ` in `s`. Refused, with the stepper as it was, where
    /// `g` is not finite and positive inside the step or at its end, where
    /// the step advances time by less than the floor, and where it has lost
    /// the orbit ([`Error::OrbitLost`]), as at a compile-time size.
    pub fn step(&mut self) -> Result<&PhasePoint, Error> {
        self.try_step()?;
        Ok(&self.physical)
    }

    /// One step of `σ` in `s`, or, when it would pass `t_end`, the partial
    /// step that ends on it; a no-op at or beyond `t_end`. On failure the
    /// stepper is as it was.
    pub(crate) fn step_toward(&mut self, t_end: f64) -> Result<(), Error> {
        if t_end <= self.physical.t {
            return Ok(());
        }
        self.try_step()?;
        if self.time() > t_end {
            self.restore();
            let t0 = self.time();
            self.land(t_end, t0)?;
        }
        Ok(())
    }

    /// The time coordinate of the integrator in `s` (the published time
    /// differs from it by the last unit after a landing).
    fn time(&self) -> f64 {
        time_of(&self.inner)
    }

    /// Keeps the stepper as it is before a step, in the scratch copies.
    fn save(&mut self) {
        match &mut self.saved {
            Some(saved) => saved.as_mut().clone_from(&self.inner),
            None => self.saved = Some(Box::new(self.inner.clone())),
        }
        self.start.clone_from(&self.physical);
        self.v_start.clone_from(&self.v_guess);
        self.memory_start = self.memory;
    }

    /// Puts back what [`save`](Self::save) kept.
    fn restore(&mut self) {
        if let Some(saved) = self.saved.as_mut() {
            core::mem::swap(&mut self.inner, saved);
        }
        self.physical.clone_from(&self.start);
        self.v_guess.clone_from(&self.v_start);
        self.memory = self.memory_start;
    }

    /// One step of `σ` in `s`, checked; on failure everything is put back.
    fn try_step(&mut self) -> Result<(), Error> {
        self.save();
        let t0 = self.time();
        self.inner.system().invalid.set(None);
        if let Err(e) = self.inner.step() {
            // Read the flag before restoring: the saved copy has its own.
            let invalid = self.inner.system().invalid.get();
            self.restore();
            return Err(match invalid {
                Some(value) => Error::InvalidDensity { state: self.physical.clone(), value },
                None => e.at_state(self.physical.clone()),
            });
        }
        match self.verify(&self.inner, t0, Some(self.floor)) {
            Ok((dt, rate)) => {
                self.after_step(dt, rate, None);
                Ok(())
            }
            Err(e) => {
                self.restore();
                Err(e.at(self.physical.clone()))
            }
        }
    }

    /// Checks a computed step from the current node (time `t0` in `s`) to
    /// `candidate`'s node, as at a compile-time size: the density there,
    /// the time it advanced (against `floor`, if given), and the rate `t'/g`
    /// against the current node's. Returns the time step and the rate at
    /// the end.
    fn verify(&self, candidate: &InS<S>, t0: f64, floor: Option<f64>) -> Result<(f64, Option<f64>), Unplaced> {
        let x = candidate.state();
        let n = self.physical.q.len();
        let (t1, q1) = (x.q[n], &x.q[..n]);
        let g1 = curvature(self.inner.system().density.floor, self.system(), t1, q1);
        let dt = t1 - t0;
        if !(g1.is_finite() && g1 > 0.0) {
            return Err(Unplaced::new(|state| Error::InvalidDensity { state, value: g1 }));
        }
        if let Some(floor) = floor {
            // NaN fails too.
            let margin = dt - floor;
            if margin.is_nan() || margin < 0.0 {
                return Err(Unplaced::new(|state| Error::TimeStepCollapsed { state, dt, floor }));
            }
        }
        let guess: Vec<f64> = q1.iter().zip(&self.physical.q).map(|(a, b)| (a - b) / dt).collect();
        let rate = self.rate_at(x, &guess);
        if let (Some(r0), Some(r1)) = (self.memory.rate, rate) {
            // NaN fails too.
            let factor = r1 / r0;
            if !(0.5..=2.0).contains(&factor) {
                return Err(Unplaced::new(|state| Error::OrbitLost { state, factor }));
            }
        }
        Ok((dt, rate))
    }

    /// The rate `t'/g = 1 + c·u` at the node `x` in `s`, `u = p_t + E(t, q, v)`
    /// (see [`Adaptive`](super::Adaptive)); `None` where the velocity cannot
    /// be found from `guess`.
    fn rate_at(&self, x: &PhasePoint, guess: &[f64]) -> Option<f64> {
        let n = self.physical.q.len();
        let (t, q, p) = (x.q[n], &x.q[..n], &x.p[..n]);
        let model = Sliced::new(self.system(), READOUT_POINTS);
        let v = tape_velocity(&model, t, q, p, guess).ok()?;
        let u = x.p[n] + tape_energy(&model, t, q, &v);
        Some(1.0 + self.inner.system().penalty * u)
    }

    /// After an accepted step of `dt` in physical time from the published
    /// state: the secant velocity, the memory and the published state
    /// (at `landed`'s time when the step landed there).
    fn after_step(&mut self, dt: f64, rate: Option<f64>, landed: Option<f64>) {
        let n = self.physical.q.len();
        let x = self.inner.state();
        for ((v, q1), q0) in self.v_guess.iter_mut().zip(&x.q[..n]).zip(&self.physical.q) {
            *v = (q1 - q0) / dt;
        }
        self.memory = Memory { landed: landed.map(|t| (x.step, t)), last_dt: Some(dt), rate };
        self.physical.step = x.step;
        self.physical.t = landed.unwrap_or(x.q[n]);
        self.physical.q.copy_from_slice(&x.q[..n]);
        self.physical.p.copy_from_slice(&x.p[..n]);
    }

    /// The partial step in `s` from the current node (time `t0`) that ends
    /// on `t_end`, given that the full step passes it.
    fn land(&mut self, t_end: f64, t0: f64) -> Result<(), Error> {
        let sigma = self.inner.step_size();
        let t_over = time_of(self.saved.as_deref().unwrap_or(&self.inner));
        let tol = 4.0 * f64::EPSILON * t_end.abs().max(t0.abs()).max(f64::MIN_POSITIVE);
        if t_end - t0 <= tol {
            self.memory.landed = Some((self.inner.state().step, t_end));
            self.physical.t = t_end;
            return Ok(());
        }
        // f(σ') = t(σ') − t_end over (0, σ), bracketed.
        let mut bracket = Bracket::new((0.0, t0 - t_end), (sigma, t_over - t_end));
        let mut best: Option<(f64, InS<S>, Option<f64>)> = None;
        for _ in 0..60 {
            let s = bracket.trial();
            let mut trial = self.inner.clone();
            let verified = if trial.set_step_size(s).is_err() || trial.step().is_err() {
                None
            } else {
                // No floor: a landing step may be arbitrarily short.
                self.verify(&trial, t0, None).ok()
            };
            let Some((_, rate)) = verified else {
                bracket.refuse(s);
                continue;
            };
            let f = time_of(&trial) - t_end;
            if best.as_ref().is_none_or(|(b, ..)| f.abs() < b.abs()) {
                best = Some((f, trial.clone(), rate));
            }
            if f.abs() <= tol {
                break;
            }
            bracket.update(s, f);
        }
        match best {
            Some((f, mut trial, rate)) if f.abs() <= 64.0 * tol => {
                let _ = trial.set_step_size(sigma);
                let dt = time_of(&trial) - t0;
                self.inner = trial;
                self.after_step(dt, rate, Some(t_end));
                Ok(())
            }
            best => Err(Error::Landing { target: t_end, reached: best.map_or(t0, |(f, ..)| t_end + f) }),
        }
    }
}

/// The time coordinate, the last, of an integrator in `s`.
fn time_of<S: DynLagrangian>(inner: &InS<S>) -> f64 {
    *inner.state().q.last().unwrap_or(&f64::NAN)
}

/// Steps of `σ` in `s` read in physical time; landing by the partial step
/// in `s` that ends on the target.
impl<S: DynLagrangian> RunTimeStepping for RunTimeAdaptive<S> {
    type System = S;

    fn system(&self) -> &S {
        RunTimeAdaptive::system(self)
    }

    fn state(&self) -> &PhasePoint {
        &self.physical
    }

    fn velocity(&self) -> Result<Vec<f64>, Error> {
        RunTimeAdaptive::velocity(self)
    }

    fn energy(&self) -> Result<f64, Error> {
        RunTimeAdaptive::energy(self)
    }

    fn discrete_energy(&self) -> f64 {
        RunTimeAdaptive::discrete_energy(self)
    }

    /// Work counters of the steps in `s` (landing trials not counted).
    fn stats(&self) -> Stats {
        *RunTimeAdaptive::stats(self)
    }

    fn step(&mut self) -> Result<(), Error> {
        self.try_step()
    }

    fn step_toward(&mut self, t_end: f64) -> Result<(), Error> {
        RunTimeAdaptive::step_toward(self, t_end)
    }

    /// `σ`, the step in `s`.
    fn step_size(&self) -> f64 {
        self.inner.step_size()
    }

    fn last_step_size(&self) -> Option<f64> {
        self.memory.last_dt
    }

    /// A new `σ`; the floor on the time step stays that of the start.
    fn set_step_size(&mut self, sigma: f64) -> Result<(), Error> {
        if !(sigma.is_finite() && sigma > 0.0) {
            return Err(Error::InvalidSetting { reason: "the step in `s` must be finite and positive" });
        }
        self.inner.set_step_size(sigma)
    }
}
