//! The runtime's short integration tests (`runtime/tests/behaviour/`),
//! built unoptimised (see `Cargo.toml`); the library is empty.
