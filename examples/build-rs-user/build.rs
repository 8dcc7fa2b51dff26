//! Generates `$OUT_DIR/drvi.rs` from the DRVI's description (and its sidecar beside it).
//!
//! `root` makes the device path resolve against the workspace root while the file is still
//! named `devices/camozzi-drvi.eds` in the output, so this crate's module is byte-identical to
//! the checked-in `generated/src/drvi.rs` (tested in `tests/same_as_xtask.rs`).

fn main() {
    let result = od_codegen::Builder::new()
        .root("../..")
        .embed_eds(true) // as `cargo xtask gen` does, so the two files are the same
        .device("drvi", "devices/camozzi-drvi.eds")
        .compile();
    if let Err(e) = result {
        // The error holds every diagnostic, rendered with file:line:col; fail the build.
        eprintln!("{e}");
        std::process::exit(1);
    }
}
