//! The facade's behaviour tests (`tests/behaviour/`), built unoptimised
//! (see `Cargo.toml`); the library is empty.
