//! Behaviour tests through the facade: errors, workflow (solutions, events, dense output, ensembles), derivatives and the macro's rewrite.
//!
//! One test binary for these files (each file is a module): one link and one set
//! of shared instantiations instead of one per file, which shortens a cold
//! `cargo test --workspace`. Run one file with `cargo test --test behaviour <file>::`. The package
//! `lagrangian-behaviour-tests` (`behaviour-tests/`) builds this binary
//! unoptimised.

// `pub` items of the test modules are reachable only inside this test crate.
#![allow(unreachable_pub)]

mod accepted_forms;
#[path = "../common/mod.rs"]
mod common;
mod composed_schemes;
mod derivatives;
mod ensemble;
mod errors;
mod events;
mod galerkin_collocation;
mod galerkin_degrees;
mod galerkin_errors;
mod guidance;
mod macro_rewrite;
mod method_matrix;
mod problem_settings;
mod run_time_energy_balance;
mod run_time_energy_steps;
mod run_time_forces;
mod run_time_galerkin_energy;
mod run_time_galerkin_errors;
mod run_time_galerkin_forces;
mod run_time_solve;
mod run_time_splitting;
mod run_time_systems;
mod run_time_time_transform;
mod solution;
