//! One way in: a problem stated once, the method and the step policy as
//! values, one stepper and one solution for every method.
//!
//! ```text
//! Problem::new(system, t0, q0, v0)          DynProblem::new(system, t0, q0, v0)   (run-time size)
//!   .solve(&scheme, policy, plan) -> Solution       (the same for every Scheme)
//!   .stepper(&scheme, policy)     -> Stepper<S, N>     (step, run, run_until, solve, state, energy, …)
//!   .solve_with_sensitivities(&scheme, policy, plan) -> Sensitivities<N>   (S: Parametric)
//!   .gradient(&scheme, h, t_end, &loss, checkpoints) -> Gradient<N, P>     (S: Parametric)
//! supports(&Combination) -> Ok | the refusal naming the combination
//! ```
//!
//! A [`Scheme`] is matched once, when the stepper is built, to the
//! const-generic driver of that method ([`Integrator`](crate::Integrator)
//! with a one-point rule, a Galerkin rule or a composition; the implicit
//! time-transformed [`Adaptive`](crate::Adaptive); the explicit
//! [`ExplicitAdaptive`](crate::ExplicitAdaptive)), and every call of the
//! stepper is one `match` on the variant into that driver. Which
//! combinations exist is said by [`supports`] alone; the capability page
//! of the documentation is generated from it.

mod dynamic;
mod extend;
mod scheme;
mod sensitivities;
mod statement;
mod stepper;
mod support;

pub use crate::dim::Dim;
pub use dynamic::{DynProblem, DynStepper};
pub use extend::{Extended, Transformed};
pub use scheme::{GalerkinQuadrature, OnePoint, Scheme};
pub use sensitivities::FORWARD_SENSITIVITIES_MAX_N;
pub use statement::Problem;
pub use stepper::{Interpolant, Stepper};
pub use support::{Capability, Combination, MAX_PROBLEM_N, Policy, Size, supports};
