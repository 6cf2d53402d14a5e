//! Galerkin discrete Lagrangians of any degree and their
//! integrator (docs/theory.md §5; Chen, Guo & Wu (finite elements) §2.2–2.3).
//!
//! The step polynomial of degree `s` passes through `q_k`, `s − 1` interior
//! nodes and `q_{k+1}`; the action of the step is its Lagrangian integrated by
//! a quadrature rule. The interior nodes are unknowns of the step, solved
//! together with the discrete Euler–Lagrange equation as one Newton block of
//! size `sN`.
//!
//! | file | what |
//! | --- | --- |
//! | `quadrature.rs` | Gauss–Legendre and Gauss–Lobatto rules with any number of points; midpoint, trapezoid, Simpson |
//! | `basis.rs` | control nodes (equispaced or Gauss–Lobatto) and the Lagrange basis |
//! | `method.rs` | [`Galerkin<S, R>`]: the discrete Lagrangian, its gradient and Hessian by the chain rule; order `min(2s, quadrature order)` |
//! | `linear.rs` | Chen, Guo & Wu (finite elements) §2.2: the linear element (`s = 1`) with the potential integrated by a quadrature |
//! | `quadratic.rs` | Chen, Guo & Wu (finite elements) §2.3: the quadratic element (`s = 2`, equispaced, exact for `L = ½ q̇²`) |
//! | `linalg.rs` | static block LU with partial pivoting and a condition estimate |
//! | `collocation.rs` | Gauss rules as collocation: the step by fixed-point iteration on the velocities at the points, no Jacobian |
//! | `forces.rs` | the discrete forces `F^m` of the Lagrange–d'Alembert principle on the nodes, and their derivatives |
//! | `stepper.rs` | the Galerkin rules as a [`Method`](crate::Method) of the one [`Integrator`](crate::Integrator): the block Newton step (fixed steps, forces), tangent map |
//! | `energy.rs` | energy-preserving variable steps: the bordered `sN + 1` Newton block |
//! | `one_point.rs` | the one-point rules in `DoubleDouble`, run as degree-1 Galerkin rules with their own points |
//!
//! Everything here is written over a [`Real`](crate::Real) type `T`, `f64`
//! by default: `Galerkin::<S, S, DoubleDouble>::gauss()` builds the method
//! with nodes, weights and basis in double-double, and the
//! [`Integrator`](crate::Integrator) built on it runs the whole step (Newton
//! block, state, Kahan sums) in that type. This is how orders up to 16 are
//! verified (`tests/verification/galerkin_order_extended.rs`). The readouts that solve in
//! `f64` (`velocity`, `energy`, `last_tangent_map`) exist for `T = f64`
//! only. [`GalerkinIntegrator`] is a name for the `Integrator` with a
//! Galerkin rule, not another type.
//!
//! Energy-preserving variable steps
//! ([`IntegratorBuilder::energy_preserving`](crate::IntegratorBuilder::energy_preserving))
//! solve the step size with the nodes (`energy.rs`), for autonomous systems
//! without forces.

mod basis;
mod collocation;
mod energy;
mod forces;
mod linalg;
mod linear;
mod method;
mod one_point;
mod quadratic;
mod quadrature;
mod stepper;

pub use basis::NodeFamily;
pub(crate) use basis::{lagrange, lagrange_derivative};
pub(crate) use forces::NoJacobian;
pub use method::{Galerkin, StageIteration};
pub(crate) use method::{PointDerivatives, point_gradient};
pub(crate) use one_point::as_galerkin;
pub use quadrature::{Quadrature, QuadratureKind};
pub(crate) use quadrature::{gauss_legendre_into, gauss_lobatto_into};
pub(crate) use stepper::GALERKIN_ACCURACY_BOUND;
pub use stepper::{GalerkinBuilder, GalerkinIntegrator, LastStep, PointEvaluations, tangent_map};
pub(crate) use stepper::{GalerkinMemory, discrete_energy_of, legendre, supports_policy};
