//! The compiler flags of trybuild's inner builds, as cargo's environment variable: shared by
//! the compile-fail test (`ui-tests/tests/ui.rs`) and od-codegen's check of the generated
//! code (`od-codegen/tests/it/compile_all.rs`), which checks its crate in trybuild's target
//! directory with these flags so that both compile their common dependencies once.
//!
//! trybuild builds its project's dependencies first with `--cfg trybuild --verbose -A
//! dead_code`, then the cases with `--diagnostic-width=140` added (trybuild 1.0.122,
//! `cargo.rs`); the flags are part of each unit's fingerprint, so every dependency (tokio,
//! serde, od-master, od-codegen, ...) was checked twice in its target directory. Cargo takes
//! `CARGO_ENCODED_RUSTFLAGS` over the `--config` flags trybuild passes, so with the second set
//! here both builds are one: the cases get the flags trybuild gives them, the dependencies are
//! checked once. `RUSTFLAGS` trybuild removes; this one it leaves. Units separated by 0x1f, as
//! cargo reads the variable. (What trybuild adds when `RUSTFLAGS` asks for a coverage build,
//! `-C instrument-coverage`, is not carried over; the project measures no coverage. Add it
//! here if it ever does.) Should trybuild's flags change, the two builds only stop sharing
//! their dependencies; each still checks what it checks.
pub const TRYBUILD_FLAGS: &str = "--cfg\x1ftrybuild\x1f--verbose\x1f-A\x1fdead_code\x1f--diagnostic-width=140";
