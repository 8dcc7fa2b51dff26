//! Generates `$OUT_DIR/drvi.rs` from the DRVI's description (and its sidecar beside it).
//!
//! `root` makes the device path resolve against the workspace root while the file is still
//! named `devices/camozzi-drvi.eds` in the output, so this crate's module is byte-identical to
//! the checked-in `generated/src/drvi.rs` (tested in `tests/same_as_xtask.rs`). Like
//! `cargo xtask gen`, it puts the entries' names behind this crate's `names` feature (on by
//! default): a firmware build turns it off and saves their flash.

fn main() {
    let result = od_codegen::Builder::new()
        .root("../..")
        .names(od_codegen::Names::Feature("names".to_owned()))
        .device("drvi", "devices/camozzi-drvi.eds")
        .compile();
    if let Err(e) = result {
        // The error holds every diagnostic, rendered with file:line:col; fail the build.
        eprintln!("{e}");
        std::process::exit(1);
    }
}
