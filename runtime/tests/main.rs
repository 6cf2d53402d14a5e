//! The runtime's integration tests: one test binary, a module per file.
//!
//! One binary instead of one per file: one link and one set of the runtime's
//! generic instantiations (the property suite's and the variable-step tests'
//! integrators overlap) instead of six, which shortens a cold
//! `cargo test --workspace`. Run one file with
//! `cargo test -p lagrangian-runtime --test integration <file>::`.
#![allow(missing_docs)]

mod auto;
mod bad_input;
mod compensated;
mod large_stack;
mod lost_orbits;
mod module_graph;
mod newton_accuracy;
mod newton_stopping;
mod properties;
mod properties_workflow;
#[cfg(feature = "serde")]
mod solution_files;
mod solve_failures;
mod variable_steps;
