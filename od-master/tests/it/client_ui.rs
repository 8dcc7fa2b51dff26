//! What a generated client refuses at compile time (trybuild, one run for all cases in
//! `tests/ui/client/`): writing a `ro` object and reading a `wo` one, a quantity of the wrong
//! dimension, a PDO field of the wrong type, and an object of a description it was not
//! generated from.
//!
//! The cases include the devices' files from the target directory's `tmp/client-ui/`, where
//! this test puts them first (trybuild builds each case in `<target>/tests/trybuild/od-master/`,
//! three levels below the target directory): the DRVI's and the AKD's descriptions and
//! sidecars as they are, and the DRVI's with 607Ah removed (through the reader and writer, so
//! the file stays a valid EDS), without its sidecar, which gives 607Ah a dimension; and the
//! DRVI's as a vendor ships it, without a sidecar, whose positions and velocities are typed by
//! CiA 402's dimensions all the same.

use std::path::Path;

#[test]
fn client_compile_failures() {
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

    let t = trybuild::TestCases::new();
    t.compile_fail("tests/ui/client/*.rs");
}
