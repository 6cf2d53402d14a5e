//! Discrete Lagrangians: the step action `A(t_k, q_k, t_{k+1}, q_{k+1}) ≈ ∫ L dt`.
//!
//! docs/theory.md §2 and §5. The runtime works with the action `A = h · L_d` rather
//! than with `L_d`, which removes every factor `h` from the discrete
//! Euler–Lagrange and energy equations. Each method lives in its own file whose
//! documentation gives its formula, source and order.

mod alpha_beta;
mod midpoint;
mod trapezoid;

pub use alpha_beta::AlphaBeta;
pub use midpoint::Midpoint;
pub use trapezoid::Trapezoid;

use crate::system::{Lagrangian, Scalar};

/// A discrete Lagrangian, given by its step action `A(x_k, x_{k+1})`, where
/// `x = (t, q)` is an extended point.
///
/// `action` is generic over the [`Scalar`] so that one evaluation on
/// hyper-dual numbers yields the residual, the next momentum and the Newton
/// Jacobian of the one-step map (docs/theory.md §4).
pub trait DiscreteLagrangian: Copy + core::fmt::Debug {
    /// Order of the one-step map for a regular Lagrangian.
    fn order(&self) -> u32;

    /// The step action `A ≈ ∫_{t0}^{t0+h} L(t, q(t), q̇(t)) dt` of the step from
    /// `(t0, q0)` to `(t0 + h, q0 + dq)`.
    ///
    /// The step is given by its increments `h` and `dq` rather than by its end
    /// point: the secant velocity `dq/h` is then free of the cancellation in
    /// `q1 − q0`, which for a growing coordinate (an angle after many turns, the
    /// time itself) would put round-off of the size of `ulp(q)/h` into every
    /// momentum and break exact conservation laws.
    fn action<S, D, const N: usize>(&self, system: &S, t0: D, h: D, q0: [D; N], dq: [D; N]) -> D
    where
        S: Lagrangian<N> + ?Sized,
        D: Scalar;

    /// [`action`](Self::action) of a step whose times and size are fixed
    /// numbers, so that only the positions carry derivatives: what the
    /// fixed-step Newton iteration and the momentum update evaluate.
    ///
    /// The default lifts `t0` and `h` to constants of `D` and calls
    /// `action`. The rules of this crate override it with `h` and the times
    /// as plain `f64`: a dual constant costs the full product rule in every
    /// operation it enters (`dq/h`, `L·h`) and only adds zero derivative
    /// parts, so the override gives the same numbers (up to the sign of a
    /// zero derivative) for less work.
    #[inline(always)]
    fn fixed_step_action<S, D, const N: usize>(&self, system: &S, t0: f64, h: f64, q0: [D; N], dq: [D; N]) -> D
    where
        S: Lagrangian<N> + ?Sized,
        D: Scalar,
    {
        self.action(system, D::from(t0), D::from(h), q0, dq)
    }

    /// The constant `κ` of the leading energy error of one step,
    /// `Ê(h) − H ≈ a₂ h²` with `a₂ = [(1 − 12κ) vᵀL_qq v − aᵀL_vv a] / 8`
    /// (`a` the acceleration), for the second-order one-point rules: 0 for
    /// the midpoint rule, ¼ for the trapezoid rule (derived in the theory
    /// notes on energy steps). `None` where no such constant applies (the
    /// first-order α-β rules); the default.
    fn energy_error_kappa(&self) -> Option<f64> {
        None
    }

    /// `true` when, for a Lagrangian `L = ½ vᵀMv − V(t, q)` with a constant
    /// mass matrix (`Lagrangian::SEPARABILITY` proven by the macro) and no
    /// forces, the DEL of this rule is explicit: the integrator then takes
    /// the step without Newton. `true` for [`Trapezoid`], which there is
    /// Störmer–Verlet in its variational form; `false` by default.
    const EXPLICIT_FOR_CONSTANT_MASS: bool = false;

