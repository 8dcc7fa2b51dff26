//! What `cargo xtask gen` prints and writes besides the modules: the description diff of each
//! changed device file, and the network DCFs.

use std::path::Path;

use xtask::codegen::{self, SOURCES};

fn root() -> std::path::PathBuf {
    xtask::workspace_root()
}

fn mini() -> (&'static str, &'static str, String, Vec<u8>) {
    let s = SOURCES.iter().find(|s| s.module == "fixture_mini").expect("fixture_mini is generated");
    let checked_in = std::fs::read_to_string(root().join("generated/src/fixture_mini.rs")).unwrap();
    let bytes = std::fs::read(root().join(s.path)).unwrap();
    (s.module, s.path, checked_in, bytes)
}

#[test]
fn the_embedded_description_is_the_device_file() {
    for s in codegen::present_sources(&root()) {
        let module = std::fs::read_to_string(root().join("generated/src").join(format!("{}.rs", s.module))).unwrap();
        let embedded = codegen::embedded_description(&module, s.module).expect("an EDS constant");
        let file = eds::source::SourceFile::decode(s.path, &std::fs::read(root().join(s.path)).unwrap()).text;
        assert!(embedded == file, "{}: the checked-in EDS constant differs from the file; run cargo xtask gen", s.path);
    }
}

#[test]
fn an_unchanged_description_reports_nothing() {
    let (module, path, checked_in, bytes) = mini();
    assert_eq!(codegen::description_change(Some(&checked_in), module, path, &bytes), None);
}

#[test]
fn a_changed_description_reports_the_odgen_diff() {
    let (module, path, checked_in, bytes) = mini();
    let text = String::from_utf8(bytes).unwrap();
    let edited = text.replacen("ParameterName=Controlword", "ParameterName=Control word", 1);
    assert_ne!(edited, text, "the fixture names 0x6040 Controlword");
    let report = codegen::description_change(Some(&checked_in), module, path, edited.as_bytes()).expect("a report");
    assert!(report.starts_with(&format!("{path} changed since the checked-in generation (odgen diff):\n")), "{report}");
    assert!(report.contains("0x6040") && report.contains("ParameterName"), "{report}");
    assert!(report.contains("Controlword") && report.contains("Control word"), "{report}");
    assert!(report.trim_end().ends_with("1 field changed"), "{report}");
}

#[test]
fn a_new_device_reports_every_object_as_added() {
    let (module, path, _, bytes) = mini();
    let report = codegen::description_change(None, module, path, &bytes).expect("a report");
    assert!(report.starts_with(&format!("{path} is new (odgen diff):")), "{report}");
    assert!(report.contains("added") && report.contains("0x6040"), "{report}");
}

#[test]
fn network_dcfs_are_generated_read_back_and_none_is_left_over() {
    let files = codegen::network_files(&root(), "networks/example.toml").unwrap();
    assert!(!files.is_empty());
    for (rel, text) in &files {
        assert!(rel.starts_with(Path::new(codegen::NETWORK_DIR).join("example")), "{}", rel.display());
        let parsed = eds::parse(&rel.to_string_lossy(), text.as_bytes(), &eds::Options::lenient());
        assert!(!parsed.has_errors(), "{}: {:#?}", rel.display(), parsed.diagnostics);
        assert!(text.contains("[DeviceComissioning]"), "{}", rel.display());
    }
    let all = codegen::expected_files(&root()).unwrap();
    assert_eq!(codegen::leftover_dcfs(&root(), &all).unwrap(), Vec::<std::path::PathBuf>::new());
}

#[test]
fn a_dcf_no_network_produces_is_stale() {
    let dir = std::env::temp_dir().join(format!("xtask-leftover-{}", std::process::id()));
    let nets = dir.join(codegen::NETWORK_DIR).join("gone");
    std::fs::create_dir_all(&nets).unwrap();
    std::fs::write(nets.join("old_node.dcf"), "[FileInfo]\n").unwrap();
    std::fs::write(nets.join("notes.txt"), "not a DCF").unwrap();
    let left = codegen::leftover_dcfs(&dir, &[]).unwrap();
    assert_eq!(left, vec![Path::new(codegen::NETWORK_DIR).join("gone/old_node.dcf")]);
    let _ = std::fs::remove_dir_all(&dir);
}
