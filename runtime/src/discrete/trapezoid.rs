//! The trapezoidal discrete Lagrangian.
//!
//! ```text
//! A(t_k, q_k, t_{k+1}, q_{k+1}) = h/2 · [ L(t_k, q_k, v̂) + L(t_{k+1}, q_{k+1}, v̂) ],   v̂ = (q_{k+1} − q_k)/h
//! ```
//!
//! Source: Chen, Guo & Wu, Chen, Guo & Wu (finite elements) §2.2 (linear element, trapezoidal
//! quadrature). Order 2. For `L = ½ vᵀMv − V(q)` with constant `M` it is the
//! Störmer–Verlet method and its update is explicit (Newton converges in one
//! iteration).

use super::{DiscreteLagrangian, array, secant_velocity, secant_velocity_fixed};
use crate::system::generalized_force;
use crate::system::{Lagrangian, Scalar};

/// The trapezoidal rule: `A = h/2 [L(t_k, q_k, v̂) + L(t_{k+1}, q_{k+1}, v̂)]`. Order 2.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Trapezoid;

impl DiscreteLagrangian for Trapezoid {
    /// For `L = ½ vᵀMv − V(t, q)`, `M` constant, the DEL
    /// `p_k − M v̂ + (h/2) f(t_k, q_k) = 0` (`f = −∇V`) gives
    /// `q_{k+1} = q_k + h M⁻¹(p_k + (h/2) f_k)` and
    /// `p_{k+1} = p_k + (h/2)(f_k + f_{k+1})`: velocity Verlet.
    const EXPLICIT_FOR_CONSTANT_MASS: bool = true;

    fn galerkin_points(&self) -> Option<([f64; 2], usize)> {
        Some(([0.0, 1.0], 1))
    }

    fn order(&self) -> u32 {
        2
    }

    fn energy_error_kappa(&self) -> Option<f64> {
        Some(0.25)
    }

    #[inline(always)]
    fn action<S, D, const N: usize>(&self, system: &S, t0: D, h: D, q0: [D; N], dq: [D; N]) -> D
    where
        S: Lagrangian<N> + ?Sized,
        D: Scalar,
    {
        let v = secant_velocity(&dq, h);
        let q1 = array(|i| q0[i] + dq[i]);
        (system.lagrangian(t0, q0, v) + system.lagrangian(t0 + h, q1, v)) * (h * 0.5)
    }

    #[inline(always)]
    fn fixed_step_action<S, D, const N: usize>(&self, system: &S, t0: f64, h: f64, q0: [D; N], dq: [D; N]) -> D
    where
        S: Lagrangian<N> + ?Sized,
        D: Scalar,
    {
        let v = secant_velocity_fixed(&dq, h);
        let q1 = array(|i| q0[i] + dq[i]);
        (system.lagrangian(D::from(t0), q0, v) + system.lagrangian(D::from(t0 + h), q1, v)) * (h * 0.5)
    }

    /// The trapezoidal rule for the forces too: `F_k^− = (h/2) F(t_k, q_k, v̂)`,
    /// `F_k^+ = (h/2) F(t_{k+1}, q_{k+1}, v̂)`.
    #[inline(always)]
    fn forces<S, D, const N: usize>(&self, system: &S, t0: D, h: D, q0: [D; N], dq: [D; N]) -> ([D; N], [D; N])
    where
        S: Lagrangian<N> + ?Sized,
        D: Scalar,
    {
        let v = secant_velocity(&dq, h);
        let q1 = array(|i| q0[i] + dq[i]);
        let half = h * 0.5;
        let (f0, f1) = (generalized_force(system, t0, q0, v), generalized_force(system, t0 + h, q1, v));
        let (minus, plus) = (array(|i| f0[i] * half), array(|i| f1[i] * half));
        (minus, plus)
    }
}
