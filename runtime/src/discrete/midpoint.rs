//! The midpoint discrete Lagrangian.
//!
//! ```text
//! A(t_k, q_k, t_{k+1}, q_{k+1}) = h · L(t_k + h/2, (q_k + q_{k+1})/2, (q_{k+1} − q_k)/h),   h = t_{k+1} − t_k
//! ```
//!
//! Source: de León & Martín de Diego, de León & Martín de Diego §3.1; Chen, Guo & Wu, Chen, Guo & Wu (finite elements)
//! eq. (2.15). Order 2. For `L = ½ vᵀMv − V(q)` it is the implicit midpoint
//! rule in `(q, p)`; it is symmetric, so its error expansion has even powers only.
//!
//! Forces use the trait's default, the same midpoint rule:
//! `F_k^− = F_k^+ = (h/2) F(t_k + h/2, (q_k + q_{k+1})/2, v̂)` (docs/theory.md §6).

use super::{DiscreteLagrangian, array, secant_velocity, secant_velocity_fixed};
use crate::system::{Lagrangian, Scalar};

/// The midpoint rule: `A = h L(t_k + h/2, (q_k+q_{k+1})/2, (q_{k+1}−q_k)/h)`. Order 2.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Midpoint;

impl DiscreteLagrangian for Midpoint {
    fn galerkin_points(&self) -> Option<([f64; 2], usize)> {
        Some(([0.5, 0.5], 1))
    }

    fn order(&self) -> u32 {
        2
    }

    fn energy_error_kappa(&self) -> Option<f64> {
        Some(0.0)
    }

    #[inline(always)]
    fn action<S, D, const N: usize>(&self, system: &S, t0: D, h: D, q0: [D; N], dq: [D; N]) -> D
    where
        S: Lagrangian<N> + ?Sized,
        D: Scalar,
    {
        let v = secant_velocity(&dq, h);
        let q_mid = array(|i| q0[i] + dq[i] * 0.5);
        system.lagrangian(t0 + h * 0.5, q_mid, v) * h
    }

    #[inline(always)]
    fn fixed_step_action<S, D, const N: usize>(&self, system: &S, t0: f64, h: f64, q0: [D; N], dq: [D; N]) -> D
    where
        S: Lagrangian<N> + ?Sized,
        D: Scalar,
    {
        let v = secant_velocity_fixed(&dq, h);
        let q_mid = array(|i| q0[i] + dq[i] * 0.5);
        system.lagrangian(D::from(t0 + h * 0.5), q_mid, v) * h
    }
}
