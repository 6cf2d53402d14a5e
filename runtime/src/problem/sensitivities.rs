//! The entry points of the derivatives of a run
//! ([`crate::sensitivity`]): forward sensitivities with the solution, and
//! the adjoint gradient of a loss.

use core::cell::RefCell;

use nalgebra::DVector;

use super::extend::Extended;
use super::scheme::{OnePoint, Scheme};
use super::statement::Problem;
use super::stepper::{Driver, Interpolant, Stepper};
use super::support::{Capability, Policy};
use crate::dense::Node;
use crate::derivatives::Segment;
use crate::dim::Dim;
use crate::discrete::DiscreteLagrangian;
use crate::error::Error;
use crate::galerkin::Galerkin;
use crate::integrator::{Integrator, Stats, StepPolicy};
use crate::sensitivity::Parametric;
use crate::sensitivity::adjoint::{self, Checkpoints, Gradient, Loss};
use crate::sensitivity::forward::{Propagation, Sensitivities};
use crate::sensitivity::galerkin_energy;
use crate::sensitivity::linearisation::{Piece, Rule};
use crate::sensitivity::split::{self, Reverse};
use crate::sensitivity::transformed::{Linear, Start};
use crate::solution::{Plan, SolveError, Stepping};
use crate::state::State;
use crate::system::Lagrangian;
use crate::time_transform::ExtendedPoint;

/// The largest system whose forward sensitivities
/// [`Problem::solve_with_sensitivities`] propagates. The tangent and a
/// step's Jacobian are dense `N × N` blocks: the propagation needs about
/// 0.8 MiB of stack at 32 coordinates, 1.2 MiB at 40 and 3 MiB at 64, more
/// than a default thread's 2 MiB.
pub const FORWARD_SENSITIVITIES_MAX_N: usize = 40;

/// Why a large system has no forward sensitivities.
const LARGE_FORWARD: &str = "forward sensitivities above `FORWARD_SENSITIVITIES_MAX_N` (40) coordinates: the tangent's dense \
     `N × N` blocks do not fit a thread's stack; the gradient of a loss (`Problem::gradient`, the adjoint) has no such limit";

/// Why a discontinuous Lagrangian has no sensitivities.
const DISCONTINUOUS: &str =
    "sensitivities of a discontinuous lagrangian: the step is not differentiable where the lagrangian jumps";

