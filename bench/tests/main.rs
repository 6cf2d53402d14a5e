//! The benchmark crate's tests: one test binary, a module per file.
//!
//! One binary instead of one per file: each of them linked the report crate
//! and instantiated its own copy of the integrators it calls, which a cold
//! `cargo test --workspace` paid five times. Run one file with
//! `cargo test -p lagrangian-bench --test integration <file>::`.

mod auto;
mod compositions;
mod constrained;
mod handwritten_agreement;
mod module_graph;
mod peer_sampling;
mod references;
mod report;
