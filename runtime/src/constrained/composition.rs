//! Symmetric compositions of constrained trapezoid steps (RATTLE):
//!
//! ```text
//! Φ_h = Ψ_{γ_m h} ∘ … ∘ Ψ_{γ_1 h},   Ψ = the constrained trapezoid step,   Σ γ_i = 1,   γ_i = γ_{m+1−i}
//! ```
//!
//! RATTLE is symmetric and symplectic on the constrained cotangent bundle
//! (Hairer, Lubich & Wanner, *Geometric Numerical Integration*, §VII.1.4),
//! so a symmetric composition of it with the weights of an order-`p`
//! composition is symmetric, symplectic on the manifold and of order `p`
//! (the same book, §V.3 and §VI.6), and every sub-step holds `g` and
//! `G v` at its node. The weights are those of [`Composition`]; the
//! sub-step is the degree-1 Lobatto Galerkin step with its constraint at
//! the end node (`galerkin.rs`), which is the constrained trapezoid rule.
//! Sub-steps of negative size (Yoshida's middle weight) are steps like any
//! other: the saddle-point system does not depend on the sign of `h`.
//!
//! Forces, dissipation, moving constraints and a time-dependent `L` are
//! those of the sub-step (`galerkin.rs`), each sub-step at its own times.
//! The forced trapezoid step stays symmetric — its discrete forces
//! `(h/2) F(t_k, q_k, Δq/h)` and `(h/2) F(t_{k+1}, q_{k+1}, Δq/h)` trade
//! places under `h → −h` with the ends swapped — so the composition keeps
//! its order; measured 4.02 for Yoshida's on a damped, driven pendulum
//! (`tests/constraints/forces.rs`). The map of a forced system is not
//! symplectic.

use super::galerkin::{ConstrainedGalerkinMemory, Guess, Segment, hidden_constraint, solve_step, step_energy};
use super::{Constrained, values};
use crate::dense::{Hermite, Node};
use crate::discrete::Midpoint;
use crate::error::Error;
use crate::galerkin::{Galerkin, NodeFamily, Quadrature};
use crate::integrator::{Composition, F64Readouts, Integrator, Method, Sealed, StepPolicy, add_increment};
use crate::state::State;
use crate::symplectic::TangentMap;
use crate::system::Lagrangian;

/// What a constrained composition keeps: the last sub-step and the size of
/// the last composed step.
#[doc(hidden)]
#[derive(Clone, Debug)]
pub struct ConstrainedCompositionMemory<const N: usize, const M: usize> {
    /// The sub-step, built once (its basis is tabulated when built).
    rule: Galerkin<1, 2>,
    /// The last sub-step, its multiplier and end velocity.
    inner: ConstrainedGalerkinMemory<N, 1, M>,
    /// The size of the last composed step.
    h: Option<f64>,
    /// The change of velocity over the last sub-step divided by its size
    /// (zero before the first): the curvature of the next sub-step's guess.
    acceleration: [f64; N],
}

impl<const M: usize> Constrained<Composition, M> {
    /// The composition `composition` of constrained trapezoid (RATTLE)
    /// steps, with `M` constraints held at every sub-step's node (the
    /// sub-steps of either sign; order that of the composition):
    ///
    /// ```
    /// use lagrangian_runtime::{Composition, Constrained, Integrator, Lagrangian, Scalar};
    ///
    /// /// A pendulum as a point on a circle of radius 1.
    /// struct Pendulum;
    /// impl Lagrangian<2> for Pendulum {
    ///     const AUTONOMOUS: bool = true;
    ///     const CYCLIC: [bool; 2] = [false, false];
    ///     const CONSTRAINTS: usize = 1;
    ///     fn lagrangian<D: Scalar>(&self, _t: D, q: [D; 2], v: [D; 2]) -> D {
    ///         (v[0] * v[0] + v[1] * v[1]) * 0.5 - q[1]
    ///     }
    ///     fn constraints<D: Scalar>(&self, _t: D, q: &[D; 2], g: &mut [D]) {
    ///         g[0] = q[0] * q[0] + q[1] * q[1] - 1.0;
    ///     }
    /// }
    ///
    /// let method = Constrained::<_, 1>::composition(Composition::YOSHIDA4);
    /// let mut sim = Integrator::new(Pendulum, method, 0.05).start(0.0, [1.0, 0.0], [0.0, 0.0])?;
    /// sim.run(200, |_| {})?;
    /// let [x, y] = sim.state().q;
    /// assert!((x * x + y * y - 1.0).abs() < 1e-14);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn composition(composition: Composition) -> Self {
        Self { rule: composition }
    }
}

