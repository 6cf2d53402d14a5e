//! The run-time-sized integrator: systems whose number of coordinates is
//! known only at run time ([`DynLagrangian`]), stepped in reverse mode with
//! the state, the tape and the matrices on the heap.
//!
//! It takes the same steps as the const-size integrator's reverse mode: both
//! call the slice-based core in `tape_step.rs` (the recording of the action,
//! Newton with banded or dense solves, the explicit Störmer–Verlet path, the
//! Legendre map and the energy). What differs is only where the state lives
//! (`Vec<f64>` here, `[f64; N]` there) and how the step action is formed:
//! here from the rule's quadrature points
//! ([`DiscreteLagrangian::galerkin_points`]), over slices. The Galerkin
//! rules of any degree ([`Galerkin`](crate::Galerkin), `dynamic/galerkin.rs`) record the
//! action of their step polynomial instead and solve its `sN` node
//! equations.

use super::composition::Composition;
use super::method::sealed;
use super::tape_step::{
    self, Composed, GalerkinWork, Growth, Guess, Lanes3, Lanes5, LastSubstep, Node, SparseWork, Taken, TapeModel,
};
use super::{Clock, EnergyFallback, Stats, StepBounds, Summation};
use crate::discrete::{DiscreteLagrangian, Trapezoid};
use crate::error::Error;
use crate::newton::NewtonOptions;
use crate::real::all_finite;
use crate::state::PhasePoint;
use crate::structure::Coupling;
use crate::system::{DynLagrangian, Scalar};
use crate::tape::Var;
use num_dual::{Dual64, DualNum};

mod energy;
mod galerkin;
mod galerkin_energy;

use energy::EnergySteps;
pub(crate) use galerkin::RunTimeGalerkin;

/// What a [`DynIntegrator`] steps with: a one-point discrete Lagrangian
/// ([`Midpoint`](crate::Midpoint), [`Trapezoid`](crate::Trapezoid),
/// [`AlphaBeta`](crate::AlphaBeta), or a rule of one's own with quadrature
/// points), a [`Composition`] of trapezoid steps (fused when its
/// sub-steps are explicit, on a system with
/// [`Separability::ConstantMass`](crate::Separability); one by one
/// otherwise), or a Galerkin rule of any degree ([`Galerkin`](crate::Galerkin)).
pub trait DynMethod: sealed::Sealed {
    /// The quadrature points `[c_1, c_2]` of the (sub-)step's rule; `None`
    /// for a rule of another form (refused at `start`).
    fn points(&self) -> Option<[f64; 2]>;

    /// The sub-step weights `γ_1 … γ_m` of a composition; `None` for one
    /// step of the rule.
    fn weights(&self) -> Option<&'static [f64]> {
        None
    }

    /// The Galerkin rule's degree, nodes and quadrature; `None` for the
    /// one-point rules and compositions.
    fn galerkin(&self) -> Option<RunTimeGalerkin> {
        None
    }

    /// Whether the (sub-)step's DEL is explicit on a constant mass matrix
    /// (see [`DiscreteLagrangian::EXPLICIT_FOR_CONSTANT_MASS`]).
    const EXPLICIT_FOR_CONSTANT_MASS: bool;
}

impl<M: DiscreteLagrangian> DynMethod for M {
    fn points(&self) -> Option<[f64; 2]> {
        self.galerkin_points().map(|(points, _)| points)
    }

    const EXPLICIT_FOR_CONSTANT_MASS: bool = M::EXPLICIT_FOR_CONSTANT_MASS;
}

impl DynMethod for Composition {
    fn points(&self) -> Option<[f64; 2]> {
        Trapezoid.points()
    }

    fn weights(&self) -> Option<&'static [f64]> {
        Some(Composition::weights(self))
    }

    const EXPLICIT_FOR_CONSTANT_MASS: bool = <Trapezoid as DiscreteLagrangian>::EXPLICIT_FOR_CONSTANT_MASS;
}

/// The error of a sub-step, as the composed step's: with the state that
/// step started from (and the integrator holds again) and its size.
fn at_composed(mut error: Error, from: PhasePoint, size: f64) -> Error {
    match &mut error {
        Error::NewtonDidNotConverge { state, h, .. }
        | Error::SingularJacobian { state, h, .. }
        | Error::NonFinite { state, h, .. }
        | Error::StepRejected { state, h, .. } => (*state, *h) = (from, size),
        _ => {}
    }
    error
}

/// A run-time-sized system and a one-point rule as the reverse-mode core
/// sees them: the rule's action from its quadrature points,
/// `A = (h/2) Σ_j L(t_k + c_j h, q_k + c_j Δq, Δq/h)`, one evaluation when
/// both points coincide (midpoint, α-β). Each term is formed with the same
/// operations as the rule's own `action`, so the const-size and the
/// run-time-sized integrators record the same tape.
pub(crate) struct Sliced<'a, S> {
    system: &'a S,
    points: [f64; 2],
}

impl<'a, S: DynLagrangian> Sliced<'a, S> {
    /// The model of `system` under the rule with quadrature points `points`.
    pub(crate) fn new(system: &'a S, points: [f64; 2]) -> Self {
        Self { system, points }
    }

