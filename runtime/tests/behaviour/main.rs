//! The runtime's short integration tests: bad input, failed solves, the
//! automatic solve's refusals, Newton's stopping and accuracy, solution
//! files. One test binary, a module per file, built unoptimised by the
//! package `lagrangian-runtime-behaviour-tests` (its `Cargo.toml` says
//! why). Run one file with
//! `cargo test -p lagrangian-runtime-behaviour-tests --test behaviour <file>::`.
#![allow(missing_docs)]

mod auto;
mod bad_input;
mod lost_orbits;
mod newton_accuracy;
mod newton_stopping;
mod solution_files;
mod solve_failures;
