//! What the one [`Integrator`] asks of a discrete Lagrangian.
//!
//! A discrete Lagrangian is a rule for the action of one step, possibly with
//! interior unknowns: the one-point rules ([`Midpoint`](crate::Midpoint),
//! [`Trapezoid`](crate::Trapezoid), [`AlphaBeta`](crate::AlphaBeta), and any
//! user [`DiscreteLagrangian`](crate::DiscreteLagrangian)) have none, the
//! Galerkin rules ([`Galerkin`](crate::Galerkin)) have `s − 1` interior nodes.
//! The integrator owns everything the methods share — the builder and its
//! checks, the state with its Kahan compensation, the clock, the step
//! policy, [`Stats`](crate::Stats), `run`/`run_until` — and a method brings
//! only how one step is solved and read: its Newton block, its
//! energy-preserving step, the discrete energy and what it keeps of the last
//! step. One-point rules in `f64` keep their direct fast path (one hyper-dual
//! sweep of the action per Newton iteration); one-point rules in another
//! [`Real`] run as the Galerkin rule of degree 1 with the same quadrature
//! point(s), which is the same discrete Lagrangian.

use super::{Integrator, StepBounds, StepPolicy};
use crate::dense::{DenseStep, Node};
use crate::error::Error;
use crate::real::Real;
use crate::symplectic::TangentMap;
use crate::system::Lagrangian;

pub(crate) mod sealed {
    /// Only the runtime's two families implement [`Method`](super::Method):
    /// a new discrete Lagrangian is written as a
    /// [`DiscreteLagrangian`](crate::DiscreteLagrangian) or as a
    /// [`Galerkin`](crate::Galerkin) rule.
    pub trait Sealed {}
}

/// A discrete Lagrangian as the [`Integrator`] drives it, in the real type
/// `T` of the run. Implemented for every
/// [`DiscreteLagrangian`](crate::DiscreteLagrangian) (in `f64` and in
/// [`DoubleDouble`](crate::DoubleDouble)) and for every
/// [`Galerkin`](crate::Galerkin) rule (in its own real type); sealed.
///
/// The items are the integrator's internals, hidden from the docs: a user
/// only names the trait in bounds.
pub trait Method<T: Real>: Clone + core::fmt::Debug + sealed::Sealed {
    /// What the method keeps of the steps it has taken (the last step's
    /// nodes, for the predictor and the readouts).
    #[doc(hidden)]
    type Memory<const N: usize>: Clone + core::fmt::Debug;

    /// Order of the one-step map for a regular Lagrangian.
    fn method_order(&self) -> u32;

    /// The number of holonomic constraints the method holds: 0 for every
    /// method but [`Constrained`](crate::Constrained). The integrator refuses
    /// a system whose `Lagrangian::CONSTRAINTS` differs.
    #[doc(hidden)]
    const CONSTRAINTS: usize = 0;

    /// The memory before the first step.
    #[doc(hidden)]
    fn memory<const N: usize>(&self) -> Self::Memory<N>;

