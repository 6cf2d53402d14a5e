//! The quadratic element of Chen, Guo & Wu (finite elements) §2.3: `s = 2`, control nodes
//! `t_k, t_{k+½}, t_{k+1}` (equispaced), the integral taken by a quadrature.
//!
//! ```text
//! A(q_k, q_{k+½}, q_{k+1}) = h Σ_j b_j L(t_k + c_j h, q_h(c_j), q_h'(c_j)/h)
//! q_h(τ) = (2τ − 1)(τ − 1) q_k + 4τ(1 − τ) q_{k+½} + τ(2τ − 1) q_{k+1}        (Chen, Guo & Wu (finite elements) (2.29)–(2.33))
//! ```
//!
//! The interior node is fixed by `∂A/∂q_{k+½} = 0` (2.38). For `L = ½ q̇²`
//! the 2-point Gauss rule integrates exactly (degree 2), and the DEL and the
//! interior equation are the stencils (2.49)–(2.50), in the A-form of
//! docs/theory.md §2 (the paper divides once more by `h`):
//!
//! ```text
//! ∂A(x_{k−1}, x_k)/∂q_k + ∂A(x_k, x_{k+1})/∂q_k = (q_{k−1} − 8 q_{k−½} + 14 q_k − 8 q_{k+½} + q_{k+1}) / (3h)
//! ∂A/∂q_{k+½} = (8/(3h)) (2 q_{k+½} − q_k − q_{k+1})
//! ```
//!
//! Order 4 with 2 Gauss points (order `min(2s, 2r)`), with the L² bound
//! (2.53) of order `h³` on the interpolant between the nodes.

use super::basis::NodeFamily;
use super::method::Galerkin;
use super::quadrature::Quadrature;

impl<const R: usize> Galerkin<2, R> {
    /// The quadratic element (equispaced nodes `0, ½, 1`) with the given quadrature.
    pub fn quadratic_with(quadrature: Quadrature<R>) -> Self {
        Self::new(NodeFamily::Equispaced, quadrature)
    }
}

impl Galerkin<2, 2> {
    /// The quadratic element of Chen, Guo & Wu (finite elements) §2.3 with 2 Gauss points: exact
    /// for the kinetic term, order 4.
    pub fn quadratic() -> Self {
        Self::quadratic_with(Quadrature::gauss_legendre())
    }
}
