//! # lagrangian
//!
//! Structure-preserving integrators from a Lagrangian written as plain Rust.
//!
//! You write `L(q, v)` as ordinary `f64` code inside an `impl` block annotated
//! with [`#[lagrangian]`](macro@lagrangian). The macro rewrites it so that it can
//! be evaluated on num-dual's dual numbers and implements [`Lagrangian`] for your
//! type; the runtime then integrates it with a variational integrator: one
//! Newton solve of the discrete Euler–Lagrange equation per step, with the
//! residual, the next momentum and the Jacobian all coming from hyper-dual
//! evaluations of the step action. The result is symplectic, conserves the
//! momenta of symmetries exactly and keeps the energy error bounded over
//! arbitrarily long runs.
//!
//! ## A pendulum in ten lines
//!
//! ```
//! use lagrangian::prelude::*;
//!
//! pub struct Pendulum { pub m: f64, pub l: f64, pub g: f64 }
//!
//! #[lagrangian]
//! impl Pendulum {
//!     fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
//!         0.5 * self.m * self.l * self.l * v[0] * v[0] + self.m * self.g * self.l * q[0].cos()
//!     }
//! }
//!
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let pendulum = Pendulum { m: 1.0, l: 1.0, g: 9.81 };
//! // The midpoint rule with h = 0.01, from θ = 1 rad at rest.
//! let mut sim = Integrator::new(pendulum, Midpoint, 0.01).start(0.0, [1.0], [0.0])?;
//! let e0 = sim.energy()?;
//! sim.run(10_000, |_| {})?;
//! let state = sim.state();
//! assert!((state.t - 100.0).abs() < 1e-9);
//! // 10⁴ steps later the energy error is still O(h²) and does not drift.
//! assert!(((sim.energy()? - e0) / e0).abs() < 1e-4);
//! # Ok(()) }
//! ```
//!
//! ## One way in: a method is a value
//!
//! Every driver implements [`Stepping`]: its provided method
//! [`solve`](Stepping::solve) runs a [`Plan`] (end time, thinning, save
//! times by dense output, events) and returns the same [`Solution`] for every
//! method — the one-point rules, Galerkin rules, compositions and both
//! time-transformed drivers. Changing the method changes one value:
//!
//! ```
//! use lagrangian::prelude::*;
//!
//! #[derive(Clone)]
//! pub struct Pendulum;
//!
//! #[lagrangian]
//! impl Pendulum {
//!     fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
//!         0.5 * v[0] * v[0] + 9.81 * q[0].cos()
//!     }
//! }
//!
//! /// The first time the pendulum passes through the bottom, and the solution.
//! fn first_crossing(mut sim: impl Stepping<1> + Clone) -> Result<(f64, Solution), Box<dyn std::error::Error>> {
//!     let plan = Plan::until(5.0).every(10).event(Event::new(|_, q, _| q[0]));
//!     let sol = sim.solve(plan)?.into_result()?;
//!     Ok((sol.events[0].t, sol))
//! }
//!
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let (q0, v0) = ([1.0], [0.0]);
//! let (a, _) = first_crossing(Integrator::new(Pendulum, Midpoint, 0.001).start(0.0, q0, v0)?)?;
//! let (b, _) = first_crossing(Integrator::new(Pendulum, Galerkin::<3, 3>::gauss(), 0.05).start(0.0, q0, v0)?)?;
//! let (c, _) = first_crossing(Integrator::new(Pendulum, Composition::YOSHIDA6, 0.02).start(0.0, q0, v0)?)?;
//! let density = Curvature::new(1.0).unwrap();
//! let (d, _) = first_crossing(TimeTransformed::new(Pendulum, density).rule(Midpoint, 0.005).start(0.0, q0, v0)?)?;
//! // A quarter of the period of a 1 rad swing: K(sin ½)/√g = 0.534784 s.
//! for t in [a, b, c, d] {
//!     assert!((t - 0.534784).abs() < 1e-4, "{t}");
//! }
//! # Ok(()) }
//! ```
//!
//! ## What you can write
//!
//! The signature is `fn lagrangian(&self, [t: f64,] q: [f64; N], v: [f64; N]) -> f64`;
//! `N`, the number of degrees of freedom, is the array length. The body may use
//! `let` bindings (also `mut` with `+=` and friends), arithmetic with literals
//! on either side, fields of `self` as constants, `if`/`else`, `for` loops over
//! integer ranges, and the methods `sin cos tan asin acos atan atan2 sinh cosh
//! tanh asinh acosh atanh exp exp2 exp_m1 ln ln_1p log log2 log10 sqrt cbrt
//! powi powf abs signum recip mul_add`. Anything else is a compile error that
//! points at the offending token and says what is allowed.
//!
//! ## Using the pieces
//!
//! Every [`Lagrangian`] also gets the methods of [`DiscreteMechanics`]: the
//! momentum and energy of `L`, the partials `D1..D4` of a discrete Lagrangian,
//! the DEL residual and its Jacobian, so you can feed them to a solver of your
//! own:
//!
//! ```
//! use lagrangian::prelude::*;
//! use lagrangian::Segment;
//!
//! struct Oscillator;
//!
//! #[lagrangian]
//! impl Oscillator {
//!     fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
//!         0.5 * v[0] * v[0] - 0.5 * q[0] * q[0]
//!     }
//! }
//!
//! // The step from (t, q) = (0, 1) to (0.1, 0.995).
//! let seg = Segment { t0: 0.0, h: 0.1, q0: [1.0], dq: [-0.005] };
//! let d = Oscillator.step_derivatives(&Midpoint, &seg);
//! // ∂²A/∂q_k∂q_{k+1} = −1/h − h/4 for the midpoint rule.
//! assert!((d.d2_q0_q1[(0, 0)] - (-10.0 - 0.025)).abs() < 1e-12);
//! let parts = Oscillator.discrete_partials(&Midpoint, &seg);
//! assert!((parts.d2[0] * 0.1 - d.d_q0[0]).abs() < 1e-12);
//! ```
//!
//! ## Forces, dissipation and symmetries
//!
//! Two optional methods add non-conservative forces (docs/theory.md §6): a Rayleigh
//! dissipation function `fn dissipation(&self, q, v) -> f64`, whose force
//! `−∂R/∂v` is taken with dual numbers, and applied forces or electromotive
//! forces `fn force(&self, [t,] q, v) -> [f64; N]`. The integrator then solves
//! the discrete Lagrange–d'Alembert equations, with each discrete Lagrangian's
//! own quadrature for the forces ([`DiscreteLagrangian::forces`]), and reports
//! the discrete energy balance ([`Integrator::energy_balance`], see
//! [`forcing`]). Symmetries are declared as [`Symmetry`] values or closures
//! `ξ(q)`; their discrete momentum maps change by exactly the forcing impulse
//! of each step ([`noether`]):
//!
//! ```
//! use lagrangian::prelude::*;
//! use lagrangian::Symmetry;
//!
//! /// A series RLC circuit with a battery; the charge q is the coordinate.
//! struct Rlc { l: f64, r: f64, c: f64, e: f64 }
//!
//! #[lagrangian]
//! impl Rlc {
//!     fn lagrangian(&self, q: [f64; 1], v: [f64; 1]) -> f64 {
//!         0.5 * self.l * v[0] * v[0] - 0.5 * q[0] * q[0] / self.c
//!     }
//!     fn dissipation(&self, _q: [f64; 1], v: [f64; 1]) -> f64 {
//!         0.5 * self.r * v[0] * v[0]
//!     }
//!     fn force(&self, _q: [f64; 1], _v: [f64; 1]) -> [f64; 1] {
//!         [self.e]
//!     }
//! }
//!
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let mut sim = Integrator::new(Rlc { l: 0.5, r: 2.0, c: 0.01, e: 9.0 }, Midpoint, 1e-3).start(0.0, [0.0], [0.0])?;
//! sim.run(5_000, |s| {
//!     // E_{k+1} − E_k = W_k, the work of the battery and the resistor:
//!     // exact (to round-off) for a quadratic L and the midpoint rule.
//!     if let Some(balance) = s.energy_balance() {
//!         assert!(balance.residual().abs() < 1e-12);
//!     }
//! })?;
//! // The capacitor charges to C E.
//! assert!((sim.state().q[0] - 0.01 * 9.0).abs() < 1e-4);
//!
//! // The momentum map of q ↦ q + ε, J = p, changes by the forcing impulse
//! // of the step plus the symmetry defect: the capacitor breaks the symmetry.
//! let translation = Symmetry::translation(0).unwrap();
//! let before = sim.momentum_map(&translation);
//! sim.step()?;
//! let impulse = sim.forcing_impulse(&translation).unwrap();
//! let step = sim.last_step().unwrap();
//! let defect = lagrangian::noether::symmetry_defect(sim.system(), sim.method(), step, &translation);
//! assert!((sim.momentum_map(&translation) - before - impulse - defect).abs() < 1e-12);
//! # Ok(()) }
//! ```
//!
//! A coordinate the macro proves cyclic gives a translation symmetry
//! ([`Symmetry::cyclic`]). Variable, energy-preserving steps refuse systems
//! with forces ([`Error::Unsupported`]): their energy is not conserved.
//!
//! ## Errors, not panics
//!
//! A step that fails (Newton does not converge, the Jacobian is singular, a
//! value is not finite) returns an [`Error`] carrying the state and the
//! diagnostics, and leaves the integrator as it was, so the caller can retry
//! with another step size. `Error` is one type for every driver and every
//! system size (its state is a run-time-sized [`PhasePoint`]), so the
//! failures of systems of different sizes gather into one `Result` with `?`.