impl<S: Lagrangian<N> + Clone, const N: usize> Problem<S, Dim<N>>
where
    Dim<N>: Extended<N>,
{
    /// Asks [`supports`](super::supports) whether `scheme` under `policy`
    /// has sensitivities (and refuses a discontinuous Lagrangian).
    fn differentiable(&self, scheme: &Scheme, policy: Policy) -> Result<(), Error> {
        self.supports(scheme, policy, Capability::Sensitivities)?;
        if S::DISCONTINUOUS {
            return Err(Error::Unsupported { what: DISCONTINUOUS });
        }
        Ok(())
    }

    /// Solves as [`solve`](Self::solve) does and returns, with the solution,
    /// the derivatives `∂(q, p)/∂(q_0, v_0, θ)` of each of its rows
    /// ([`Sensitivities`]), propagated with the linearisation of each step
    /// (no finite differences).
    ///
    /// The combinations are those [`supports`](super::supports) accepts with
    /// [`Capability::Sensitivities`]: fixed steps of the one-point rules,
    /// the Galerkin rules, the compositions, the implicit time
    /// transformation and the explicit time-transformed splitting (`policy`
    /// is then the step `σ` in `s`; the node times move with the inputs,
    /// [`Jacobian::time`](crate::sensitivity::Jacobian::time)), and
    /// energy-preserving steps of the one-point and Galerkin rules and
    /// energy-balance steps of the one-point rules (the step sizes
    /// differentiated through the energy equation, with the discrete work
    /// of the forces under energy balance, the node times moving too). A step that took the least-squares fallback of the energy
    /// equation ends the sensitivities with [`Error::NotDifferentiable`] in
    /// [`Sensitivities::error`], the solution kept.
    /// Rows between nodes (save times, events) are refused
    /// ([`SolveError::InvalidPlan`]); an observer of the plan is still
    /// called. Systems of more than [`FORWARD_SENSITIVITIES_MAX_N`]
    /// coordinates are refused ([`Error::Unsupported`]): the tangent and
    /// each step's Jacobian are dense `N × N` blocks kept inline, `O(N²)`
    /// of stack and `O(N³)` of work per step; the gradient of a scalar
    /// loss ([`gradient`](Self::gradient), the discrete adjoint) has no
    /// such limit.
    ///
    /// ```
    /// use lagrangian_runtime::problem::{Problem, Scheme};
    /// use lagrangian_runtime::sensitivity::Parametric;
    /// use lagrangian_runtime::{Lagrangian, Plan, Scalar};
    ///
    /// /// `L = ½ v² − ½ k q²` with the stiffness `k` as a parameter.
    /// #[derive(Clone)]
    /// struct Spring { k: f64 }
    /// impl Lagrangian<1> for Spring {
    ///     const AUTONOMOUS: bool = true;
    ///     const CYCLIC: [bool; 1] = [false];
    ///     fn lagrangian<D: Scalar>(&self, t: D, q: [D; 1], v: [D; 1]) -> D {
    ///         self.lagrangian_with(&[D::from(self.k)], t, q, v)
    ///     }
    /// }
    /// impl Parametric<1, 1> for Spring {
    ///     const NAMES: [&'static str; 1] = ["k"];
    ///     fn parameters(&self) -> [f64; 1] { [self.k] }
    ///     fn with_parameters(&self, theta: [f64; 1]) -> Self { Spring { k: theta[0] } }
    ///     fn lagrangian_with<D: Scalar>(&self, theta: &[D; 1], _t: D, q: [D; 1], v: [D; 1]) -> D {
    ///         (v[0] * v[0] - theta[0] * q[0] * q[0]) * 0.5
    ///     }
    /// }
    ///
    /// let run = Problem::new(Spring { k: 1.0 }, 0.0, [1.0], [0.0])
    ///     .solve_with_sensitivities(&Scheme::MIDPOINT, 0.001, Plan::until(1.0))?;
    /// let last = run.jacobians.last().unwrap();
    /// // q(t) = cos(√k t): ∂q/∂q0 = cos t, ∂q/∂k = −(t/2) sin t at k = 1.
    /// assert!((last.get(0, 0) - 1f64.cos()).abs() < 1e-6);
    /// assert!((last.get(0, 2) + 0.5 * 1f64.sin()).abs() < 1e-6);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn solve_with_sensitivities<const P: usize>(
        &self,
        scheme: &Scheme,
        policy: impl Into<Policy>,
        plan: Plan<'_>,
    ) -> Result<Sensitivities<N>, SolveError>
    where
        S: Parametric<N, P>,
    {
        let policy = policy.into();
        self.differentiable(scheme, policy)?;
        if plan.interpolates() {
            return Err(SolveError::InvalidPlan {
                reason: "sensitivities are computed at the nodes: a plan with save times or events has rows between them",
            });
        }
        // A constant condition: above the limit the propagation is not
        // compiled at all, so no frame sized for its blocks is entered.
        if const { N > FORWARD_SENSITIVITIES_MAX_N } {
            return Err(Error::Unsupported { what: LARGE_FORWARD }.into());
        }
        self.propagated(scheme, policy, plan)
    }

    /// The run of [`solve_with_sensitivities`](Self::solve_with_sensitivities)
    /// once its arguments are checked.
    #[inline(never)]
    fn propagated<const P: usize>(
        &self,
        scheme: &Scheme,
        policy: Policy,
        plan: Plan<'_>,
    ) -> Result<Sensitivities<N>, SolveError>
    where
        S: Parametric<N, P>,
    {
        let stepper = self.stepper(scheme, policy)?;
        let (every, node) = (plan.kept_every(), stepper.state());
        let propagation = RefCell::new(match stepper.extended_start::<P>(self.initial())? {
            Some(start) => Propagation::extended(self.system(), start, every, &node),
            None => Propagation::new(self.system(), stepper.rule()?, self.initial(), every, &node),
        });
        let mut tracked = Tracked { stepper, propagation: &propagation, pieces: Vec::new() };
        let solution = Stepping::solve(&mut tracked, plan)?;
        Ok(propagation.into_inner().finish(solution))
    }

    /// The exact gradient of `loss` along the run from the initial data to
    /// `t_end` (the last step shortened to land on it, as
    /// [`Plan::until`] does) with respect to `q_0`, `v_0` and the
    /// parameters: the discrete adjoint, with a copy of the stepper kept as
    /// `checkpoints` says. Memory is the copies plus one segment of nodes.
    /// `policy` is a step size (fixed steps) or a [`Policy`]. Under a time
    /// transformation it is the step `σ` in `s`, the node times move with
    /// the inputs (the loss's `∂ℓ/∂t` enters), and the landing step's size,
    /// solved for `t_end`, is differentiated. Under energy-preserving steps
    /// of a one-point or Galerkin rule, and energy-balance steps of a
    /// one-point rule, the step sizes the energy equation fixes (with the
    /// discrete work of the forces) are differentiated and the node times move with the inputs too (the
    /// first step, of the given size, and the landing on `t_end` have their
    /// end times given).
    ///
    /// Errors: the refusal of [`supports`](super::supports) for a
    /// combination without sensitivities, [`Error::InvalidSetting`] for a
    /// checkpoint budget of zero, [`Error::NonFiniteLoss`] where the loss or
    /// its gradient is not finite, [`Error::NotDifferentiable`] for an
    /// energy-preserving step that took the least-squares fallback, and the
    /// errors of the steps.
    pub fn gradient<L: Loss<N, P>, const P: usize>(
        &self,
        scheme: &Scheme,
        policy: impl Into<Policy>,
        t_end: f64,
        loss: &L,
        checkpoints: Checkpoints,
    ) -> Result<Gradient<N, P>, Error>
    where
        S: Parametric<N, P>,
    {
        let policy = policy.into();
        self.differentiable(scheme, policy)?;
        let stepper = self.stepper(scheme, policy)?;
        let h = policy.step();
        if stepper.extended_node().is_some() {
            return adjoint::gradient_extended(stepper, self.initial(), h, t_end, loss, checkpoints);
        }
        let rule = stepper.rule()?;
        adjoint::gradient(stepper, rule, self.initial(), h, t_end, loss, checkpoints)
    }
}