    /// `L(t0 + c h, q0 + c Δq, v)`.
    fn at(&self, c: f64, t0: Var, h: Var, q0: &[Var], dq: &[Var], v: &[Var]) -> Var {
        let (t, q): (Var, Vec<Var>) = if c == 0.0 {
            (t0, q0.to_vec())
        } else if c == 1.0 {
            (t0 + h, q0.iter().zip(dq).map(|(&a, &d)| a + d).collect())
        } else {
            (t0 + h * c, q0.iter().zip(dq).map(|(&a, &d)| a + d * c).collect())
        };
        self.system.lagrangian(t, &q, v)
    }
}

impl<S: DynLagrangian> TapeModel for Sliced<'_, S> {
    fn coupling(&self) -> Coupling {
        S::COUPLING
    }

    fn lagrangian(&self, t: Var, q: &[Var], v: &[Var]) -> Var {
        self.system.lagrangian(t, q, v)
    }

    fn action(&self, t0: Var, h: Var, q0: &[Var], dq: &[Var]) -> Var {
        let inv_h = h.recip();
        let v: Vec<Var> = dq.iter().map(|&d| d * inv_h).collect();
        let [c1, c2] = self.points;
        if c1 == c2 {
            self.at(c1, t0, h, q0, dq, &v) * h
        } else {
            (self.at(c1, t0, h, q0, dq, &v) + self.at(c2, t0, h, q0, dq, &v)) * (h * 0.5)
        }
    }

    fn gradient_q(&self, t: f64, q: &[f64], zero: &[f64], out: &mut [f64]) -> bool {
        if S::HAS_GRADIENT {
            self.system.gradient_q(t, q, zero, out);
        }
        S::HAS_GRADIENT
    }

    fn value_gradient_q(&self, t: f64, q: &[f64], zero: &[f64], out: &mut [f64]) -> Option<f64> {
        S::HAS_GRADIENT.then(|| self.system.value_gradient_q(t, q, zero, out))
    }

    fn add_gradient_q_at_rest(&self, t: f64, q: &[f64], out: &mut [f64]) -> Option<bool> {
        S::HAS_GRADIENT.then(|| self.system.add_gradient_q_at_rest(t, q, out))
    }

    fn autonomous(&self) -> bool {
        S::AUTONOMOUS
    }

    fn points(&self) -> Option<[f64; 2]> {
        Some(self.points)
    }

    fn has_gradient_qv(&self) -> bool {
        S::HAS_GRADIENT_QV
    }

    crate::integrator::tape_step::scalar_methods!();

    fn has_force(&self) -> bool {
        S::HAS_FORCE
    }

    fn has_dissipation(&self) -> bool {
        S::HAS_DISSIPATION
    }

    fn dissipation(&self, q: &[Var], v: &[Var]) -> Var {
        self.system.dissipation(q, v)
    }

    fn force_f64(&self, t: f64, q: &[f64], v: &[f64], f: &mut [f64]) {
        self.system.force(t, q, v, f);
    }

    fn force_dual(&self, t: Dual64, q: &[Dual64], v: &[Dual64], f: &mut [Dual64]) {
        self.system.force(t, q, v, f);
    }

    fn force_lanes3(&self, t: Lanes3, q: &[Lanes3], v: &[Lanes3], f: &mut [Lanes3]) {
        self.system.force(t, q, v, f);
    }

    fn force_lanes5(&self, t: Lanes5, q: &[Lanes5], v: &[Lanes5], f: &mut [Lanes5]) {
        self.system.force(t, q, v, f);
    }
}

impl<S: DynLagrangian> Sliced<'_, S> {
    fn gradient_qv_generic<D: Scalar>(&self, t: D, q: &[D], v: &[D], out_q: &mut [D], out_v: &mut [D]) {
        self.system.gradient_qv_scalar(t, q, v, out_q, out_v);
    }
    fn lagrangian_generic<D: Scalar>(&self, t: D, q: &[D], v: &[D]) -> D {
        self.system.lagrangian(t, q, v)
    }
}

/// Whether the system has a force or a dissipation function.
const fn is_forced<S: DynLagrangian>() -> bool {
    S::HAS_FORCE || S::HAS_DISSIPATION
}

/// The coupling the step matrix is laid out for: that of `L`, widened by
/// the force's (`∂F_k^−/∂Δq` joins the step's Jacobian).
fn step_coupling<S: DynLagrangian>() -> Coupling {
    let coupling = S::COUPLING;
    if is_forced::<S>() {
        Coupling { q_v: coupling.q_v.union(S::FORCE_COUPLING.overall()), ..coupling }
    } else {
        coupling
    }
}

/// Configuration of a [`DynIntegrator`] before it is given its initial
/// state; made by [`DynIntegrator::new`].
#[derive(Clone, Debug)]
pub struct DynIntegratorBuilder<S, M> {
    system: S,
    method: M,
    h: f64,
    newton: NewtonOptions,
    summation: Summation,
    /// The bounds of energy-preserving steps; `None`: fixed steps.
    energy_steps: Option<StepBounds>,
    fallback: EnergyFallback,
}

