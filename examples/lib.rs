//! The examples of the `lagrangian` crate live in this package (see
//! `Cargo.toml`); run one with `cargo run --release --example NAME` from the
//! repository root. The library is empty: the plotting support is included
//! by each example from `support/`.
