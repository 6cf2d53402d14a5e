//! The linear element of Chen, Guo & Wu (finite elements) §2.2: `s = 1`, the potential integrated
//! along the segment by a quadrature.
//!
//! ```text
//! A(q_k, q_{k+1}) = h Σ_j b_j L(t_k + c_j h, (1 − c_j) q_k + c_j q_{k+1}, (q_{k+1} − q_k)/h)
//! ```
//!
//! For `L = ½ q̇² − V(q)` this is Chen, Guo & Wu (finite elements) (2.23)–(2.24),
//! `L_d = ½ ((q_{k+1} − q_k)/h)² − F(q_k, q_{k+1})` with
//! `F = (1/h) ∫ V(linear interpolant) dt` replaced by the quadrature: the
//! velocity is constant on the segment, so the kinetic term is exact with any
//! rule. No interior nodes: the step is the plain DEL.
//!
//! * midpoint rule → [`Midpoint`](crate::Midpoint), Chen, Guo & Wu (finite elements) (2.15)–(2.16); order 2;
//! * trapezoid rule → [`Trapezoid`](crate::Trapezoid) (Störmer–Verlet for
//!   separable `L`); order 2;
//! * Simpson's rule → a new member, order 2 (the linear interpolant limits it);
//! * Gauss with many points → `F` integrated to round-off, the paper's exact
//!   element; order 2, with the L² error bound (2.28) of order `h²`.

use super::basis::NodeFamily;
use super::method::Galerkin;
use super::quadrature::Quadrature;

impl<const R: usize> Galerkin<1, R> {
    /// The linear element with the given quadrature (Chen, Guo & Wu (finite elements) §2.2). Order 2.
    pub fn linear(quadrature: Quadrature<R>) -> Self {
        Self::new(NodeFamily::Equispaced, quadrature)
    }
}

impl Galerkin<1, 1> {
    /// The linear element with the midpoint rule: the same map as [`Midpoint`](crate::Midpoint).
    pub fn linear_midpoint() -> Self {
        Self::linear(Quadrature::midpoint())
    }
}

impl Galerkin<1, 2> {
    /// The linear element with the trapezoid rule: the same map as [`Trapezoid`](crate::Trapezoid).
    pub fn linear_trapezoid() -> Self {
        Self::linear(Quadrature::trapezoid())
    }
}

impl Galerkin<1, 3> {
    /// The linear element with Simpson's rule.
    pub fn linear_simpson() -> Self {
        Self::linear(Quadrature::simpson())
    }
}
