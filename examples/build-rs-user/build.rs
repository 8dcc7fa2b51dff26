//! Generates `$OUT_DIR/drvi.rs` from the DRVI's description (and its sidecar beside it), and
//! `$OUT_DIR/vendor_io.rs` from a vendor's file as it comes.
//!
//! `root` makes the device path resolve against the workspace root while the file is still
//! named `devices/camozzi-drvi.eds` in the output, so this crate's module is byte-identical to
//! the checked-in `generated/src/drvi.rs` (tested in `tests/same_as_xtask.rs`). Like
//! `cargo xtask gen`, it puts the entries' names behind this crate's `names` feature (on by
//! default): a firmware build turns it off and saves their flash.
//!
//! `vendor-io.eds` stands for a file nobody here wrote: its default TPDO 1 mapping is two
//! `0x00000000` placeholders. Generation is lenient by default, so the crate builds, Cargo
//! shows one line for it (`warning: build-rs-user@0.1.0: vendor-io.eds:121:2:
//! warning[G0108]: …`), and the module has no `pdo::Tpdo1` while 0x1A00 stays in the
//! dictionary for a master to remap. `Builder::strict()` would make it an error instead.
//! `od-codegen` is the only build-dependency: it re-exports what a build script needs.

fn main() {
    let ours = od_codegen::Builder::new()
        .root("../..")
        .strict() // our own file: every deviation is an error
        .embed_eds(true) // as `cargo xtask gen` does, so the two files are the same
        .names(od_codegen::Names::Feature("names".to_owned()))
        .device("drvi", "devices/camozzi-drvi.eds")
        .compile();
    let vendor = od_codegen::Builder::new().device("vendor_io", "vendor-io.eds").compile();
    for result in [ours, vendor] {
        if let Err(e) = result {
            // The error names the device and holds every error, rendered with file:line:col.
            eprintln!("{e}");
            std::process::exit(1);
        }
    }
}
