//! The project's device files and the schema of their sidecars.
//!
//! `devices/<name>.eds` is a CiA 306 device description transcribed from the vendor's manual;
//! `devices/<name>.toml` is its [`sidecar::Sidecar`]: units, scaling, modes, error tables and the
//! transcription decisions. Both are the project's main input: the code generator and the
//! simulated drives follow from them.
#![deny(missing_docs)]

/// The sidecar schema (the `od-sidecar` crate, part of the generator's input).
pub use od_sidecar as sidecar;

use std::path::{Path, PathBuf};

/// The bundled devices, by file stem.
pub const DEVICES: [&str; 3] = ["camozzi-drvi", "camozzi-drcs", "kollmorgen-akd"];

/// The directory holding the device files.
pub fn dir() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// Path of a bundled device's EDS.
pub fn eds_path(name: &str) -> PathBuf {
    dir().join(format!("{name}.eds"))
}

/// Path of a bundled device's sidecar.
pub fn sidecar_path(name: &str) -> PathBuf {
    dir().join(format!("{name}.toml"))
}
