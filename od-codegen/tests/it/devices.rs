//! Snapshots of the project's devices at the two boundaries of the generator: the model the
//! reader makes of each description (YAML; the generator's only input) and the module the
//! generator writes for it (the same text `cargo xtask gen` checks in under `generated/src`).
//!
//! A change to the reader, the sidecar handling or the emitter shows up here as a reviewable
//! diff (`cargo insta review`), before it reaches the checked-in crate.

use std::path::{Path, PathBuf};

/// `(module, description)`, paths relative to the workspace root, as in `xtask`'s list.
const DEVICES: &[(&str, &str)] = &[
    ("drvi", "devices/camozzi-drvi.eds"),
    ("drcs", "devices/camozzi-drcs.eds"),
    ("akd", "devices/kollmorgen-akd.eds"),
];

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().map(Path::to_path_buf).unwrap_or_default()
}

#[test]
fn device_models() {
    for (module, rel) in DEVICES {
        let bytes = std::fs::read(root().join(rel)).unwrap();
        let parsed = eds::parse(rel, &bytes, &eds::Options::lenient());
        assert!(!parsed.has_errors(), "{rel}: {:#?}", parsed.diagnostics);
        insta::assert_yaml_snapshot!(format!("model_{module}"), parsed.model);
    }
}

#[test]
fn device_code() {
    let mut builder = od_codegen::Builder::new().root(root()).cargo_metadata(false).strict().embed_eds(true);
    for (module, rel) in DEVICES {
        builder = builder.device(*module, *rel);
    }
    let outputs = builder.generate().unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(outputs.len(), DEVICES.len());
    for ((module, _), out) in DEVICES.iter().zip(outputs) {
        assert_eq!(out.file_name, format!("{module}.rs"));
        insta::assert_snapshot!(format!("code_{module}"), out.text);
    }
}
