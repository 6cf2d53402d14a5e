//! The facade's structure-analysis, run-time-sized and large-systems tests
//! (`tests/systems/`), built unoptimised (see `Cargo.toml`); the library is
//! empty.