impl<S: DynLagrangian, M: DynMethod> DynIntegratorBuilder<S, M> {
    /// Energy-preserving variable steps within `bounds`, starting from the
    /// guess `h` given to [`DynIntegrator::new`], for the one-point and
    /// Galerkin rules (`dynamic/galerkin_energy.rs`), as
    /// [`IntegratorBuilder::energy_preserving`](crate::IntegratorBuilder::energy_preserving)
    /// at a compile-time size: each step size solves the discrete energy
    /// equation `E_{k+1} = E_k` (for a time-dependent `L`, the discrete
    /// energy balance of de León & Martín de Diego; for a system with a
    /// force or a dissipation function, the energy balance
    /// `E_{k+1} = E_k + W_k` with the discrete work of the forces) with the
    /// DEL, by banded solves where `L` is banded (`O(N)` per step). The
    /// first step has the size `h`.
    pub fn energy_preserving(mut self, bounds: StepBounds) -> Self {
        self.energy_steps = Some(bounds);
        self
    }

    /// What energy-preserving steps do where no admissible step size
    /// satisfies the energy equation (default: [`EnergyFallback::Fail`]; with
    /// [`EnergyFallback::LeastSquares`] the step of least energy mismatch is
    /// taken and counted in [`Stats::energy_fallbacks`]).
    pub fn energy_fallback(mut self, fallback: EnergyFallback) -> Self {
        self.fallback = fallback;
        self
    }

    /// Replaces the Newton settings.
    pub fn newton(mut self, options: NewtonOptions) -> Self {
        self.newton = options;
        self
    }

    /// How increments are added to the state ([`Summation`]):
    /// [`Summation::Compensated`] by default.
    pub fn summation(mut self, summation: Summation) -> Self {
        self.summation = summation;
        self
    }

    /// Starts at `(t0, q0, v0)` with `p0 = ∂L/∂v(t0, q0, v0)`.
    ///
    /// Under [`energy_preserving`](Self::energy_preserving) steps, fails
    /// with [`Error::InvalidStepBounds`] for unusable bounds,
    /// [`Error::InvalidStepSize`] for an `h` outside them, and
    /// [`Error::Unsupported`] for a composition (its steps are fixed), a
    /// Galerkin rule on a forced, dissipative or time-dependent system (as at
    /// a compile-time size) and an [`accuracy`](StepBounds::accuracy) bound.
    ///
    /// Fails with [`Error::Unsupported`] for a discrete Lagrangian
    /// without quadrature points ([`DiscreteLagrangian::galerkin_points`]),
    /// a system with holonomic constraints (stepped by
    /// [`DynConstrained`](crate::DynConstrained)), or a system so large that
    /// the step's buffers cannot be allocated;
    /// with [`Error::InvalidStepSize`] for a step that is not finite and
    /// positive, [`Error::InvalidNewtonOptions`], [`Error::WrongLength`]
    /// when `q0` or `v0` does not have `dimension()` entries, and
    /// [`Error::InvalidInitialData`] for a system without coordinates,
    /// non-finite data, a force `Q − ∂R/∂v` that is not finite there, or
    /// where `∂²L/∂v²` is singular (the Legendre transform is not regular).
    pub fn start(self, t0: f64, q0: &[f64], v0: &[f64]) -> Result<DynIntegrator<S, M>, Error> {
        // A Galerkin rule's model serves `L` at a point (the Legendre map,
        // the readouts), never a one-point action: its points are unused.
        let galerkin = self.method.galerkin();
        let Some(points) = self.method.points().or(galerkin.map(|_| [0.5, 0.5])) else {
            return Err(Error::Unsupported {
                what: "a discrete lagrangian without quadrature points (`galerkin_points`) on a run-time-sized system",
            });
        };
        if let Some(rule) = &galerkin {
            rule.rule()?;
        }
        self.newton.validate().map_err(|reason| Error::InvalidNewtonOptions { reason })?;
        Error::check_step(self.h)?;
        if let Some(bounds) = self.energy_steps {
            energy_steps_defined::<S, M>(&self.method, bounds, self.h)?;
        }
        let n = self.system.dimension();
        if self.system.constraint_count() > 0 {
            return Err(Error::Unsupported {
                what: "a system with holonomic constraints under `DynIntegrator`: step it with `DynConstrained`",
            });
        }
        Error::check_run_time_data(n, t0, q0, v0)?;
        let model = Sliced { system: &self.system, points };
        let (p0, energy) =
            tape_step::legendre(&model, t0, q0, v0).map_err(|reason| Error::InvalidInitialData { reason })?;
        if is_forced::<S>() {
            let mut force = vec![0.0; n];
            tape_step::generalized_force(&model, t0, q0, v0, &mut force);
            if !all_finite(&force) {
                return Err(Error::InvalidInitialData {
                    reason: "the force `force − ∂(dissipation)/∂v` is not finite at the initial data",
                });
            }
        }
        let work = SparseWork::new(n, step_coupling::<S>()).map_err(|_| Error::Unsupported {
            what: "a system this large with this coupling: the step matrix cannot be allocated",
        })?;
        let galerkin = galerkin.map(|rule| galerkin::work(&rule, n, step_coupling::<S>())).transpose()?;
        Ok(DynIntegrator {
            system: self.system,
            method: self.method,
            points,
            h: self.h,
            newton: self.newton,
            summation: self.summation,
            state: PhasePoint { step: 0, t: t0, q: q0.to_vec(), p: p0 },
            carry: vec![0.0; n],
            p_carry: vec![0.0; n],
            energy,
            v0: v0.to_vec(),
            previous: None,
            earlier: None,
            last_substep: None,
            composed_h: None,
            clock: Clock { t: t0, step: 0 },
            stats: Stats::default(),
            work: Box::new(work),
            galerkin,
            variable: self.energy_steps.map(|bounds| Box::new(EnergySteps::new(bounds, self.fallback, energy))),
        })
    }
}

