//! Real files: every corpus file and every device description, read, written and read back,
//! gives the same model; writing is a fixed point; what we write from a valid model passes
//! strict validation.
//!
//! The corpus is read in place from `EDS_CORPUS_DIR` (relative to the repository root), default
//! `../shared/eds-corpus`; without it that part is skipped with a message.

use crate::write_common;

use std::path::{Path, PathBuf};

use eds::{FileKind, Model, Options, Severity};

fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("eds/ has a parent").to_path_buf()
}

fn files_in(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .expect("list directory")
        .flatten()
        .map(|e| e.path())
        .filter(|p| matches!(p.extension().and_then(|e| e.to_str()), Some("eds" | "dcf")))
        .collect();
    v.sort();
    v
}

fn corpus() -> Option<Vec<PathBuf>> {
    let root = repo_root();
    let dir = match std::env::var_os("EDS_CORPUS_DIR") {
        Some(d) => {
            let d = PathBuf::from(d);
            if d.is_absolute() { d } else { root.join(d) }
        }
        None => root.join("../shared/eds-corpus"),
    };
    if dir.is_dir() {
        Some(files_in(&dir))
    } else {
        eprintln!("SKIPPED corpus part: no corpus at {} (set EDS_CORPUS_DIR)", dir.display());
        None
    }
}

/// Reads `path`, writes the model, reads the text back: the models must be equal and writing
/// again must give the same bytes. Returns the written text.
fn round_trip(path: &Path) -> Option<(Model, String)> {
    let parsed = eds::read_file(path, &Options::lenient()).expect("read file");
    let name = path.file_name().unwrap().to_string_lossy().into_owned();
    if !eds::write::unrepresentable(&parsed.model).is_empty() {
        eprintln!("{name}: not representable: {:?}", eds::write::unrepresentable(&parsed.model));
    }
    let text = eds::write::write(&parsed.model);
    let back = eds::parse(&name, text.as_bytes(), &Options::lenient());
    assert_eq!(back.model, parsed.model, "{name}: the written file reads back differently:\n{text}");
    assert_eq!(eds::write::write(&back.model), text, "{name}: writing is not a fixed point");
    // Nothing the reader complained about is new: our text has no errors the source did not have.
    let before = parsed.errors().count();
    let after: Vec<_> = back.errors().collect();
    assert!(after.len() <= before, "{name}: writing introduced errors: {after:#?}");
    Some((parsed.model, text))
}

#[test]
fn corpus_files_round_trip() {
    let Some(files) = corpus() else { return };
    assert!(!files.is_empty(), "corpus directory is empty");
    let mut bytes = 0;
    for f in &files {
        let (_, text) = round_trip(f).unwrap();
        bytes += text.len();
    }
    eprintln!("{} corpus files round-tripped ({bytes} bytes written)", files.len());
}

#[test]
fn device_descriptions_round_trip() {
    let files = files_in(&repo_root().join("devices"));
    assert!(!files.is_empty(), "no devices/*.eds");
    for f in &files {
        round_trip(f);
    }
}

fn strict_problems(name: &str, text: &str) -> Vec<String> {
    let parsed = eds::parse(name, text.as_bytes(), &Options::strict());
    parsed
        .diagnostics
        .iter()
        .filter(|d| d.severity == Severity::Error)
        .map(|d| eds::diag::render(d, &parsed.document.source))
        .collect()
}

#[test]
fn written_fixtures_pass_strict_validation() {
    let eds_text = eds::write::write(&write_common::full_eds());
    let errors = strict_problems("full.eds", &eds_text);
    assert!(errors.is_empty(), "{}\n{eds_text}", errors.join("\n"));
    let dcf_text = eds::write::write(&write_common::full_dcf());
    let errors = strict_problems("full.dcf", &dcf_text);
    assert!(errors.is_empty(), "{}\n{dcf_text}", errors.join("\n"));
}

#[test]
fn written_files_of_strictly_valid_sources_stay_strictly_valid() {
    let mut files = files_in(&repo_root().join("devices"));
    files.extend(corpus().unwrap_or_default());
    let mut checked = 0;
    for f in files {
        let parsed = eds::read_file(&f, &Options::strict()).expect("read");
        if parsed.has_errors() {
            continue;
        }
        let name = f.file_name().unwrap().to_string_lossy().into_owned();
        let text = eds::write::write(&parsed.model);
        let errors = strict_problems(&name, &text);
        assert!(errors.is_empty(), "{name} is strictly valid but what we write is not:\n{}", errors.join("\n"));
        checked += 1;
    }
    eprintln!("{checked} strictly valid files stay strictly valid when written");
}

#[test]
fn configured_device_descriptions_round_trip_as_dcf() {
    for f in files_in(&repo_root().join("devices")) {
        let parsed = eds::read_file(&f, &Options::lenient()).expect("read");
        let dcf = eds::write::configure(&parsed.model, 9, None, &[]).expect("configure without values");
        assert_eq!(dcf.kind, FileKind::Dcf);
        let text = eds::write::write_dcf(&dcf);
        let back = eds::parse("configured.dcf", text.as_bytes(), &Options::lenient());
        assert_eq!(back.model, dcf);
        assert_eq!(back.model.node_id(), Some(9));
    }
}
