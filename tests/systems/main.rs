//! Structure analysis, run-time-sized and large systems.
//!
//! One test binary for these files (each file is a module): one link and one set
//! of shared instantiations instead of one per file, which shortens a cold
//! `cargo test --workspace`. Run one file with `cargo test --test systems <file>::`.
//! The package `lagrangian-systems-tests` (`systems-tests/`) builds this
//! binary unoptimised; the chains run in a default thread's stack are the
//! facade's test `default_stack`, optimised.

// `pub` items of the test modules are reachable only inside this test crate.
#![allow(unreachable_pub)]

#[path = "../common/mod.rs"]
mod common;
// The FPU-β chain and its helpers, shared with `tests/default_stack/`.
pub mod chains;
mod dyn_lagrangian;
mod dynamic_systems;
mod lane_duals;
mod large_systems;
mod structure_analysis;
mod structure_fuzz;