pub use lagrangian_macros::lagrangian;
// The public surface, listed: the types a user names, and the modules that
// are documented extension points. The engine's internals (`tape`, `banded`,
// `hyperdual`, `chunk`) stay in the runtime crate.
pub use lagrangian_runtime::num_dual;
pub use lagrangian_runtime::{
    Action, ActionGradient, Adaptive, AlphaBeta, Auto, Composition, Coupling, Curvature, DenseKind, Derivatives, Dim,
    Direction, DiscreteLagrangian, DiscreteMechanics, DiscretePartials, DoubleDouble, Dyn, DynLagrangian,
    EnergyFallback, Error, Estimate, Event, EventRecord, ExplicitAdaptive, ExplicitTimeTransformed,
    ExtendedStepDerivatives, F64Readouts, ForceCoupling, Galerkin, GalerkinIntegrator, Generator, Integrator,
    IntegratorBuilder, Lagrangian, LeapfrogForm, LegendreFailure, Method, Midpoint, NewtonOptions, NewtonReport, Node,
    NodeFamily, NodeView, Pattern, PhasePoint, Plan, Policy, Problem, Quadrature, RadiusPower, Real, Rows,
    RunTimeStepping, Scalar, Scheme, Segment, Separability, Solution, SolveError, Solved, State, Stats, Status,
    StepBounds, StepDensity, StepDerivatives, StepPolicy, Stepper, Stepping, Summation, Symmetry, TangentMap,
    TimeFunction, TimeTransformed, Tolerance, Trapezoid, solve_to,
};
pub use lagrangian_runtime::{Checkpoints, Gradient, Jacobian, Loss, Parametric, Sensitivities};
pub use lagrangian_runtime::{Constrained, DynConstrained};
pub use lagrangian_runtime::{
    auto, constrained, dense, derivatives, dim, discrete, double_double, ensemble, events, forcing, galerkin, guidance,
    mechanics, newton, noether, problem, sensitivity, solution, structure, symplectic, system, time_transform,
};