impl<const M: usize> Sealed for Constrained<Composition, M> {}

impl<const M: usize> Method<f64> for Constrained<Composition, M> {
    type Memory<const N: usize> = ConstrainedCompositionMemory<N, M>;

    const CONSTRAINTS: usize = M;

    fn method_order(&self) -> u32 {
        self.rule.order()
    }

    fn memory<const N: usize>(&self) -> ConstrainedCompositionMemory<N, M> {
        ConstrainedCompositionMemory {
            rule: Galerkin::new(NodeFamily::GaussLobatto, Quadrature::gauss_lobatto()),
            inner: ConstrainedGalerkinMemory::new(),
            h: None,
            acceleration: [0.0; N],
        }
    }

    fn supports<Sys: Lagrangian<N>, const N: usize>(&self, policy: &StepPolicy) -> Result<(), Error> {
        Constrained::<Midpoint, M>::new(Midpoint).supports::<Sys, N>(&StepPolicy::Fixed)?;
        // Refused as without constraints.
        self.rule.supports::<Sys, N>(policy)
    }

    fn supports_derivatives<Sys: Lagrangian<N>, const N: usize>(
        &self,
        reverse: bool,
        policy: &StepPolicy,
    ) -> Result<(), Error> {
        Constrained::<Midpoint, M>::new(Midpoint).supports_derivatives::<Sys, N>(reverse, policy)
    }

    fn legendre<Sys: Lagrangian<N>, const N: usize>(
        system: &Sys,
        t0: f64,
        q0: [f64; N],
        v0: [f64; N],
    ) -> Result<([f64; N], f64), Error> {
        <Constrained<Midpoint, M> as Method<f64>>::legendre(system, t0, q0, v0)
    }

    fn fixed_step<Sys: Lagrangian<N>, const N: usize>(
        it: &mut Integrator<Sys, Self, N>,
        h: f64,
        t1: f64,
    ) -> Result<(), Error> {
        let state = it.state;
        let memory = &mut it.memory;
        let (rule, inner) = (&memory.rule, &mut memory.inner);
        // The sub-steps run on copies; the integrator changes only when all succeeded.
        let (mut t, mut q, mut carry, mut p) = (state.t, state.q, it.carry, state.p);
        let mut v = if inner.last.is_some() { inner.velocity } else { it.v0 };
        let mut lambda = inner.lambda;
        let mut acceleration = memory.acceleration;
        let mut last_h = inner.last.map(|seg| seg.h);
        let mut last = None;
        let mut iterations = 0;
        let weights = it.method.rule.weights();
        for (i, &gamma) in weights.iter().enumerate() {
            let hs = gamma * h;
            let t_end = if i + 1 == weights.len() { t1 } else { t + hs };
            // The multiplier is an impulse: it scales with the (signed) step.
            let rho = last_h.map_or(0.0, |l| hs / l);
            // The parabola at the velocity and the last sub-step's mean
            // acceleration: an error `O(h³)` where the straight line's is
            // `O(h²)` (callgrind, `bench/constrained-instructions.sh` on a
            // build with both, double pendulum: 37 585 against 46 690
            // instructions per step of Yoshida 4 at h = 0.01, 90 046 against
            // 110 718 of Yoshida 6 and 177 122 against 214 573 of Kahan–Li 8
            // at h = 0.021). The multiplier's guess does not matter: the
            // equations are affine in it, and the first iteration's matrix is
            // the guess's own.
            let d = core::array::from_fn(|i| hs * (v[i] + 0.5 * hs * acceleration[i]));
            let guess = Guess { d: [d], lambda: lambda.map(|x| x * rho), interior: [[0.0; M]] };
            let work = &mut inner.work;
            let solved = solve_step(&it.system, rule, &it.newton, (t, hs, t_end), (&q, &p), guess, work);
            let solved = match solved {
                Ok(s) => s,
                Err(error) => {
                    it.stats.failed_steps += 1;
                    return Err(error.at(state));
                }
            };
            last = Some(Segment { t0: t, h: hs, q0: q, d: solved.d });
            (q, carry) = add_increment(it.summation, &q, &carry, &solved.d[0]);
            acceleration = core::array::from_fn(|i| (solved.velocity[i] - v[i]) / hs);
            (p, v, lambda, t, last_h) = (solved.momentum, solved.velocity, solved.lambda, t_end, Some(hs));
            iterations += solved.iterations;
        }
        it.state = State { step: state.step + 1, t: t1, q, p };
        it.carry = carry;
        it.p_carry = [0.0; N];
        (inner.last, inner.lambda, inner.velocity) = (last, lambda, v);
        (memory.h, memory.acceleration) = (Some(h), acceleration);
        it.stats.steps += 1;
        it.stats.newton_iterations += iterations as u64;
        Ok(())
    }