/// Why a least-squares energy step has no derivative.
const LEAST_MISMATCH: &str = "its size minimises the mismatch of the energy equation (the least-squares fallback or \
     an accuracy cap) instead of solving it, and that minimum is not differentiated";

/// Where the next step of a stepper linearised in the extended phase
/// starts ([`Stepper::extended_node`]).
pub(crate) enum ExtendedNode<const N: usize> {
    /// A time-transformed stepper's node in `s`, `[s, x, p̃]`.
    Transformed(Vec<f64>),
    /// The splitting's point `(q, t, p, p_t)`.
    Split(ExtendedPoint<f64, N>),
    /// An energy-preserving stepper's: whether the next step is its first
    /// (of the given size), and how many of its steps so far minimised the
    /// energy mismatch instead of solving the energy equation.
    Energy { first: bool, inexact: u64 },
}

/// Why a composition stepped in reverse mode has no sensitivities.
const REVERSE_COMPOSITION: &str = "sensitivities of a composition stepped in reverse mode (above \
     `Derivatives::FORWARD_MAX_N` coordinates): its sub-steps are not kept";

/// Why a composition of other sub-steps than the trapezoid's has no
/// sensitivities (the text of `supports`' refusal).
const COMPOSED: &str = "sensitivities of a composition of midpoint, α-β or Galerkin sub-steps: the linearisation keeps the sub-steps of the trapezoid compositions only";

