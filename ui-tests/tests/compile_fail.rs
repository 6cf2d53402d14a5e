//! Misuses of `#[lagrangian]` and the diagnostics they produce.
//!
//! Each `ui/*.rs` case is named after the misuse; its `.stderr` shows that
//! the macro's own error lands on the offending token with no follow-on
//! errors. Regenerate with `TRYBUILD=overwrite` and read the diff.

#[test]
fn ui() {
    let cases = trybuild::TestCases::new();
    cases.compile_fail("tests/ui/*.rs");
    // No `pass` cases here: with one, trybuild builds (rather than checks)
    // every case and all the dependencies. The accepted unusual forms are
    // ordinary tests (`tests/behaviour/accepted_forms.rs`).
}
