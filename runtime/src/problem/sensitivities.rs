//! The entry points of the derivatives of a run
//! ([`crate::sensitivity`]): forward sensitivities with the solution, and
//! the adjoint gradient of a loss.

use super::extend::{Dim, Extended};
use super::scheme::Scheme;
use super::statement::Problem;
use super::support::{Capability, Policy};
use crate::error::Error;
use crate::sensitivity::Parametric;
use crate::sensitivity::adjoint::{self, Checkpoints, Gradient, Loss};
use crate::sensitivity::forward::{Propagation, Sensitivities};
use crate::sensitivity::linearisation::Rule;
use crate::solution::{Plan, SolveError};
use crate::state::State;
use crate::system::Lagrangian;

/// Why a discontinuous Lagrangian has no sensitivities.
const DISCONTINUOUS: &str =
    "sensitivities of a discontinuous lagrangian: the step is not differentiable where the lagrangian jumps";

impl<S: Lagrangian<N> + Clone, const N: usize> Problem<S, N>
where
    Dim<N>: Extended<N>,
{
    /// The rule of `scheme` when the combination has sensitivities;
    /// otherwise the refusal of [`supports`](super::supports) (or of a
    /// discontinuous Lagrangian).
    fn differentiable(&self, scheme: &Scheme, policy: Policy) -> Result<Rule, Error<N>> {
        self.supports(scheme, policy, Capability::Sensitivities)?;
        if S::DISCONTINUOUS {
            return Err(Error::Unsupported { what: DISCONTINUOUS });
        }
        match scheme {
            Scheme::OnePoint(rule) => Ok(Rule::of(rule)),
            // `supports` accepts the one-point rules only.
            _ => Err(Error::Unsupported { what: "sensitivities of this scheme" }),
        }
    }

    /// Solves as [`solve`](Self::solve) does and returns, with the solution,
    /// the derivatives `∂(q, p)/∂(q_0, v_0, θ)` of each of its rows
    /// ([`Sensitivities`]), propagated with the linearisation of each step
    /// (no finite differences).
    ///
    /// The combinations are those [`supports`](super::supports) accepts with
    /// [`Capability::Sensitivities`]: fixed steps of the one-point rules.
    /// Rows between nodes (save times, events) are refused
    /// ([`SolveError::InvalidPlan`]); an observer of the plan is still
    /// called.
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
        mut plan: Plan<'_, N>,
    ) -> Result<Sensitivities<N>, SolveError<N>>
    where
        S: Parametric<N, P>,
    {
        let policy = policy.into();
        let rule = self.differentiable(scheme, policy)?;
        if plan.interpolates() {
            return Err(SolveError::InvalidPlan {
                reason: "sensitivities are computed at the nodes: a plan with save times or events has rows between them",
            });
        }
        let mut stepper = self.stepper(scheme, policy)?;
        let propagation =
            std::cell::RefCell::new(Propagation::new(self.system(), rule, self.initial(), plan.kept_every()));
        let mut theirs = plan.take_observer();
        let mut k = 0u64;
        let plan = plan.observe_every(1, |node| {
            propagation.borrow_mut().node(State { step: k, t: node.t, q: node.q, p: node.p });
            if let Some((n, observe)) = theirs.as_mut()
                && k.is_multiple_of(*n as u64)
            {
                observe(node);
            }
            k += 1;
        });
        let solution = stepper.solve(plan)?;
        Ok(propagation.into_inner().finish(solution))
    }

    /// The exact gradient of `loss` along the run from the initial data to
    /// `t_end` (the last step shortened to land on it, as
    /// [`Plan::until`] does) with respect to `q_0`, `v_0` and the
    /// parameters: the discrete adjoint, with a copy of the stepper kept as
    /// `checkpoints` says. Memory is the copies plus one segment of nodes.
    ///
    /// Errors: the refusal of [`supports`](super::supports) for a
    /// combination without sensitivities, [`Error::InvalidSetting`] for a
    /// checkpoint budget of zero, [`Error::NonFiniteLoss`] where the loss or
    /// its gradient is not finite, and the errors of the steps.
    pub fn gradient<L: Loss<N, P>, const P: usize>(
        &self,
        scheme: &Scheme,
        h: f64,
        t_end: f64,
        loss: &L,
        checkpoints: Checkpoints,
    ) -> Result<Gradient<N, P>, Error<N>>
    where
        S: Parametric<N, P>,
    {
        let policy = Policy::fixed(h);
        let rule = self.differentiable(scheme, policy)?;
        let stepper = self.stepper(scheme, policy)?;
        adjoint::gradient(stepper, rule, self.initial(), h, t_end, loss, checkpoints)
    }
}