impl<S: Lagrangian<N> + Clone, const N: usize> Stepper<S, Dim<N>>
where
    Dim<N>: Extended<N>,
{
    /// The Galerkin rule every step of this stepper is made of.
    pub(crate) fn rule(&self) -> Result<Rule, Error> {
        Ok(match &*self.driver {
            Driver::Midpoint(_) => Rule::one_point(&OnePoint::Midpoint),
            Driver::Trapezoid(_) | Driver::Composition(_) => Rule::one_point(&OnePoint::Trapezoid),
            Driver::AlphaBeta(d) => Rule::one_point(&OnePoint::AlphaBeta(d.method)),
            Driver::Gauss2(d) => Rule::galerkin(&d.method),
            Driver::Gauss3(d) => Rule::galerkin(&d.method),
            Driver::Gauss4(d) => Rule::galerkin(&d.method),
            Driver::Gauss5(d) => Rule::galerkin(&d.method),
            Driver::Gauss6(d) => Rule::galerkin(&d.method),
            Driver::Gauss7(d) => Rule::galerkin(&d.method),
            Driver::Gauss8(d) => Rule::galerkin(&d.method),
            Driver::Lobatto2(d) => Rule::galerkin(&d.method),
            Driver::Lobatto3(d) => Rule::galerkin(&d.method),
            Driver::Lobatto4(d) => Rule::galerkin(&d.method),
            // Linearised in the extended phase (`extended_step`), not by
            // one rule in `t`.
            Driver::Transformed(_) | Driver::Splitting(_) => {
                return Err(Error::Unsupported { what: "one rule in `t` for the steps of a time transformation" });
            }
            // Refused by `supports` before a stepper is built.
            Driver::Composed(_) => return Err(Error::Unsupported { what: COMPOSED }),
        })
    }

    /// Where the next step of a stepper linearised in the extended phase
    /// starts, for [`extended_step`](Self::extended_step): a time-transformed
    /// stepper's node in `s`, or what an energy-preserving one-point
    /// stepper's next step depends on; `None` for the other steppers.
    pub(crate) fn extended_node(&self) -> Option<ExtendedNode<N>> {
        /// An energy-preserving integrator's node; `None` under fixed steps.
        fn energy<S: Lagrangian<N>, R: DiscreteLagrangian, const N: usize>(
            d: &Integrator<S, R, N>,
        ) -> Option<ExtendedNode<N>> {
            let StepPolicy::EnergyPreserving(_) = d.policy() else { return None };
            let stats = d.stats();
            Some(ExtendedNode::Energy {
                first: d.last_segment().is_none(),
                inexact: stats.energy_fallbacks + stats.accuracy_capped_steps,
            })
        }
        /// An energy-preserving Galerkin integrator's node (its memory is
        /// its last step); `None` under fixed steps.
        fn galerkin<S: Lagrangian<N>, const N: usize, const D: usize, const R: usize>(
            d: &Integrator<S, Galerkin<D, R>, N>,
        ) -> Option<ExtendedNode<N>> {
            let StepPolicy::EnergyPreserving(_) = d.policy() else { return None };
            let stats = d.stats();
            Some(ExtendedNode::Energy {
                first: d.memory.is_none(),
                inexact: stats.energy_fallbacks + stats.accuracy_capped_steps,
            })
        }
        match &*self.driver {
            Driver::Transformed(d) => Some(ExtendedNode::Transformed(<Dim<N> as Extended<N>>::node(d))),
            Driver::Splitting(d) => Some(ExtendedNode::Split(d.extended_point())),
            Driver::Midpoint(d) => energy(d),
            Driver::Trapezoid(d) => energy(d),
            Driver::AlphaBeta(d) => energy(d),
            Driver::Gauss2(d) => galerkin(d),
            Driver::Gauss3(d) => galerkin(d),
            Driver::Gauss4(d) => galerkin(d),
            Driver::Gauss5(d) => galerkin(d),
            Driver::Gauss6(d) => galerkin(d),
            Driver::Gauss7(d) => galerkin(d),
            Driver::Gauss8(d) => galerkin(d),
            Driver::Lobatto2(d) => galerkin(d),
            Driver::Lobatto3(d) => galerkin(d),
            Driver::Lobatto4(d) => galerkin(d),
            Driver::Composition(_) | Driver::Composed(_) => None,
        }
    }

    /// The linearisation in the extended phase of the last step, from
    /// `node` (of [`extended_node`](Self::extended_node)), which was `from`
    /// in physical time; `target`: the time the step was asked to land on,
    /// if any.
    pub(crate) fn extended_step<const P: usize>(
        &self,
        node: &ExtendedNode<N>,
        from: &State<N>,
        target: Option<f64>,
    ) -> Result<Linear, Error>
    where
        S: Parametric<N, P>,
    {
        let to = Stepping::state(self);
        let singular =
            || Error::SingularJacobian { state: (*from).into(), h: to.t - from.t, iterations: 0, rcond: 0.0 };
        let missing = Error::Unsupported { what: "sensitivities of a step whose nodes were not kept" };
        match (node, &*self.driver) {
            (ExtendedNode::Transformed(node), Driver::Transformed(d)) => {
                <Dim<N> as Extended<N>>::linearise::<S, P>(d, node).ok_or_else(singular)
            }
            // No equation is solved: only a derivative can fail.
            (ExtendedNode::Split(node), Driver::Splitting(d)) => {
                split::linearise::<S, N, P>(d, node).ok_or_else(|| Error::NonFinite {
                    state: (*from).into(),
                    h: to.t - from.t,
                    iterations: 0,
                    quantity: "jacobian",
                })
            }
            (&ExtendedNode::Energy { first, inexact }, driver) => {
                let stats = Stepping::stats(self);
                if stats.energy_fallbacks + stats.accuracy_capped_steps != inexact {
                    return Err(Error::NotDifferentiable { state: (*from).into(), reason: LEAST_MISMATCH });
                }
                // The first step has the given size; a landing ends on its
                // target (no energy step ends there: it would have landed).
                let pinned = first || target == Some(to.t);
                let rule = self.rule()?;
                // A Galerkin step's nodes and size, as the driver kept them.
                macro_rules! galerkin {
                    ($d:expr) => {{
                        let l = $d.memory.as_ref().ok_or(missing)?;
                        let piece = Piece::kept(l.t0, l.h, l.q0, l.carry, &l.d);
                        galerkin_energy::linearise::<S, N, P>(self.system(), &rule, &piece, pinned).ok_or_else(singular)
                    }};
                }
                let seg = match driver {
                    Driver::Midpoint(d) => d.last_segment(),
                    Driver::Trapezoid(d) => d.last_segment(),
                    Driver::AlphaBeta(d) => d.last_segment(),
                    Driver::Gauss2(d) => return galerkin!(d),
                    Driver::Gauss3(d) => return galerkin!(d),
                    Driver::Gauss4(d) => return galerkin!(d),
                    Driver::Gauss5(d) => return galerkin!(d),
                    Driver::Gauss6(d) => return galerkin!(d),
                    Driver::Gauss7(d) => return galerkin!(d),
                    Driver::Gauss8(d) => return galerkin!(d),
                    Driver::Lobatto2(d) => return galerkin!(d),
                    Driver::Lobatto3(d) => return galerkin!(d),
                    Driver::Lobatto4(d) => return galerkin!(d),
                    _ => None,
                };
                <Dim<N> as Extended<N>>::linearise_energy::<S, P>(self.system(), &rule, seg.ok_or(missing)?, pinned)
                    .ok_or_else(singular)
            }
            _ => Err(missing),
        }
    }

    /// The last step of a stepper linearised in the extended phase, from
    /// its node `node` (`from` in physical time; `target` as for
    /// [`extended_step`](Self::extended_step)), as the reverse sweep keeps
    /// it: the splitting's full steps by their end point and size, the rest by
    /// their linearisation.
    pub(crate) fn extended_reverse<const P: usize>(
        &self,
        node: ExtendedNode<N>,
        from: &State<N>,
        target: Option<f64>,
    ) -> Result<Reverse<N>, Error>
    where
        S: Parametric<N, P>,
    {
        match (node, &*self.driver) {
            (ExtendedNode::Split(node), Driver::Splitting(d)) => {
                split::reverse::<S, N, P>(d, &node).ok_or_else(|| Error::NonFinite {
                    state: (*from).into(),
                    h: Stepping::state(self).t - from.t,
                    iterations: 0,
                    quantity: "jacobian",
                })
            }
            (node, _) => self.extended_step::<P>(&node, from, target).map(Reverse::Dense),
        }
    }

    /// Pulls the costate `lambda` back through a full step of the
    /// splitting kept as [`Reverse::Step`] (see [`split::Transpose`],
    /// made on first use); `None` for another stepper or where a result is
    /// not finite.
    pub(crate) fn splitting_pullback<const P: usize>(
        &self,
        transpose: &mut Option<split::Transpose<N, P>>,
        step: (&ExtendedPoint<f64, N>, f64),
        lambda: &mut DVector<f64>,
        (dtheta, dc): (&mut [f64; P], &mut f64),
    ) -> Option<()>
    where
        S: Parametric<N, P>,
    {
        let Driver::Splitting(d) = &*self.driver else { return None };
        transpose.get_or_insert_with(|| split::Transpose::new(d)).step(d, step, lambda, dtheta, dc)
    }

    /// The derivatives of the first node in the extended phase of a
    /// time-transformed or energy-preserving stepper from the initial data
    /// `initial` (`None` for the other steppers).
    pub(crate) fn extended_start<const P: usize>(
        &self,
        initial: (f64, [f64; N], [f64; N]),
    ) -> Result<Option<Start>, Error>
    where
        S: Parametric<N, P>,
    {
        let start = match self.extended_node() {
            None => return Ok(None),
            Some(ExtendedNode::Transformed(_) | ExtendedNode::Split(_)) => match &*self.driver {
                Driver::Transformed(d) => <Dim<N> as Extended<N>>::start_tangent::<S, P>(d, initial),
                Driver::Splitting(d) => split::start::<S, N, P>(d, initial),
                _ => None,
            },
            Some(ExtendedNode::Energy { .. }) => <Dim<N> as Extended<N>>::energy_start::<S, P>(self.system(), initial),
        };
        start.map(Some).ok_or(Error::InvalidInitialData {
            reason: "the derivatives of the initial data in the extended phase are not finite",
        })
    }

    /// Appends to `out` the Galerkin steps of [`rule`](Self::rule) the last
    /// step, from `from` to the current node, was made of.
    pub(crate) fn last_pieces(&self, from: &State<N>, out: &mut Vec<Piece<N>>) -> Result<(), Error> {
        let to = Stepping::state(self);
        let missing = Error::Unsupported { what: "sensitivities of a step whose nodes were not kept" };
        // The last Galerkin step a driver kept, as a piece (one arm per
        // rule: each variant's memory is its own type).
        macro_rules! kept {
            ($d:expr) => {{
                let l = $d.memory.as_ref().ok_or(missing)?;
                Piece::kept(l.t0, l.h, l.q0, l.carry, &l.d)
            }};
        }
        match &*self.driver {
            Driver::Midpoint(_) | Driver::Trapezoid(_) | Driver::AlphaBeta(_) => {
                out.push(Piece::segment(&Segment::between((from.t, from.q), (to.t, to.q))));
            }
            Driver::Gauss2(d) => out.push(kept!(d)),
            Driver::Gauss3(d) => out.push(kept!(d)),
            Driver::Gauss4(d) => out.push(kept!(d)),
            Driver::Gauss5(d) => out.push(kept!(d)),
            Driver::Gauss6(d) => out.push(kept!(d)),
            Driver::Gauss7(d) => out.push(kept!(d)),
            Driver::Gauss8(d) => out.push(kept!(d)),
            Driver::Lobatto2(d) => out.push(kept!(d)),
            Driver::Lobatto3(d) => out.push(kept!(d)),
            Driver::Lobatto4(d) => out.push(kept!(d)),
            Driver::Composition(d) => {
                if d.derivatives.reverse::<N>() {
                    return Err(Error::Unsupported { what: REVERSE_COMPOSITION });
                }
                let weights = d.method.weights();
                out.extend((0..d.memory.stages).map(|i| Piece::segment(&d.memory.substep(i, weights, d.summation))));
            }
            Driver::Composed(_) => return Err(Error::Unsupported { what: COMPOSED }),
            Driver::Transformed(_) | Driver::Splitting(_) => return Err(missing),
        }
        Ok(())
    }
}

