//! Verification tests: fitted orders, conservation, symplecticity, reference solutions.
//!
//! One test binary for these files (each file is a module): one link and one set
//! of shared instantiations instead of one per file, which shortens a cold
//! `cargo test --workspace`. Run one file with `cargo test --test verification <file>::`.

// `pub` items of the test modules are reachable only inside this test crate.
#![allow(unreachable_pub)]

mod capability_matrix;
#[path = "../common/mod.rs"]
mod common;
mod compositions;
mod convergence;
mod dense_output;
mod discontinuous;
mod double_double_one_point;
mod explicit_verlet;
mod forced_variable_steps;
mod forces;
mod fused_compositions;
mod galerkin_energy_steps;
mod galerkin_forces;
mod galerkin_order;
mod galerkin_order_extended;
mod galerkin_paper;
mod galerkin_structure;
mod gradient_code;
mod gradient_fuzz;
mod impulse;
mod noether;
mod perturbed_pendulum;
mod sensitivities;
mod structure;
mod summation;
mod time_dependent;
mod time_transformed;
mod time_transformed_splitting;