    /// `Err(reason)` for an unusable rule (an invalid quadrature).
    #[doc(hidden)]
    fn check(&self) -> Result<(), &'static str> {
        Ok(())
    }

    /// `Err` for a combination of system and policy the method does not
    /// support, with the reason.
    #[doc(hidden)]
    fn supports<S: Lagrangian<N>, const N: usize>(&self, policy: &StepPolicy) -> Result<(), Error<T>> {
        let _ = policy;
        Ok(())
    }

    /// Whether steps can take their derivatives in reverse mode (a tape;
    /// see [`Derivatives`](crate::Derivatives)) under `policy`; `reverse` is
    /// what the configuration chose. Only the one-point rules in `f64` have
    /// a reverse-mode step so far.
    #[doc(hidden)]
    fn supports_derivatives<S: Lagrangian<N>, const N: usize>(
        &self,
        reverse: bool,
        policy: &StepPolicy,
    ) -> Result<(), Error<T>> {
        let _ = policy;
        if reverse {
            return Err(Error::Unsupported {
                what: "reverse-mode derivatives (systems larger than `Derivatives::FORWARD_MAX_N`) with this method: only midpoint, trapezoid, α-β and compositions in `f64` have them",
            });
        }
        Ok(())
    }

    /// Whether [`Derivatives::Automatic`](crate::Derivatives::Automatic)
    /// should take reverse mode for this method, system and policy at sizes
    /// where forward mode still works (measured crossover, see
    /// [`Derivatives::REVERSE_MIN_N`](crate::Derivatives::REVERSE_MIN_N)).
    #[doc(hidden)]
    fn prefers_reverse<S: Lagrangian<N>, const N: usize>(&self, policy: &StepPolicy) -> bool {
        let _ = policy;
        false
    }

    /// The momentum `p0 = ∂L/∂v` and the energy `E_L` at the initial data,
    /// after checking that they and `L` are finite and that `∂²L/∂v²` is
    /// regular there.
    #[doc(hidden)]
    #[allow(clippy::type_complexity)]
    fn legendre<S: Lagrangian<N>, const N: usize>(
        system: &S,
        t0: T,
        q0: [T; N],
        v0: [T; N],
    ) -> Result<([T; N], T), Error<T>>;

    /// The momentum and the energy of [`legendre`](Self::legendre), with
    /// `memory` (fresh from [`memory`](Self::memory)) made ready for the
    /// first step: a method whose first step would compute again what the
    /// Legendre transform's regularity check computes (the explicit steps'
    /// `M⁻¹`) keeps it there instead. The memory is filled in place, not
    /// returned: a composition's memory of a large system is hundreds of
    /// kilobytes, and each copy of it on the way to the integrator is stack.
    #[doc(hidden)]
    fn start_memory<S: Lagrangian<N>, const N: usize>(
        &self,
        system: &S,
        t0: T,
        q0: [T; N],
        v0: [T; N],
        memory: &mut Self::Memory<N>,
    ) -> Result<([T; N], T), Error<T>> {
        let _ = memory;
        Self::legendre(system, t0, q0, v0)
    }

    /// One step of size `h` whose end node is stamped `t1`; on failure the
    /// integrator is unchanged.
    #[doc(hidden)]
    fn fixed_step<S: Lagrangian<N>, const N: usize>(
        it: &mut Integrator<S, Self, N, T>,
        h: T,
        t1: T,
    ) -> Result<(), Error<T>>
    where
        Self: Sized;

    /// One energy-preserving step (the first one included); on failure the
    /// integrator is unchanged. A method without energy-preserving steps
    /// keeps this refusal, which `supports` already gives at `start`.
    #[doc(hidden)]
    fn energy_step<S: Lagrangian<N>, const N: usize>(
        _it: &mut Integrator<S, Self, N, T>,
        _bounds: StepBounds,
    ) -> Result<(), Error<T>>
    where
        Self: Sized,
    {
        Err(Error::Unsupported { what: "energy-preserving steps with this method" })
    }

    /// Sets the energy target of energy-preserving steps from the last step
    /// (nothing to set for a method without them).
    #[doc(hidden)]
    fn reread_energy<S: Lagrangian<N>, const N: usize>(_it: &mut Integrator<S, Self, N, T>)
    where
        Self: Sized,
    {
    }

    /// The size of the last step; `None` before the first.
    #[doc(hidden)]
    fn last_step_size<const N: usize>(memory: &Self::Memory<N>) -> Option<T>;

    /// The discrete energy `E_k` of the last step; at `k = 0` the energy
    /// of the initial data.
    #[doc(hidden)]
    fn discrete_energy<S: Lagrangian<N>, const N: usize>(it: &Integrator<S, Self, N, T>) -> T
    where
        Self: Sized;
}

/// Readouts that solve in `f64` (the inverse Legendre transform, the tangent map).
pub trait F64Readouts: Method<f64> {
    /// The first guess of the velocity at the current node.
    #[doc(hidden)]
    fn velocity_guess<S: Lagrangian<N>, const N: usize>(it: &Integrator<S, Self, N, f64>) -> [f64; N]
    where
        Self: Sized;

    /// The velocity `M⁻¹ p_k` of the current node from the factored
    /// constant mass matrix that the reverse-mode explicit path keeps, when
    /// it has one (`None` otherwise: Newton then inverts the Legendre map).
    #[doc(hidden)]
    fn constant_mass_velocity<S: Lagrangian<N>, const N: usize>(_it: &Integrator<S, Self, N, f64>) -> Option<[f64; N]>
    where
        Self: Sized,
    {
        None
    }

    /// The tangent map of the last step.
    #[doc(hidden)]
    fn tangent_map<S: Lagrangian<N>, const N: usize>(it: &Integrator<S, Self, N, f64>) -> Option<TangentMap<N>>
    where
        Self: Sized;

    /// The forcing impulse of the last step on a symmetry.
    #[doc(hidden)]
    fn forcing_impulse<S: Lagrangian<N>, const N: usize>(
        it: &Integrator<S, Self, N, f64>,
        symmetry: &(impl crate::noether::Generator<N> + ?Sized),
    ) -> Option<f64>
    where
        Self: Sized;

    /// The method's own interpolant of one step, for dense output.
    #[doc(hidden)]
    type Native<const N: usize>: DenseStep<N>;

    /// The interpolant of the last step, which ran from `start` to the
    /// current node `end`.
    #[doc(hidden)]
    fn native<S: Lagrangian<N>, const N: usize>(
        it: &Integrator<S, Self, N, f64>,
        start: &Node<N>,
        end: &Node<N>,
    ) -> Self::Native<N>
    where
        Self: Sized;
}
