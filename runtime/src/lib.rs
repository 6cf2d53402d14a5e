//! Runtime of [`lagrangian`](https://docs.rs/lagrangian): discrete Lagrangians,
//! hyper-dual derivatives of the step action and the Newton stepper.
//!
//! Most users depend on the facade crate `lagrangian` and never name this
//! crate; it is separate so that the proc-macro crate and the numerics can be
//! built and tested apart. The runtime knows a user's system only through the
//! [`Lagrangian`] trait.

pub mod auto;
pub mod banded;
#[doc(hidden)]
pub mod chunk;
pub mod constrained;
pub mod dense;
pub mod derivatives;
pub mod dim;
pub mod discrete;
pub mod double_double;
pub mod ensemble;
mod error;
pub mod events;
pub mod forcing;
pub mod galerkin;
pub mod guidance;
pub mod hyperdual;
mod integrator;
pub mod mechanics;
pub mod newton;
pub mod noether;
pub mod problem;
mod real;
mod root;
pub mod sensitivity;
#[cfg(feature = "serde")]
mod serde_arrays;
pub mod solution;
mod state;
mod stepping;
pub mod structure;
mod symmetry;
pub mod symplectic;
pub mod system;
pub mod tape;
pub mod time_transform;

pub use auto::{Auto, Estimate, Solved, Tolerance, solve_to};
pub use constrained::Constrained;
pub use constrained::dynamic::DynConstrained;
pub use dense::{Node, NodeView};
pub use derivatives::{ActionGradient, ExtendedStepDerivatives, Segment, StepDerivatives};
pub use dim::{Dim, Dyn};
pub use discrete::{AlphaBeta, DiscreteLagrangian, Midpoint, Trapezoid};
pub use double_double::DoubleDouble;
pub use error::Error;
pub use events::{Action, Direction, Event, EventRecord};
pub use galerkin::{Galerkin, GalerkinIntegrator, NodeFamily, Quadrature};
pub use integrator::{
    Composition, Derivatives, EnergyFallback, F64Readouts, Integrator, IntegratorBuilder, Method, Stats, StepBounds,
    StepPolicy, Summation,
};
// The run-time-sized driver without the dispatch of `Stepper<S, Dyn>`:
// users go through `Problem`/`Stepper`; the bench measures the driver on
// its own (and under `Summation::Plain`, which `Problem` does not offer)
// against the stepper, and tests of the driver's internals (summation,
// energy fallback, rules of one's own) name it.
#[doc(hidden)]
pub use integrator::{CompositionMemory, OnePointMemory};
#[doc(hidden)]
pub use integrator::{DynIntegrator, DynIntegratorBuilder, DynMethod};
pub use mechanics::{DiscreteMechanics, DiscretePartials, LegendreFailure};
pub use newton::{NewtonOptions, NewtonReport};
pub use noether::{Generator, Symmetry};
pub use num_dual;
pub use problem::{Policy, Problem, Scheme, Stepper};
pub use real::Real;
pub use sensitivity::{Checkpoints, Gradient, Jacobian, Loss, Parametric, Sensitivities};
pub use solution::{DenseKind, Plan, RowIter, Rows, RunTimeStepping, Solution, SolveError, Status, Stepping};
pub use state::{PhasePoint, State};
pub use structure::{Coupling, ForceCoupling, Pattern, Separability};
pub use symplectic::TangentMap;
pub use system::{DynLagrangian, Lagrangian, Scalar};
pub use time_transform::{Adaptive, Curvature, RadiusPower, StepDensity, TimeTransformed};
pub use time_transform::{ExplicitAdaptive, ExplicitTimeTransformed, LeapfrogForm, TimeFunction};
