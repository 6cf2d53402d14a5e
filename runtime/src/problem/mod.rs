//! One way in: a problem stated once, the method and the step policy as
//! values, one stepper and one solution for every method.
//!
//! ```text
//! Problem::new(system, t0, q0, v0)   q0, v0: [f64; N] (Problem<S, Dim<N>>) or Vec<f64> (Problem<S, Dyn>)
//!   .solve(&scheme, policy, plan) -> Solution       (the same for every Scheme and size)
//!   .stepper(&scheme, policy)     -> Stepper<S, Z>  (step, run, run_until, solve, state, energy, …)
//!   .solve_with_sensitivities(&scheme, policy, plan) -> Sensitivities<N>   (S: Parametric; Dim<N>)
//!   .gradient(&scheme, h, t_end, &loss, checkpoints) -> Gradient<N, P>     (S: Parametric; Dim<N>)
//! supports(&Combination) -> Ok | the refusal naming the combination
//! ```
//!
//! A [`Scheme`] is matched once, when the stepper is built, to the driver
//! of that method: at a compile-time size the const-generic
//! [`Integrator`](crate::Integrator) with a one-point rule, a Galerkin rule
//! or a composition, the implicit time-transformed
//! [`Adaptive`](crate::Adaptive) or the explicit
//! [`ExplicitAdaptive`](crate::ExplicitAdaptive); at a run-time size the
//! reverse-mode integrator on a tape (with a composition of its steps), its
//! implicit time transformation or its explicit splitting ([`RunTimeStepping`](crate::RunTimeStepping)).
//! Every call of the stepper is one `match` on the variant into that
//! driver. Which
//! combinations exist is said by [`supports`] alone; the capability page
//! of the documentation is generated from it.

mod composed;
mod dynamic;
mod extend;
mod scheme;
mod sensitivities;
mod statement;
mod stepper;
mod support;

pub use crate::dim::{Coordinates, Dim, Dimension, Dyn};
pub use extend::{Extended, Transformed};
pub use scheme::{GalerkinQuadrature, OnePoint, Scheme};
pub use sensitivities::FORWARD_SENSITIVITIES_MAX_N;
pub use statement::Problem;
pub use stepper::{Interpolant, Steppable, Stepper};
pub use support::{Capability, Combination, MAX_PROBLEM_N, Policy, Size, supports};
