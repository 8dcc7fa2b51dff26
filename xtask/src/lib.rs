//! Project automation behind `cargo xtask`. Each command is a module with a
//! `main(args) -> Result<(), String>` entry point that `main.rs` dispatches to.
#![deny(missing_docs)]

pub mod codegen;
pub mod deps;
pub mod size;

use std::path::PathBuf;

/// The workspace root (the parent of this crate's directory).
pub fn workspace_root() -> PathBuf {
    let here = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    here.parent().map(PathBuf::from).unwrap_or(here)
}
