//! The generation policy over real files (`$EDS_CORPUS_DIR`, skipped with a message when
//! unset): lenient generation refuses no file the reader loads without errors, and strict
//! generation reports exactly the same deviations, as errors. Prints how many of each kind the
//! corpus has.

use std::collections::BTreeMap;
use std::path::PathBuf;

use od_codegen::{Options, Severity, diag::DEVIATIONS, expand_text};

#[test]
fn lenient_refuses_nothing_and_strict_reports_the_same_deviations_as_errors() {
    let Some(dir) = std::env::var_os("EDS_CORPUS_DIR") else {
        println!("SKIPPED: EDS_CORPUS_DIR is not set");
        return;
    };
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..").join(dir);
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| matches!(p.extension().and_then(|e| e.to_str()), Some("eds" | "dcf")))
        .collect();
    files.sort();
    assert!(!files.is_empty(), "no files in {}", dir.display());
    let mut kinds: BTreeMap<&'static str, usize> = BTreeMap::new();
    let mut files_with_deviations = 0;
    for f in &files {
        let name = f.file_name().unwrap().to_string_lossy().into_owned();
        let parsed = eds::read_file(f, &eds::Options::lenient()).unwrap();
        assert!(!parsed.has_errors(), "{name}: the reader refuses it");
        // The text path (the `Builder`'s; `text_path.rs` holds it to the token path): the
        // same diagnostics, and its code compared as the file it writes.
        let lenient = expand_text(&parsed.model, &Options::new("m", name.clone()));
        let mut strict_options = Options::new("m", name.clone());
        strict_options.strict = true;
        let strict = expand_text(&parsed.model, &strict_options);
        assert!(!lenient.has_errors(), "{name}:\n{}", od_codegen::diag::render_plain(&lenient.diagnostics));
        assert!(lenient.render(&name).unwrap() == strict.render(&name).unwrap(), "{name}: strictness changed the code");
        assert_eq!(lenient.diagnostics.len(), strict.diagnostics.len(), "{name}");
        let mut any = false;
        for (l, s) in lenient.diagnostics.iter().zip(&strict.diagnostics) {
            assert_eq!((l.code, &l.message, l.at), (s.code, &s.message, s.at), "{name}");
            if DEVIATIONS.contains(&l.code) {
                assert_eq!((l.severity, s.severity), (Severity::Warning, Severity::Error), "{name}: {l:?}");
                assert!(l.at.is_some(), "{name}: a deviation without a location: {l:?}");
                *kinds.entry(l.code.0).or_default() += 1;
                any = true;
            } else {
                assert_eq!(l.severity, s.severity, "{name}: {l:?}");
            }
        }
        files_with_deviations += usize::from(any);
    }
    println!("{} files, {files_with_deviations} with deviations: {kinds:?}", files.len());
}
