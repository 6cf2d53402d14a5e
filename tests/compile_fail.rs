//! Misuses of `#[lagrangian]` and the diagnostics they produce.
//!
//! Each `ui/*.rs` case is named after the misuse; its `.stderr` shows that
//! the macro's own error lands on the offending token with no follow-on
//! errors. Regenerate with `TRYBUILD=overwrite` and read the diff.

#[test]
fn ui() {
    trybuild::TestCases::new().compile_fail("tests/ui/*.rs");
}