    /// The two quadrature points `(c_1, c_2)` (weights ½ each) and the
    /// degree to which they integrate exactly, for which this rule is the
    /// Galerkin rule of degree 1 (linear interpolation of `q`):
    /// `A = (h/2) Σ_j L(t_k + c_j h, q_k + c_j dq, dq/h)`. The integrator
    /// runs the rule that way in a real type other than `f64`
    /// ([`DoubleDouble`](crate::DoubleDouble)). `None` (the default) for a
    /// rule that is not of that form; it is then refused in such a type.
    fn galerkin_points(&self) -> Option<([f64; 2], usize)> {
        None
    }

    /// The discrete forces `(F_k^−, F_k^+)` of the step from `(t0, q0)` to
    /// `(t0 + h, q0 + dq)`: `F_k^−·δq_k + F_k^+·δq_{k+1}` approximates the
    /// virtual work `∫ F·δq dt` of the generalised force
    /// [`generalized_force`](crate::system::generalized_force) `F = Q − ∂R/∂v`
    /// (docs/theory.md §6, discrete Lagrange–d'Alembert).
    ///
    /// Each method evaluates `F` with its own quadrature, at the secant
    /// velocity `dq/h`, and shares each quadrature point's impulse between the
    /// two nodes as the linear interpolant of `δq` does. The default is the
    /// midpoint rule, `F_k^− = F_k^+ = (h/2) F(t0 + h/2, q0 + dq/2, dq/h)`,
    /// which is of order 2; a discrete Lagrangian of higher order should
    /// override it with its own quadrature. Generic over the [`Scalar`], so
    /// the Newton Jacobian gets `∂F_k^−/∂q_{k+1}` from the same dual seeding
    /// as the action.
    #[inline(always)]
    fn forces<S, D, const N: usize>(&self, system: &S, t0: D, h: D, q0: [D; N], dq: [D; N]) -> ([D; N], [D; N])
    where
        S: Lagrangian<N> + ?Sized,
        D: Scalar,
    {
        let v = secant_velocity(&dq, h);
        let q_mid = array(|i| q0[i] + dq[i] * 0.5);
        one_point(system, (t0 + h * 0.5, q_mid, v), h, 0.5)
    }
}

/// `dq / h`, the constant velocity of the linear interpolant.
#[inline(always)]
pub(crate) fn secant_velocity<D: Scalar, const N: usize>(dq: &[D; N], h: D) -> [D; N] {
    let inv_h = h.recip();
    array(|i| dq[i] * inv_h)
}

/// [`secant_velocity`] for a step size that carries no derivative.
#[inline(always)]
pub(crate) fn secant_velocity_fixed<D: Scalar, const N: usize>(dq: &[D; N], h: f64) -> [D; N] {
    let inv_h = h.recip();
    array(|i| dq[i] * inv_h)
}

/// `[f(0), …, f(N−1)]` by a plain loop. `core::array::from_fn` and
/// `array::map` build arrays of large elements (the array hyper-duals of
/// `crate::hyperdual`) through an out-of-line closure and `memcpy`; this
/// measured a fifth of a double-pendulum step.
#[inline(always)]
pub(crate) fn array<D: Scalar, const N: usize>(f: impl Fn(usize) -> D) -> [D; N] {
    let mut out = [D::zero(); N];
    for (i, x) in out.iter_mut().enumerate() {
        *x = f(i);
    }
    out
}

/// The discrete forces of the quadrature rule that evaluates `F` at one point
/// `(t, q, v)` with weight `h` and shares the impulse between the nodes as
/// the linear interpolant of `δq` does there: `α h F` on `q_k` and `β h F` on
/// `q_{k+1}`, `α + β = 1`.
#[inline(always)]
pub(crate) fn one_point<S, D, const N: usize>(
    system: &S,
    (t, q, v): (D, [D; N], [D; N]),
    h: D,
    alpha: f64,
) -> ([D; N], [D; N])
where
    S: Lagrangian<N> + ?Sized,
    D: Scalar,
{
    let f = crate::system::generalized_force(system, t, q, v);
    let minus = array(|i| f[i] * h * alpha);
    let plus = array(|i| f[i] * h * (1.0 - alpha));
    (minus, plus)
}
