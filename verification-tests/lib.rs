//! The facade's verification tests that run in seconds unoptimised
//! (`tests/verification/unoptimised.rs`), built unoptimised (see `Cargo.toml`);
//! the library is empty.
