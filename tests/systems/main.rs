//! Structure analysis, run-time-sized and large systems.
//!
//! One test binary for these files (each file is a module): one link and one set
//! of shared instantiations instead of one per file, which shortens a cold
//! `cargo test --workspace`. Run one file with `cargo test --test systems <file>::`.

// `pub` items of the test modules are reachable only inside this test crate.
#![allow(unreachable_pub)]

#[path = "../common/mod.rs"]
mod common;
mod dyn_lagrangian;
mod dynamic_systems;
mod lane_duals;
mod large_systems;
mod structure_analysis;
mod structure_fuzz;
