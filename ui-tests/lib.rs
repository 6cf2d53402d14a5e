//! Compile-fail tests of `#[lagrangian]` (`tests/compile_fail.rs`, cases in
//! `tests/ui/`); the library is empty.
