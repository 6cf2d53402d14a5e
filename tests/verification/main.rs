//! Verification tests: fitted orders, conservation, symplecticity, reference solutions.
//!
//! One test binary for these files (each file is a module): one link and one set
//! of shared instantiations instead of one per file, which shortens a cold
//! `cargo test --workspace`. These are the files whose tests run for minutes
//! unoptimised or overflow a test thread's stack there, and the capability matrix,
//! which writes its page relative to the facade; the others in this directory are
//! the modules of `unoptimised.rs`, the test `verification` of the package
//! `lagrangian-verification-tests`, built at opt-level 0. Run one file with
//! `cargo test --test verification <file>::` (both tests are named `verification`).

// `pub` items of the test modules are reachable only inside this test crate.
#![allow(unreachable_pub)]

mod capability_matrix;
#[path = "../common/mod.rs"]
mod common;
mod galerkin_energy_steps;
mod galerkin_order;
mod galerkin_order_extended;
mod galerkin_structure;
mod noether;
mod perturbed_pendulum;
mod run_time_galerkin;
mod structure;
mod time_transformed;
mod time_transformed_splitting;