    fn last_step_size<const N: usize>(memory: &ConstrainedCompositionMemory<N, M>) -> Option<f64> {
        memory.h
    }

    fn discrete_energy<Sys: Lagrangian<N>, const N: usize>(it: &Integrator<Sys, Self, N>) -> f64 {
        // The discrete energy of the last sub-step (each sub-step keeps its
        // own; the constraint forces do no work).
        match &it.memory.inner.last {
            Some(seg) => step_energy(&it.system, &it.memory.rule, seg),
            None => it.energy,
        }
    }
}

impl<const M: usize> F64Readouts for Constrained<Composition, M> {
    fn velocity_guess<Sys: Lagrangian<N>, const N: usize>(it: &Integrator<Sys, Self, N>) -> [f64; N] {
        if it.memory.inner.last.is_some() { it.memory.inner.velocity } else { it.v0 }
    }

    /// Not offered yet: the tangent map of a constrained step lives on the
    /// constraint manifold's cotangent bundle.
    fn tangent_map<Sys: Lagrangian<N>, const N: usize>(_: &Integrator<Sys, Self, N>) -> Option<TangentMap<N>> {
        None
    }

    /// Zero for a system without forces or dissipation; not offered
    /// (`None`) for one with them: the impulse is the sum over all
    /// sub-steps, and the memory keeps the last sub-step only.
    fn forcing_impulse<Sys: Lagrangian<N>, const N: usize>(
        it: &Integrator<Sys, Self, N>,
        _: &(impl crate::noether::Generator<N> + ?Sized),
    ) -> Option<f64> {
        if Sys::HAS_FORCE || Sys::HAS_DISSIPATION {
            return None;
        }
        it.memory.h.map(|_| 0.0)
    }

    type Native<const N: usize> = Hermite<N>;

    fn native<Sys: Lagrangian<N>, const N: usize>(
        _: &Integrator<Sys, Self, N>,
        start: &Node<N>,
        end: &Node<N>,
    ) -> Hermite<N> {
        Hermite::cubic(start, end)
    }
}

impl<Sys: Lagrangian<N>, const N: usize, const M: usize> Integrator<Sys, Constrained<Composition, M>, N> {
    /// The constraint values `g(t_k, q_k)` at the current node.
    pub fn constraint_values(&self) -> [f64; M] {
        values::<Sys, N, M>(&self.system, self.state.t, &self.state.q)
    }

    /// The hidden constraint `G(t_k, q_k) v_k + ∂g/∂t(t_k, q_k)` at the
    /// current node (`G v` for constraints that do not depend on time), with
    /// `v_k` the velocity of the momentum `p_k`.
    pub fn constraint_velocities(&self) -> Result<[f64; M], Error> {
        hidden_constraint(&self.system, &self.state, self.velocity()?)
    }

    /// The multiplier `λ` of the last sub-step (zero before the first).
    pub fn multipliers(&self) -> [f64; M] {
        self.memory.inner.lambda
    }
}