/// Everything a typical user needs: `use lagrangian::prelude::*;`.
pub mod prelude {
    pub use lagrangian_macros::lagrangian;
    pub use lagrangian_runtime::PhasePoint;
    pub use lagrangian_runtime::problem::{Capability, GalerkinQuadrature, OnePoint};
    pub use lagrangian_runtime::{Adaptive, Curvature, RadiusPower, StepDensity, TimeTransformed};
    pub use lagrangian_runtime::{
        AlphaBeta, DiscreteLagrangian, DiscreteMechanics, DynLagrangian, EnergyFallback, Error, F64Readouts,
        Integrator, Lagrangian, Method, Midpoint, NewtonOptions, Scalar, State, StepBounds, StepPolicy, Summation,
        Symmetry, Trapezoid,
    };
    pub use lagrangian_runtime::{Auto, Estimate, Solved, Tolerance, solve_to};
    pub use lagrangian_runtime::{Checkpoints, Loss, Parametric};
    pub use lagrangian_runtime::{Composition, ExplicitAdaptive, ExplicitTimeTransformed, LeapfrogForm, TimeFunction};
    pub use lagrangian_runtime::{Constrained, DynConstrained};
    pub use lagrangian_runtime::{Dim, Dyn, Policy, Problem, Scheme, Stepper};
    pub use lagrangian_runtime::{DoubleDouble, Galerkin, GalerkinIntegrator, NodeFamily, Quadrature, Real};
    pub use lagrangian_runtime::{Event, NodeView, Plan, Rows, RunTimeStepping, Solution, SolveError, Stepping};
}

