//! Derivatives of the computed trajectory with respect to the parameters
//! `θ` of the system and the initial data `(q0, v0)` (docs/theory.md §11).
//!
//! A fixed step is the map `x_{k+1} = Φ(x_k, θ)`, `x = (q, p)`, defined by
//! the discrete Euler–Lagrange (and Lagrange–d'Alembert) equations of a
//! Galerkin step (a one-point rule is the one of degree 1 with its own
//! points; a composition is the product of its sub-steps). Its Jacobians
//! `Φ_x`, `Φ_θ` follow from the implicit function theorem, the interior
//! nodes of a Galerkin step eliminated with them, with the derivatives of
//! the step's equations from nested dual numbers ([`linearisation`]). Forward sensitivities ([`forward`]) propagate
//! `S_{k+1} = Φ_x S_k + Φ_θ`; the discrete adjoint ([`adjoint`]) runs
//! `λ_k = ∂ℓ_k/∂x_k + Φ_xᵀ λ_{k+1}` backwards and sums `Φ_θᵀ λ_{k+1}`, the
//! exact gradient of the computed loss, with checkpoints so that memory is
//! `O(checkpoints + segment)`, and forms the products `Φ_xᵀ λ`, `Φ_θᵀ λ`
//! without `Φ_x` (`pullback.rs`: one transposed solve with the step's
//! Newton matrix and second derivatives contracted with vectors). Both
//! differentiate the same equations of each step, so they agree to
//! round-off; the pairing `λ_kᵀ S_k` of the two is conserved by a
//! symplectic step.
//!
//! A step of the implicit time transformation is a fixed step of the
//! extended system in `s`; [`transformed`] linearises it in the extended
//! phase `(q, t, p, p_t)`, so the node times have derivatives too, with the
//! driver's constant `c` and the landing step on `t_end` differentiated.
//! A step of the explicit time-transformed splitting is an explicit map of
//! the same extended phase, the product of its drifts and kicks; `split.rs`
//! linearises it with dual numbers and hands the same linearisation to the
//! same propagation and reverse sweep.
//!
//! An energy-preserving step of a one-point rule is, in the same way, a
//! fixed step of size 1 of the parametrised motion `t' L(t, q, q'/t')`,
//! whose momentum is `(p, −E)`; `energy.rs` linearises it in the extended
//! phase `(q, t, p, −E)` with the same dense Jacobians, so the step size
//! the energy equation fixes is differentiated and the node times move
//! with the inputs. An energy-balance step of a forced system is that step
//! with the extended force `(t' F, −F·q')`, whose time component is the
//! discrete work in the energy equation. An energy-preserving Galerkin step gives `t` degree 1
//! where `q` has degree `s`, so it is not such a Galerkin step of the
//! parametrised motion; `galerkin_energy.rs` linearises the bordered system
//! in `(interior nodes, end node, h)` that the stepper solves, in the same
//! extended phase.
//!
//! The entry points are [`Problem::solve_with_sensitivities`] and
//! [`Problem::gradient`](crate::Problem::gradient); which combinations
//! they take is said by [`supports`](crate::problem::supports) with
//! [`Capability::Sensitivities`](crate::problem::Capability::Sensitivities).
//!
//! [`Problem::solve_with_sensitivities`]: crate::Problem::solve_with_sensitivities

pub mod adjoint;
pub(crate) mod energy;
#[cfg(test)]
pub(crate) mod fixtures;
pub mod forward;
pub(crate) mod galerkin_energy;
pub mod linearisation;
#[doc(hidden)]
pub mod names;
mod parametric;
mod pullback;
pub(crate) mod split;
#[doc(hidden)]
pub mod transformed;

pub use adjoint::{Checkpoints, Gradient, Loss};

pub use forward::{Jacobian, Sensitivities};
pub use parametric::Parametric;