/// `Ok` when energy-preserving steps within `bounds` from the guess `h` are
/// defined for `method` on the system `S`; the typed refusal otherwise.
fn energy_steps_defined<S: DynLagrangian, M: DynMethod>(method: &M, bounds: StepBounds, h: f64) -> Result<(), Error> {
    if !bounds.valid() {
        return Err(Error::InvalidStepBounds { h_min: bounds.h_min, h_max: bounds.h_max, max_ratio: bounds.max_ratio });
    }
    if !(bounds.h_min..=bounds.h_max).contains(&h) {
        return Err(Error::InvalidStepSize { h });
    }
    if bounds.accuracy.is_some() {
        return Err(Error::Unsupported { what: energy::NO_ACCURACY_BOUND });
    }
    if method.galerkin().is_some() && (is_forced::<S>() || !S::AUTONOMOUS) {
        return Err(Error::Unsupported {
            what: "energy steps with a Galerkin rule for a forced, dissipative or time-dependent system: they are written for autonomous systems without forces",
        });
    }
    if method.weights().is_some() {
        return Err(Error::Unsupported { what: "variable steps with a composition: its steps are fixed" });
    }
    Ok(())
}

/// The last step: `(t_k, h, q_k, Δq)`.
#[derive(Debug)]
struct DynSegment {
    t0: f64,
    h: f64,
    q0: Vec<f64>,
    dq: Vec<f64>,
}

impl Clone for DynSegment {
    fn clone(&self) -> Self {
        Self { t0: self.t0, h: self.h, q0: self.q0.clone(), dq: self.dq.clone() }
    }

    fn clone_from(&mut self, source: &Self) {
        (self.t0, self.h) = (source.t0, source.h);
        self.q0.clone_from(&source.q0);
        self.dq.clone_from(&source.dq);
    }
}

/// A variational integrator for a system whose size is known only at run
/// time ([`DynLagrangian`]), with a one-point discrete Lagrangian `M`
/// ([`Midpoint`](crate::Midpoint), [`Trapezoid`](crate::Trapezoid),
/// [`AlphaBeta`](crate::AlphaBeta)), a [`Composition`] of trapezoid
/// sub-steps ([`DynMethod`]; explicit ones fused, Newton ones taken one by
/// one) or a Galerkin rule ([`Galerkin`](crate::Galerkin), any degree: its
/// `sN` node unknowns in one banded or dense Newton block), and fixed
/// steps, or for the one-point rules energy-preserving ones
/// ([`DynIntegratorBuilder::energy_preserving`], `dynamic/energy.rs`);
/// every method with the system's forces and dissipation
/// ([`DynLagrangian::force`], [`DynLagrangian::dissipation`]) by the
/// discrete Lagrange–d'Alembert principle, every step then a Newton step.
///
/// It mirrors [`Integrator`](crate::Integrator) in reverse mode
/// ([`Derivatives::Reverse`](crate::Derivatives)) and takes the same steps:
/// derivatives from a tape, Newton systems banded when
/// [`DynLagrangian::COUPLING`] proves a band (dense otherwise), and for
/// [`Trapezoid`](crate::Trapezoid) on a system with
/// [`Separability::ConstantMass`](crate::Separability) the explicit
/// Störmer–Verlet step (no Newton iteration). Nothing on this path uses
/// stack space that grows with the size: a chain of 100 000 masses runs in
/// a thread with the default 2 MiB stack.
///
/// A failed step changes nothing: the error carries the state the step
/// started from, and a retry with a smaller step
/// ([`set_step_size`](Self::set_step_size)) starts there.
///
/// ```
/// use lagrangian_runtime::{DynIntegrator, DynLagrangian, Midpoint, RunTimeStepping, Scalar};
///
/// /// Uncoupled oscillators, as many as `n`.
/// struct Oscillators { n: usize }
/// impl DynLagrangian for Oscillators {
///     const AUTONOMOUS: bool = true;
///     fn dimension(&self) -> usize { self.n }
///     fn lagrangian<D: Scalar>(&self, _t: D, q: &[D], v: &[D]) -> D {
///         let mut l = D::from(0.0);
///         for i in 0..q.len() {
///             l += (v[i] * v[i] - q[i] * q[i]) * 0.5;
///         }
///         l
///     }
/// }
///
/// let n = 3;
/// let mut sim = DynIntegrator::new(Oscillators { n }, Midpoint, 0.01).start(0.0, &vec![1.0; n], &vec![0.0; n])?;
/// sim.run(628, |_| {})?;
/// assert!((sim.state().q[2] - 6.28f64.cos()).abs() < 1e-4);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
#[derive(Debug)]
pub struct DynIntegrator<S, M> {
    system: S,
    method: M,
    /// The rule's quadrature points.
    points: [f64; 2],
    h: f64,
    newton: NewtonOptions,
    /// How increments are added to the state; under [`Summation::Plain`]
    /// `carry` and `p_carry` stay zero.
    summation: Summation,
    state: PhasePoint,
    /// Kahan compensation of the position: it is `state.q + carry`.
    carry: Vec<f64>,
    /// Kahan compensation of the momentum: it is `state.p + p_carry`.
    p_carry: Vec<f64>,
    /// The energy of the initial data.
    energy: f64,
    v0: Vec<f64>,
    previous: Option<DynSegment>,
    /// `(h, Δq)` of the step before the last, for the predictor.
    earlier: Option<(f64, Vec<f64>)>,
    /// Compositions: the last sub-step of the last (composed) step, the
    /// readouts' segment; `previous` and `earlier` hold whole steps.
    last_substep: Option<LastSubstep>,
    /// Compositions: the size of the last composed step (`previous` is its
    /// last sub-step when the sub-steps are taken one by one).
    composed_h: Option<f64>,
    clock: Clock<f64>,
    stats: Stats,
    work: Box<SparseWork>,
    /// The work of a Galerkin rule's steps; `None` for the other methods.
    galerkin: Option<Box<GalerkinWork>>,
    /// Energy-preserving steps; `None`: fixed steps.
    variable: Option<Box<EnergySteps>>,
}

