//! Compile tests (trybuild): the happy path compiles warning-free and runs; each kind of
//! mistake fails to compile with its message on the offending tokens (`ui/fail/*.stderr`).
//!
//! Several mistakes share a file where they can: every `object_dictionary!` reports all of its
//! errors in one compile, which these files also demonstrate.

#[test]
fn ui() {
    let t = trybuild::TestCases::new();
    t.pass("tests/ui/pass/*.rs");
    t.compile_fail("tests/ui/fail/*.rs");
}
