//! Tests of the `lagrangian` crate compiled as a user's release build
//! compiles them (see `Cargo.toml`); the library is empty.