/// A copy owns buffers of its own. `clone_from` refills the buffers the
/// target already has (the step's scratch is not copied): `solve`, when it
/// may have to go back to a node, refreshes its copy of the integrator
/// before every step this way, without allocating.
impl<S: Clone, M: Clone> Clone for DynIntegrator<S, M> {
    fn clone(&self) -> Self {
        Self {
            system: self.system.clone(),
            method: self.method.clone(),
            points: self.points,
            h: self.h,
            newton: self.newton,
            summation: self.summation,
            state: self.state.clone(),
            carry: self.carry.clone(),
            p_carry: self.p_carry.clone(),
            energy: self.energy,
            v0: self.v0.clone(),
            previous: self.previous.clone(),
            earlier: self.earlier.clone(),
            last_substep: self.last_substep.clone(),
            composed_h: self.composed_h,
            clock: self.clock,
            stats: self.stats,
            work: self.work.clone(),
            galerkin: self.galerkin.clone(),
            variable: self.variable.clone(),
        }
    }

    fn clone_from(&mut self, source: &Self) {
        // Every field by name, so that a new one cannot be forgotten.
        let Self {
            system,
            method,
            points,
            h,
            newton,
            summation,
            state,
            carry,
            p_carry,
            energy,
            v0,
            previous,
            earlier,
            last_substep,
            composed_h,
            clock,
            stats,
            work,
            galerkin,
            variable,
        } = self;
        system.clone_from(&source.system);
        method.clone_from(&source.method);
        *points = source.points;
        *h = source.h;
        *newton = source.newton;
        *summation = source.summation;
        state.clone_from(&source.state);
        carry.clone_from(&source.carry);
        p_carry.clone_from(&source.p_carry);
        *energy = source.energy;
        v0.clone_from(&source.v0);
        previous.clone_from(&source.previous);
        match (earlier, &source.earlier) {
            (Some((h, dq)), Some((source_h, source_dq))) => {
                *h = *source_h;
                dq.clone_from(source_dq);
            }
            (to, from) => to.clone_from(from),
        }
        last_substep.clone_from(&source.last_substep);
        *composed_h = source.composed_h;
        *clock = source.clock;
        *stats = source.stats;
        work.as_mut().clone_from(&source.work);
        galerkin.clone_from(&source.galerkin);
        variable.clone_from(&source.variable);
    }
}

impl<S, M> DynIntegrator<S, M> {
    /// Configures an integrator for `system` with the discrete Lagrangian
    /// `method` and step `h`; continue with [`DynIntegratorBuilder::start`].
    #[allow(clippy::new_ret_no_self)]
    pub fn new(system: S, method: M, h: f64) -> DynIntegratorBuilder<S, M> {
        DynIntegratorBuilder {
            system,
            method,
            h,
            newton: NewtonOptions::default(),
            summation: Summation::Compensated,
            energy_steps: None,
            fallback: EnergyFallback::Fail,
        }
    }
}

/// The node a step of a run-time-sized integrator starts from: its state,
/// the compensations `(carry, p_carry)` and how the step sums.
fn node_at<'a>(state: &'a PhasePoint, (q_carry, p_carry): (&'a [f64], &'a [f64]), summation: Summation) -> Node<'a> {
    let PhasePoint { step, t, q, p } = state;
    Node { step: *step, t: *t, q, p, q_carry, p_carry, plain: summation.is_plain() }
}