/// Paths named by code that `#[lagrangian]` generates. Not a public API.
#[doc(hidden)]
pub mod __private {
    pub use lagrangian_runtime::sensitivity::names as parameter_names;
    pub use lagrangian_runtime::{
        Coupling, DynLagrangian, ForceCoupling, Lagrangian, Parametric, Pattern, Scalar, Separability, StepDensity,
        Symmetry,
    };
    pub use lagrangian_runtime::{chunk, hyperdual, tape};
}

/// The README's examples, compiled and run as doc tests.
#[doc = include_str!("../README.md")]
#[cfg(doctest)]
pub struct ReadmeDoctests;

/// The guide's chapters (`docs/guide/`), each compiled and run as doc tests.
#[cfg(doctest)]
pub mod guide {
    #[doc = include_str!("../docs/guide/01-first-system.md")]
    pub struct FirstSystem;
    #[doc = include_str!("../docs/guide/02-accuracy.md")]
    pub struct Accuracy;
    #[doc = include_str!("../docs/guide/03-long-runs.md")]
    pub struct LongRuns;
    #[doc = include_str!("../docs/guide/04-forces.md")]
    pub struct Forces;
    #[doc = include_str!("../docs/guide/05-variable-steps.md")]
    pub struct VariableSteps;
    #[doc = include_str!("../docs/guide/06-large-systems.md")]
    pub struct LargeSystems;
    #[doc = include_str!("../docs/guide/07-solutions.md")]
    pub struct Solutions;
    #[doc = include_str!("../docs/guide/08-ensembles.md")]
    pub struct Ensembles;
    #[doc = include_str!("../docs/guide/09-performance.md")]
    pub struct Performance;
    #[doc = include_str!("../docs/guide/10-theory.md")]
    pub struct Theory;
    #[doc = include_str!("../docs/guide/automatic.md")]
    pub struct Automatic;
    #[doc = include_str!("../docs/guide/constraints.md")]
    pub struct Constraints;
    #[doc = include_str!("../docs/guide/cluster.md")]
    pub struct Cluster;
    #[doc = include_str!("../docs/guide/one-way-in.md")]
    pub struct OneWayIn;
    #[doc = include_str!("../docs/guide/derivatives.md")]
    pub struct Derivatives;
}
