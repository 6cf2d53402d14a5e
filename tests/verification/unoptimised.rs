//! Verification tests that run in seconds unoptimised: fitted orders,
//! forces, compositions, dense output, compensated sums, the gradient code,
//! the sensitivities and adjoints of small systems.
//!
//! The test `verification` of the package `lagrangian-verification-tests`,
//! built at opt-level 0 (its `Cargo.toml` says why); the files are modules
//! of this binary, beside those of the facade's optimised `main.rs` in the
//! same directory. Run one file with `cargo test --test verification <file>::`.

// `pub` items of the test modules are reachable only inside this test crate.
#![allow(unreachable_pub)]

#[path = "../common/mod.rs"]
mod common;
#[path = "composed_orders.rs"]
mod composed_orders;
#[path = "compositions.rs"]
mod compositions;
#[path = "convergence.rs"]
mod convergence;
#[path = "dense_output.rs"]
mod dense_output;
#[path = "discontinuous.rs"]
mod discontinuous;
#[path = "double_double_one_point.rs"]
mod double_double_one_point;
#[path = "explicit_verlet.rs"]
mod explicit_verlet;
#[path = "forced_variable_steps.rs"]
mod forced_variable_steps;
#[path = "forces.rs"]
mod forces;
#[path = "fused_compositions.rs"]
mod fused_compositions;
#[path = "galerkin_forces.rs"]
mod galerkin_forces;
#[path = "galerkin_paper.rs"]
mod galerkin_paper;
#[path = "gradient_code.rs"]
mod gradient_code;
#[path = "gradient_fuzz.rs"]
mod gradient_fuzz;
#[path = "impulse.rs"]
mod impulse;
#[path = "sensitivities.rs"]
mod sensitivities;
#[path = "summation.rs"]
mod summation;
#[path = "time_dependent.rs"]
mod time_dependent;