impl<S: DynLagrangian, M: DynMethod> DynIntegrator<S, M> {
    /// The rule's DEL is explicit for this system (see
    /// [`DiscreteLagrangian::EXPLICIT_FOR_CONSTANT_MASS`]).
    /// A force (which may depend on `v`) makes every step implicit, as at a
    /// compile-time size.
    const EXPLICIT: bool = M::EXPLICIT_FOR_CONSTANT_MASS && S::SEPARABILITY.has_constant_mass() && !is_forced::<S>();

    /// The current state `(k, t_k, q_k, p_k)`.
    pub fn state(&self) -> &PhasePoint {
        &self.state
    }

    /// The system being integrated.
    pub fn system(&self) -> &S {
        &self.system
    }

    /// The discrete Lagrangian in use.
    pub fn method(&self) -> &M {
        &self.method
    }

    /// The number of coordinates.
    pub fn dimension(&self) -> usize {
        self.state.q.len()
    }

    /// The current step size.
    pub fn step_size(&self) -> f64 {
        self.h
    }

    /// The size of the last step taken; `None` before the first.
    pub fn last_step_size(&self) -> Option<f64> {
        self.composed_h.or(self.previous.as_ref().map(|last| last.h))
    }

    /// How increments are added to the state ([`DynIntegratorBuilder::summation`]).
    pub fn summation(&self) -> Summation {
        self.summation
    }

    /// Work counters (Newton iterations per step: `newton_iterations / steps`;
    /// 0 on the explicit path).
    pub fn stats(&self) -> &Stats {
        &self.stats
    }

    /// Changes the step size for the following steps (for example to retry a
    /// failed step with a smaller one). The integrator stays variational: the
    /// DEL equations hold with the step sizes actually taken.
    ///
    /// Under energy-preserving steps `h` is the next guess and must lie in
    /// `[h_min, h_max]`.
    pub fn set_step_size(&mut self, h: f64) -> Result<(), Error> {
        Error::check_step(h)?;
        if let Some(steps) = &self.variable
            && !(steps.bounds.h_min..=steps.bounds.h_max).contains(&h)
        {
            return Err(Error::InvalidStepSize { h });
        }
        self.clock = Clock { t: self.state.t, step: self.state.step };
        self.h = h;
        Ok(())
    }

    /// Takes one step: of size [`step_size`](Self::step_size) under fixed
    /// steps, of the size the energy equation fixes under
    /// [`energy-preserving`](DynIntegratorBuilder::energy_preserving) steps.
    ///
    /// On failure nothing changes: the state, the step size and the
    /// predictor are those from before the call, and the error carries the
    /// state and the Newton diagnostics.
    pub fn step(&mut self) -> Result<&PhasePoint, Error> {
        if self.variable.is_some() {
            self.energy_step()?;
            return Ok(&self.state);
        }
        let t1 = self.clock.at(self.state.step + 1, self.h);
        self.step_by(self.h, t1)?;
        Ok(&self.state)
    }

    /// One step toward `t_end` (see
    /// [`RunTimeStepping::step_toward`](crate::RunTimeStepping::step_toward)):
    /// the landing step is shortened to end on `t_end` exactly (a step
    /// that would end within `10⁻⁹ h` of it is stretched by that much
    /// instead), and the step size is then restored; a no-op at or beyond
    /// `t_end`.
    ///
    /// Under energy-preserving steps every step, the last included, is at
    /// most the largest admissible step `min(h_max, max_ratio·h_{k−1})`; the
    /// last one is a fixed step of the remaining length (the energy equation
    /// is not imposed on it, and its discrete energy is conserved from then
    /// on) and may be shorter than `h_min`.
    pub(crate) fn step_toward(&mut self, t_end: f64) -> Result<(), Error> {
        let remaining = t_end - self.state.t;
        if remaining.is_nan() || remaining <= 0.0 {
            return Ok(());
        }
        if !self.lands(t_end) {
            return self.step().map(|_| ());
        }
        self.step_by(remaining, t_end)?;
        self.clock = Clock { t: self.state.t, step: self.state.step };
        if self.variable.is_some() {
            // A fixed landing step: its energy is conserved from here on.
            self.reread_energy();
        }
        Ok(())
    }

    /// One fixed step of size `h` (negative too) whose end node is stamped
    /// `t1`, apart from the step size and the clock: a sub-step of a
    /// composition of this rule. On failure nothing changes but the
    /// failure count.
    pub(crate) fn sub_step(&mut self, h: f64, t1: f64) -> Result<(), Error> {
        self.step_by(h, t1)
    }

    /// Numbers the current node `k` (a composition of this rule counts its
    /// nodes, not its sub-steps).
    pub(crate) fn number_node(&mut self, k: u64) {
        self.state.step = k;
        self.work.rekey_node_force(k);
    }

