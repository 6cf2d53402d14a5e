//! Time-transformed (Sundman–Poincaré) adaptive steps that keep the
//! structure: a fixed step in a new independent variable `s` with
//! `dt/ds = g(t, q)` is an adaptive step in `t`, and a variational method in
//! `s` stays symplectic (docs/time-transformation.md has the derivation).
//!
//! The system `L(t, q, v)` with `N` degrees of freedom becomes a system in
//! `s` with `M = N + 1` coordinates `x = (q, t)` and the Lagrangian
//!
//! ```text
//! L̃(x, x') = t' L(t, q, q'/t') + (t' − g(t, q))² / (2 c g(t, q)),     x' = dx/ds
//! ```
//!
//! the Legendre dual of `K = g (H + p_t) + ½ c g (H + p_t)²`, which has the
//! same flow as Poincaré's `g (H + p_t)` on its zero level. Its momenta are
//! the physical `p = ∂L/∂v` and `p_t = −E + u` with `u = (t'/g − 1)/c`, which
//! the initial data `t' = g` makes zero. `L̃` is regular where `L` is (the
//! `c` term makes `t'` an ordinary velocity), so every discrete Lagrangian of
//! the runtime integrates it unchanged: [`TimeTransformed`] implements
//! [`Lagrangian<M>`](crate::Lagrangian), and the map in `s` is symplectic in
//! `(q, t, p, p_t)`, conserves `p_t` (hence the energy, up to a bounded `u`)
//! for an autonomous `L` and a `g` without `t`, and conserves the momentum
//! of every symmetry that `L` and `g` share. Time-dependent `L` and forces
//! (Lagrange–d'Alembert in `s`: `t' F` on `q` and `−F·q'` on `t`) work too.
//!
//! [`Adaptive`] drives any integrator of the adapter ([`Integrator`](crate::Integrator) with a
//! one-point or Galerkin rule, in `f64` or
//! [`DoubleDouble`](crate::DoubleDouble): the type of the step `σ` sets
//! the run's), reports `t`, `q`, `p`
//! and the energy in physical time, lands on requested times, and refuses a
//! step density that is not positive and finite, or steps that stop
//! advancing time, with typed errors that keep the state. The monitor can
//! be a type of this module or the system's own `fn step_density` in its
//! `#[lagrangian]` block ([`TimeTransformed::with_own_density`]).
//!
//! For separable systems `½ vᵀMv − V(t, q)` with constant `M`,
//! [`ExplicitTimeTransformed`] is an explicit alternative: a splitting of the
//! time-transformed Hamiltonian `f(T + p_t + c) − f(c − V)` (the logarithmic
//! Hamiltonian method and its power-law relatives, with compositions up to
//! order 8), symplectic in the same extended phase space and without Newton.

mod adaptive;
mod builder;
mod density;
mod dynamic;
mod dynamic_splitting;
mod extended;
mod splitting;
mod stepper;

pub use crate::error::Argument;

pub use adaptive::Adaptive;
pub(crate) use builder::default_penalty;
pub use builder::{DEFAULT_RTOL, TimeTransformedBuilder};
pub use density::{Curvature, RadiusPower, StepDensity};
pub(crate) use dynamic::{RuleInS, RunTimeAdaptive};
pub(crate) use dynamic_splitting::RunTimeSplitting;
pub use extended::TimeTransformed;
pub(crate) use extended::{extended_force, extended_lagrangian, homogeneous, split};
pub use splitting::{
    ExplicitAdaptive, ExplicitTimeTransformed, ExtendedPoint, LeapfrogForm, SplittingStats, TimeFunction,
};
pub(crate) use splitting::{Flow, gravitating_start, kinetic_energy, shift_with_margin, square, stages};
pub use stepper::{Rule, SMethod, SStepper};