/// A stepper that hands each step it takes to the forward propagation:
/// [`Stepping::solve`] runs it as it runs the stepper itself.
struct Tracked<'p, 's, S: Parametric<N, P>, const N: usize, const P: usize>
where
    Dim<N>: Extended<N>,
{
    stepper: Stepper<S, Dim<N>>,
    propagation: &'p RefCell<Propagation<'s, S, N, P>>,
    /// The pieces of the last step (storage reused from step to step).
    pieces: Vec<Piece<N>>,
}

impl<S: Parametric<N, P>, const N: usize, const P: usize> Clone for Tracked<'_, '_, S, N, P>
where
    Dim<N>: Extended<N>,
{
    fn clone(&self) -> Self {
        Self { stepper: self.stepper.clone(), propagation: self.propagation, pieces: Vec::new() }
    }

    /// The stepper in place: no allocation.
    fn clone_from(&mut self, source: &Self) {
        self.stepper.clone_from(&source.stepper);
        self.propagation = source.propagation;
    }
}

impl<S: Parametric<N, P>, const N: usize, const P: usize> Tracked<'_, '_, S, N, P>
where
    Dim<N>: Extended<N>,
{
    /// Runs `step`, asked to land on `target` if any, and propagates the
    /// tangent through it when it succeeds.
    fn tracked(
        &mut self,
        target: Option<f64>,
        step: impl FnOnce(&mut Stepper<S, Dim<N>>) -> Result<(), Error>,
    ) -> Result<(), Error> {
        let from = self.stepper.state();
        let node = self.stepper.extended_node();
        step(&mut self.stepper)?;
        let to = self.stepper.state();
        if let Some(node) = node {
            // A landing that found the node already on its target took no step.
            if to.step != from.step {
                let linear = self.stepper.extended_step::<P>(&node, &from, target);
                self.propagation.borrow_mut().step_extended(linear, &to);
            }
            return Ok(());
        }
        self.pieces.clear();
        let pieces = self.stepper.last_pieces(&from, &mut self.pieces).map(|()| self.pieces.as_slice());
        self.propagation.borrow_mut().step(&from, pieces, &to);
        Ok(())
    }
}