    /// `true` when the next step toward `t_end` is its landing step: a
    /// whole step would reach `t_end` or come within `10⁻⁹ h` of it; under
    /// energy-preserving steps, the largest admissible step would reach it.
    fn lands(&self, t_end: f64) -> bool {
        match (&self.variable, &self.previous) {
            (None, _) => super::fixed_step_lands(self.clock.at(self.state.step + 1, self.h), self.h, t_end),
            (Some(steps), Some(last)) => t_end - self.state.t <= steps.bounds.bracket(last.h).1,
            (Some(_), None) => t_end - self.state.t <= self.h,
        }
    }

    /// One step of size `h` whose end node is stamped with time `t1`.
    fn step_by(&mut self, h: f64, t1: f64) -> Result<(), Error> {
        if self.galerkin.is_some() {
            return self.galerkin_step(h, t1);
        }
        match self.method.weights() {
            // Explicit sub-steps are fused, unless a discontinuous system's
            // energy watch needs each one.
            Some(weights) if Self::EXPLICIT && !S::DISCONTINUOUS => self.fused_step(weights, h, t1),
            Some(weights) => self.substeps(weights, h, t1),
            None => self.single_step(h, t1),
        }
    }

    /// A composed step taken sub-step by sub-step (Newton sub-steps, or a
    /// discontinuous system): each one a step of the trapezoid rule of size
    /// `γ_i h`, then the node counted once. A failed sub-step puts back the
    /// state, the compensations, the last two segments and the counters
    /// from before the composed step.
    fn substeps(&mut self, weights: &[f64], h: f64, t1: f64) -> Result<(), Error> {
        let saved = (self.state.clone(), self.carry.clone(), self.p_carry.clone());
        let memory = (self.previous.clone(), self.earlier.clone(), self.work.energy, self.stats);
        let (start, mut elapsed) = (self.state.t, 0.0);
        for (i, &gamma) in weights.iter().enumerate() {
            elapsed += gamma;
            let ti = if i + 1 == weights.len() { t1 } else { start + elapsed * h };
            if let Err(e) = self.single_step(gamma * h, ti) {
                let (state, carry, p_carry) = saved;
                let (previous, earlier, energy, stats) = memory;
                (self.state, self.carry, self.p_carry) = (state, carry, p_carry);
                (self.previous, self.earlier) = (previous, earlier);
                // The node force (of a sub-node) is recomputed, to the same bits.
                self.work.forget_node_force();
                self.work.energy = energy;
                self.stats = stats;
                self.stats.failed_steps += 1;
                return Err(at_composed(e, self.state.clone(), h));
            }
        }
        let (before, stats) = (saved.0.step, memory.3.steps);
        self.state.step = before + 1;
        self.stats.steps = stats + 1;
        self.work.rekey_node_force(before + 1);
        self.composed_h = Some(h);
        Ok(())
    }

    /// A composed step of explicit sub-steps, fused
    /// ([`SparseWork::verlet_composed`]).
    fn fused_step(&mut self, weights: &[f64], h: f64, t1: f64) -> Result<(), Error> {
        let last = self.previous.as_ref().map(|last| (last.h, &last.dq[..]));
        let earlier = self.earlier.as_ref().map(|(h, dq)| (*h, &dq[..]));
        let model = Sliced { system: &self.system, points: self.points };
        let node = node_at(&self.state, (&self.carry, &self.p_carry), self.summation);
        let predict = |out: &mut [f64]| super::predict_into(h, last, earlier, &self.v0, out);
        let last = self.previous.as_ref().map(|last| (&last.dq[..], h / last.h));
        let growth = Growth { last, predict: &predict };
        let outcome = self.work.verlet_composed(&model, &node, h, t1, weights, &growth, self.newton.min_rcond);
        let Composed { taken, last } = match outcome {
            Ok(composed) => composed,
            Err(failure) => {
                self.stats.failed_steps += 1;
                return Err(Error::from_newton(failure, self.state.clone(), h));
            }
        };
        self.commit(taken, h, t1);
        if let Some(old) = self.last_substep.replace(last) {
            self.work.recycle(old.q0);
            self.work.recycle(old.dq);
        }
        self.composed_h = Some(h);
        Ok(())
    }

