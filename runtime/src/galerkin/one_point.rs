//! The one-point rules (`Midpoint`, `Trapezoid`, `AlphaBeta`) in
//! [`DoubleDouble`]: the Galerkin rule of degree 1 (linear interpolation of
//! `q`) whose quadrature is the rule's own point(s), which is the same
//! discrete Lagrangian,
//!
//! ```text
//! A = (h/2) Σ_{j=1,2} L(t_k + c_j h, q_k + c_j dq, dq/h)
//! ```
//!
//! with `c_1 = c_2 = ½` for the midpoint rule, `(0, 1)` for the trapezoid
//! rule and `c_1 = c_2 = 1 − α` for the α-β rule
//! ([`DiscreteLagrangian::galerkin_points`]). The `f64` path of these rules
//! (`integrator/one_point.rs`) stays the direct one.

use super::stepper::{beyond_forward, has_energy_steps, no_energy_steps, refused};
use super::{Galerkin, GalerkinMemory, NodeFamily, Quadrature};
use crate::DoubleDouble;
use crate::discrete::DiscreteLagrangian;
use crate::error::Error;
use crate::integrator::{Integrator, Method, StepBounds, StepPolicy};
use crate::system::Lagrangian;

/// In [`DoubleDouble`]: the Galerkin rule of degree 1 with the same point(s)
/// ([`DiscreteLagrangian::galerkin_points`]), which is the same discrete
/// Lagrangian; its memory holds that rule.
impl<M: DiscreteLagrangian> Method<DoubleDouble> for M {
    type Memory<const N: usize> = (Galerkin<1, 2, DoubleDouble>, GalerkinMemory<N, 1, DoubleDouble>);

    fn method_order(&self) -> u32 {
        self.order()
    }

    fn memory<const N: usize>(&self) -> Self::Memory<N> {
        (as_galerkin(self), None)
    }

    fn check(&self) -> Result<(), &'static str> {
        if self.galerkin_points().is_none() {
            return Err("this discrete lagrangian does not say which galerkin rule it is \
                        (`DiscreteLagrangian::galerkin_points`), so it has no path in a real type other than f64");
        }
        as_galerkin::<M, DoubleDouble>(self).check()
    }

    fn supports<S: Lagrangian<N>, const N: usize>(&self, policy: &StepPolicy) -> Result<(), Error<DoubleDouble>> {
        super::supports_policy::<S, N, DoubleDouble>(policy)
    }

    fn legendre<S: Lagrangian<N>, const N: usize>(
        system: &S,
        t0: DoubleDouble,
        q0: [DoubleDouble; N],
        v0: [DoubleDouble; N],
    ) -> Result<([DoubleDouble; N], DoubleDouble), Error<DoubleDouble>> {
        if const { beyond_forward(N) } {
            return Err(refused());
        }
        super::legendre(system, t0, q0, v0)
    }

    fn fixed_step<S: Lagrangian<N>, const N: usize>(
        it: &mut Integrator<S, Self, N, DoubleDouble>,
        h: DoubleDouble,
        t1: DoubleDouble,
    ) -> Result<(), Error<DoubleDouble>> {
        if const { beyond_forward(N) } {
            return Err(refused());
        }
        as_galerkin_run(it, |g| g.step_nodes(h, t1))
    }

    fn energy_step<S: Lagrangian<N>, const N: usize>(
        it: &mut Integrator<S, Self, N, DoubleDouble>,
        bounds: StepBounds,
    ) -> Result<(), Error<DoubleDouble>> {
        if const { beyond_forward(N) } {
            return Err(refused());
        }
        if const { !has_energy_steps::<S, N>() } {
            return Err(no_energy_steps());
        }
        as_galerkin_run(it, |g| g.energy_step_nodes(bounds))
    }

    fn reread_energy<S: Lagrangian<N>, const N: usize>(it: &mut Integrator<S, Self, N, DoubleDouble>) {
        if const { beyond_forward(N) || !has_energy_steps::<S, N>() } {
            return;
        }
        let _ = as_galerkin_run(it, |g| {
            g.reread_node_energy();
            Ok(())
        });
    }

    fn last_step_size<const N: usize>(memory: &Self::Memory<N>) -> Option<DoubleDouble> {
        memory.1.as_ref().map(|last| last.h)
    }

    fn discrete_energy<S: Lagrangian<N>, const N: usize>(it: &Integrator<S, Self, N, DoubleDouble>) -> DoubleDouble {
        let state = (it.state.t, &it.state.q, &it.v0);
        super::discrete_energy_of(&it.system, &it.memory.0, it.memory.1.as_ref(), state)
    }
}

/// Runs `op` on the Galerkin integrator this one-point integrator is in
/// `DoubleDouble`: the same state, clock, counters and memory, the system
/// borrowed. Everything `op` changes is copied back, so a failed `op`
/// (which changes nothing but the failure count) leaves the integrator as
/// it was.
fn as_galerkin_run<S: Lagrangian<N>, M: DiscreteLagrangian, const N: usize>(
    it: &mut Integrator<S, M, N, DoubleDouble>,
    op: impl FnOnce(&mut Integrator<&S, Galerkin<1, 2, DoubleDouble>, N, DoubleDouble>) -> Result<(), Error<DoubleDouble>>,
) -> Result<(), Error<DoubleDouble>> {
    let mut g = Integrator {
        system: &it.system,
        method: it.memory.0,
        h: it.h,
        newton: it.newton,
        state: it.state,
        carry: it.carry,
        p_carry: it.p_carry,
        policy: it.policy,
        fallback: it.fallback,
        energy: it.energy,
        energy_carry: it.energy_carry,
        time_error: it.time_error,
        watched_energy: it.watched_energy,
        // Moved, not copied: it holds the Newton block's storage on the heap.
        memory: it.memory.1.take(),
        v0: it.v0,
        clock: it.clock,
        stats: it.stats,
        derivatives: it.derivatives,
        summation: it.summation,
    };
    let outcome = op(&mut g);
    let Integrator {
        h,
        state,
        carry,
        p_carry,
        energy,
        energy_carry,
        time_error,
        watched_energy,
        memory,
        clock,
        stats,
        ..
    } = g;
    it.h = h;
    it.state = state;
    it.carry = carry;
    it.p_carry = p_carry;
    it.energy = energy;
    it.energy_carry = energy_carry;
    it.time_error = time_error;
    it.watched_energy = watched_energy;
    it.memory.1 = memory;
    it.clock = clock;
    it.stats = stats;
    outcome
}

/// The Galerkin rule of degree 1 whose two quadrature points (weights ½
/// each) are the rule's own; a rule that names none gets NaN points, which
/// `check` refuses before any step.
pub(crate) fn as_galerkin<M: DiscreteLagrangian, T: crate::real::Real>(method: &M) -> Galerkin<1, 2, T> {
    let (points, exact) = method.galerkin_points().unwrap_or(([f64::NAN; 2], 0));
    Galerkin::new(NodeFamily::Equispaced, Quadrature::two_points(points.map(T::from), exact))
}
