//! The runtime's long-running integration tests: one test binary, a module
//! per file, optimised with the rest of the test profile.
//!
//! One binary instead of one per file: one link and one set of the runtime's
//! generic instantiations (the property suite's and the variable-step tests'
//! integrators overlap) instead of several, which shortens a cold
//! `cargo test --workspace`. The short ones (`tests/behaviour/`) are the test
//! `behaviour` of the package `lagrangian-runtime-behaviour-tests`, built
//! unoptimised; these run ten to fifty times longer unoptimised, and
//! `large_stack` measures what fits a default stack with optimised frames.
//! Run one file with
//! `cargo test -p lagrangian-runtime --test integration <file>::`.
#![allow(missing_docs)]

mod compensated;
mod large_stack;
mod module_graph;
mod properties;
mod properties_workflow;
mod variable_steps;