    /// One step of the rule (a sub-step of a composition: the trapezoid
    /// rule's) of size `h` ending at `t1`.
    fn single_step(&mut self, h: f64, t1: f64) -> Result<(), Error> {
        let last = self.previous.as_ref().map(|last| (last.h, &last.dq[..]));
        let earlier = self.earlier.as_ref().map(|(h, dq)| (*h, &dq[..]));
        let model = Sliced { system: &self.system, points: self.points };
        // The last step's discrete energy, read before an explicit step clears it.
        let before = self.work.energy.unwrap_or(self.energy);
        let node = node_at(&self.state, (&self.carry, &self.p_carry), self.summation);
        let outcome = if Self::EXPLICIT {
            // The predictor only when the growth check needs it.
            let predict = |out: &mut [f64]| super::predict_into(h, last, earlier, &self.v0, out);
            let last = self.previous.as_ref().map(|last| (&last.dq[..], h / last.h));
            let growth = Growth { last, predict: &predict };
            self.work.verlet_step(&model, &node, h, t1, &growth, self.newton.min_rcond).map(|taken| (taken, None))
        } else {
            let mut predictor = vec![0.0; self.state.q.len()];
            super::predict_into(h, last, earlier, &self.v0, &mut predictor);
            let scaled: Option<Vec<f64>> =
                self.previous.as_ref().map(|last| last.dq.iter().map(|x| x * (h / last.h)).collect());
            let guess = Guess { predictor: &predictor, last: scaled.as_deref() };
            self.work.newton_step(&model, &node, h, t1, &guess, &self.newton).map(|(taken, e)| (taken, Some(e)))
        };
        let (taken, energy) = match outcome {
            Ok(x) => x,
            Err(failure) => {
                self.stats.failed_steps += 1;
                return Err(Error::from_newton(failure, self.state.clone(), h));
            }
        };
        // An explicit step computes no energy; a discontinuous system's watch
        // takes it from the new segment (one reverse sweep).
        let energy = match energy {
            None if S::DISCONTINUOUS => {
                let model = Sliced { system: &self.system, points: self.points };
                Some(tape_step::step_energy(&model, self.state.t, h, &self.state.q, &taken.dq))
            }
            energy => energy,
        };
        if let (true, Some(after)) = (S::DISCONTINUOUS, energy) {
            tape_step::watch_energy_jump(&mut self.stats, before, after, t1);
        }
        if !Self::EXPLICIT || S::DISCONTINUOUS {
            self.work.energy = energy;
        }
        self.commit(taken, h, t1);
        Ok(())
    }

    /// Replaces the state by the step `taken` from the current node; the
    /// buffers it frees go back to the work for the next step.
    fn commit(&mut self, taken: Taken, h: f64, t1: f64) {
        let Taken { dq, q1, q_carry, p1, p_carry, report } = taken;
        let q0 = core::mem::replace(&mut self.state.q, q1);
        let p0 = core::mem::replace(&mut self.state.p, p1);
        // Under plain summation the step wrote no compensations: the zeros stay.
        let freed = match self.summation {
            Summation::Compensated => {
                [p0, core::mem::replace(&mut self.carry, q_carry), core::mem::replace(&mut self.p_carry, p_carry)]
            }
            Summation::Plain => [p0, q_carry, p_carry],
        };
        for buffer in freed {
            self.work.recycle(buffer);
        }
        if let Some((_, dq)) = self.earlier.take() {
            self.work.recycle(dq);
        }
        self.earlier = self.previous.take().map(|last| {
            self.work.recycle(last.q0);
            (last.h, last.dq)
        });
        self.previous = Some(DynSegment { t0: self.state.t, h, q0, dq });
        self.state.t = t1;
        self.state.step += 1;
        self.stats.steps += 1;
        self.stats.newton_iterations += report.iterations as u64;
        self.stats.last = report;
    }

    /// The discrete energy `E_k = −∂A(x_{k−1}, x_k)/∂t_k` of the last step
    /// (one reverse sweep unless the step recorded it); at `k = 0`, the
    /// continuous energy of the initial data.
    pub fn discrete_energy(&self) -> f64 {
        let model = Sliced { system: &self.system, points: self.points };
        // A composition's: that of its last sub-step.
        if let Some(last) = &self.last_substep {
            return tape_step::step_energy(&model, last.t0, last.h, &last.q0, &last.dq);
        }
        let Some(seg) = &self.previous else { return self.energy };
        match self.work.energy {
            Some(e) => e,
            None => tape_step::step_energy(&model, seg.t0, seg.h, &seg.q0, &seg.dq),
        }
    }

    /// The velocity `v_k` whose momentum `∂L/∂v(t_k, q_k, v_k)` is `p_k`:
    /// `M⁻¹ p_k` with the factored mass matrix of the explicit path on a
    /// system with [`Separability::ConstantMass`](crate::Separability), else
    /// Newton from the last secant velocity, with banded or dense solves.
    pub fn velocity(&self) -> Result<Vec<f64>, Error> {
        if S::SEPARABILITY.has_constant_mass() {
            let mut v = vec![0.0; self.state.p.len()];
            if self.work.constant_mass_velocity(&self.state.p, &mut v) {
                return Ok(v);
            }
        }
        // The last (sub-)step's secant velocity.
        let last = match &self.last_substep {
            Some(sub) => Some((sub.h, &sub.dq)),
            None => self.previous.as_ref().map(|last| (last.h, &last.dq)),
        };
        let guess: Vec<f64> = match last {
            Some((h, dq)) => dq.iter().map(|x| x / h).collect(),
            None => self.v0.clone(),
        };
        let model = Sliced { system: &self.system, points: self.points };
        let PhasePoint { t, q, p, .. } = &self.state;
        tape_step::velocity(&model, *t, q, p, &guess).map_err(|(iterations, residual_norm)| Error::InverseLegendre {
            state: self.state.clone(),
            iterations,
            residual_norm,
        })
    }

    /// The continuous energy `E_L(t_k, q_k, v_k)` at the velocity of the current momentum.
    pub fn energy(&self) -> Result<f64, Error> {
        let v = self.velocity()?;
        let model = Sliced { system: &self.system, points: self.points };
        Ok(tape_step::energy(&model, self.state.t, &self.state.q, &v))
    }
}
