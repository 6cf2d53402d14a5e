//! The main job of the `lagrangian` workspace: a work–precision and stress
//! report of the project's variational integrators against the methods a user
//! would otherwise reach for (two DOP853 implementations, an adaptive
//! Gauss–Legendre IRK, hand-written Störmer–Verlet, Yoshida 6 and Kahan–Li 8
//! compositions), on problems with checked reference solutions.
//!
//! `cargo run --release -p lagrangian-bench` writes `target/report/`; see
//! `--help` for the options and [`report`] for the JSON schema.

pub mod calibrate;
pub mod cartesian;
pub mod chain;
pub mod clock;
pub mod compositions;
pub mod constrained;
mod constrained_peers;
pub mod exact;
pub mod handwritten;
pub mod integrate;
mod invariants;
pub mod methods;
pub mod output;
mod peers;
pub mod problem;
pub mod problems;
pub mod readme;
pub mod report;
pub mod run;
pub mod step_cost;
pub mod suite;
