//! The workspace's compile tests: what compiles and runs, and what must not compile, each
//! mistake with its message on the offending tokens (`ui/**/*.stderr`).
//!
//! All compile-fail cases of the workspace are here, in one trybuild project, so that the
//! dependencies they need (od-macros and its generator, od-runtime, od-master) are built once in
//! trybuild's own target directory, and only checked, never code-generated (a trybuild project
//! with a passing case builds everything): 290 s of CPU for this project alone before, when it
//! had a passing case, and od-master and od-codegen each had a project of their own that also
//! built their other dev-dependencies (the simulated drives, criterion, proptest). A package
//! of its own (`ui-tests`), so that trybuild's project has only the dependencies the cases
//! need (it takes every dependency of the package it runs in) and the tests' build compiles
//! them once, for the target (a proc-macro crate's tests are built for the host).
//!
//! * `ui/fail/`: `object_dictionary!` mistakes. Several share a file where they can: every
//!   `object_dictionary!` reports all of its errors in one compile. `every_*.rs`, `follow_up.rs`
//!   and `syntax.rs` are the inputs of the crate's in-process error tests (`src/tests.rs`,
//!   which check the messages and their order): here each error's place is checked as a user
//!   sees it, line, column and underlined tokens.
//! * `ui/client/`: what a generated client refuses: writing a `ro` object and reading a `wo`
//!   one, a quantity of the wrong dimension, a PDO field of the wrong type, an object of a
//!   description it was not generated from, and a vendor's file without a sidecar whose
//!   positions and velocities are typed by CiA 402's dimensions all the same. The cases include
//!   the devices' files from the target directory's `tmp/client-ui/`, where [`client_files`]
//!   puts them first (trybuild builds each case three levels below the target directory): the
//!   DRVI's and the AKD's descriptions and sidecars as they are, the DRVI's with 607Ah removed
//!   (through the reader and writer, so the file stays a valid EDS) and without its sidecar,
//!   and the DRVI's alone, as a vendor ships it.
//! * `../od-codegen/tests/stale/`: generated code and runtime of different interface versions
//!   (`::od_runtime::__private_vN`) fail to compile naming the module; od-codegen's tests check
//!   that those files are what its generator writes today.
//!
//! The passing case, a dictionary declared inline, is an ordinary module of this test
//! (`pass/inline.rs`, warnings denied there) that the test runs.

use std::path::Path;

#[path = "pass/inline.rs"]
mod inline;

#[test]
fn an_inline_dictionary_compiles_without_warnings_and_works() {
    inline::run();
}

/// The device files the client cases include, in `<target>/tmp/client-ui/`.
fn client_files() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap();
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("client-ui");
    std::fs::create_dir_all(&dir).unwrap();
    for f in ["camozzi-drvi.eds", "camozzi-drvi.toml", "kollmorgen-akd.eds", "kollmorgen-akd.toml"] {
        let text = std::fs::read(root.join("devices").join(f)).unwrap();
        od_codegen::write_if_changed(&dir.join(f), std::str::from_utf8(&text).unwrap()).unwrap();
    }
    let parsed = eds::read_file(root.join("devices/camozzi-drvi.eds"), &eds::Options::lenient()).unwrap();
    assert!(!parsed.has_errors());
    let mut model = parsed.model;
    assert!(model.objects.remove(&eds::model::Index(0x607A)).is_some());
    // The DRVI's description alone, without its sidecar: a vendor's file as users have it.
    let alone = std::fs::read(root.join("devices/camozzi-drvi.eds")).unwrap();
    od_codegen::write_if_changed(&dir.join("vendor-drvi.eds"), std::str::from_utf8(&alone).unwrap()).unwrap();
    let trimmed = eds::write::write_eds(&model);
    od_codegen::write_if_changed(&dir.join("drvi-without-607a.eds"), &trimmed).unwrap();
}

// trybuild's flags, which od-codegen's check of the generated code (dictionaries and clients)
// uses too (the file says why).
#[path = "shared/trybuild_flags.rs"]
mod trybuild_flags;
use trybuild_flags::TRYBUILD_FLAGS;

#[test]
fn what_must_not_compile_does_not() {
    client_files();
    // SAFETY: the other test of this binary (the inline dictionary) neither reads nor writes
    // the environment, and no code outside Rust's std runs in this process (std's own reads
    // and writes of the environment take one lock).
    unsafe { std::env::set_var("CARGO_ENCODED_RUSTFLAGS", TRYBUILD_FLAGS) };
    let t = trybuild::TestCases::new();
    t.compile_fail("tests/ui/fail/*.rs");
    t.compile_fail("tests/ui/client/*.rs");
    t.compile_fail("../od-codegen/tests/stale/*.rs");
}