impl<S: Parametric<N, P>, const N: usize, const P: usize> Stepping<N> for Tracked<'_, '_, S, N, P>
where
    Dim<N>: Extended<N>,
{
    type System = S;
    type Native = Interpolant<N>;

    fn system(&self) -> &S {
        Stepping::system(&self.stepper)
    }

    fn state(&self) -> State<N> {
        Stepping::state(&self.stepper)
    }

    fn velocity(&self) -> Result<[f64; N], Error> {
        Stepping::velocity(&self.stepper)
    }

    fn stats(&self) -> Stats {
        Stepping::stats(&self.stepper)
    }

    fn step(&mut self) -> Result<(), Error> {
        self.tracked(None, Stepping::step)
    }

    fn step_toward(&mut self, t_end: f64, last_h: Option<f64>) -> Result<(), Error> {
        self.tracked(Some(t_end), |s| Stepping::step_toward(s, t_end, last_h))
    }

    /// One step at a time, so that each is propagated (a plan for
    /// sensitivities lands only on its end, one step away).
    fn land(&mut self, t: f64) -> Result<(), Error> {
        let mut last_h = None;
        while Stepping::state(&self.stepper).t < t {
            let t0 = Stepping::state(&self.stepper).t;
            self.step_toward(t, last_h)?;
            last_h = Some(Stepping::state(&self.stepper).t - t0);
        }
        Ok(())
    }

    fn native(&self, start: &Node<N>, end: &Node<N>) -> Interpolant<N> {
        Stepping::native(&self.stepper, start, end)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::EnergyFallback;
    use crate::sensitivity::fixtures::Pendulum;
    use crate::system::Scalar;

    /// The angle at the end.
    struct Angle;
    impl Loss<1, 2> for Angle {
        fn terminal<D: Scalar>(&self, _t: D, q: [D; 1], _p: [D; 1], _theta: &[D; 2]) -> D {
            q[0]
        }
    }

    /// A trapezoid stepper on energy-preserving steps with the least-squares
    /// fallback: its energy equation loses its root on the pendulum from
    /// 1 rad (docs/capabilities.md), and the run goes on through
    /// least-mismatch steps.
    fn least_squares(problem: &Problem<Pendulum, Dim<1>>) -> Stepper<Pendulum, Dim<1>> {
        let mut stepper = problem.stepper(&Scheme::TRAPEZOID, Policy::energy_preserving(0.02)).unwrap();
        let Driver::Trapezoid(d) = &mut *stepper.driver else { unreachable!("the trapezoid driver") };
        d.fallback = EnergyFallback::LeastSquares;
        stepper
    }

    #[test]
    fn a_least_mismatch_energy_step_is_not_differentiated() {
        let problem = Problem::new(Pendulum { theta: [1.3, 9.81] }, 0.0, [1.0], [0.3]);
        let stepper = least_squares(&problem);
        let start = stepper.extended_start::<2>(problem.initial()).unwrap().unwrap();
        let propagation = RefCell::new(Propagation::extended(problem.system(), start, 1, &stepper.state()));
        let mut tracked = Tracked { stepper, propagation: &propagation, pieces: Vec::new() };
        let solution = Stepping::solve(&mut tracked, Plan::until(2.5)).unwrap();
        let fallbacks = Stepping::stats(&tracked.stepper).energy_fallbacks;
        assert!(fallbacks > 0, "no least-squares step");
        // The run is kept whole; its sensitivities stop before the first
        // least-mismatch step.
        assert!(solution.is_finished());
        let sens = propagation.into_inner().finish(solution);
        let n = sens.jacobians.len();
        assert!(n >= 2 && n < sens.solution.len(), "{n} of {}", sens.solution.len());
        match sens.error {
            Some(Error::NotDifferentiable { state, .. }) => assert_eq!(state.step as usize, n - 1),
            other => panic!("{other:?}"),
        }
        // The adjoint refuses it too.
        let e = adjoint::gradient_extended(
            least_squares(&problem),
            problem.initial(),
            0.02,
            2.5,
            &Angle,
            Checkpoints::Budget(4),
        )
        .unwrap_err();
        assert!(matches!(e, Error::NotDifferentiable { .. }), "{e}");
        eprintln!("{fallbacks} least-squares steps; sensitivities of {n} rows of {}: {e}", sens.solution.len());
    }
}
