//! The corpus of real files in `$EDS_CORPUS_DIR` (skipped, saying so, when unset): every file
//! loads in lenient mode without an error, writes back byte for byte, and its strict-mode
//! diagnostics are snapshot (one line each, so a change in what the reader says about a real
//! file shows up in review).

use std::path::PathBuf;

use eds::{Options, Severity};

fn corpus() -> Option<Vec<PathBuf>> {
    let Some(dir) = std::env::var_os("EDS_CORPUS_DIR") else {
        println!("EDS_CORPUS_DIR is not set: skipping the corpus tests");
        return None;
    };
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("EDS_CORPUS_DIR={}: {e}", PathBuf::from(&dir).display()))
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.extension()
                .and_then(|e| e.to_str())
                .is_some_and(|e| e.eq_ignore_ascii_case("eds") || e.eq_ignore_ascii_case("dcf"))
        })
        .collect();
    files.sort();
    assert!(!files.is_empty(), "no .eds or .dcf files in {}", PathBuf::from(&dir).display());
    Some(files)
}

fn name(p: &std::path::Path) -> String {
    p.file_name().and_then(|n| n.to_str()).unwrap_or("file").to_owned()
}

#[test]
fn every_file_loads_leniently_without_errors() {
    let Some(files) = corpus() else { return };
    let mut failures = Vec::new();
    for path in &files {
        let bytes = std::fs::read(path).expect("read");
        let p = eds::parse(&name(path), &bytes, &Options::lenient());
        if p.has_errors() {
            let errors: Vec<_> = p.errors().cloned().collect();
            failures.push(eds::diag::render_all(&errors, &p.document.source));
        }
        assert!(!p.model.objects.is_empty(), "{}: no objects", name(path));
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

#[test]
fn every_file_round_trips_byte_for_byte() {
    let Some(files) = corpus() else { return };
    for path in &files {
        let bytes = std::fs::read(path).expect("read");
        let p = eds::parse(&name(path), &bytes, &Options::lenient());
        assert!(p.document.write_lossless() == bytes, "{} does not round-trip", name(path));
    }
}

/// Every model reads back equal from its JSON, which it writes the same again; every entry is
/// stored at its own sub-index and every object at its own index; and each element of a compact
/// array is named as CiA 306 says, by a straightforward reference: the array's name followed by
/// the decimal sub-index, unless the file's names section gives it a name (`sub=name`).
#[test]
fn every_model_reads_back_from_json_with_keys_and_names_in_place() {
    let Some(files) = corpus() else { return };
    let mut elements = 0;
    for path in &files {
        let bytes = std::fs::read(path).expect("read");
        let text = String::from_utf8_lossy(&bytes);
        // The file's lines, trimmed, to look names up in (a scan of the text per element made
        // this test quadratic: 35 s).
        let lines: std::collections::HashSet<&str> = text.lines().map(str::trim).collect();
        let p = eds::parse(&name(path), &bytes, &Options::lenient());
        let json = serde_json::to_string(&p.model).expect("serialise");
        let back: eds::Model = serde_json::from_str(&json).unwrap_or_else(|e| panic!("{}: {e}", name(path)));
        assert!(back == p.model, "{}: the model does not read back from its JSON", name(path));
        assert_eq!(serde_json::to_string(&back).expect("serialise"), json, "{}", name(path));
        for (index, o) in &p.model.objects {
            assert_eq!(*index, o.index, "{}", name(path));
            for (sub, e) in &o.subs {
                assert_eq!(*sub, e.sub, "{} 0x{:04X}", name(path), index.0);
            }
            let Some(n) = o.compact_sub_obj else { continue };
            for s in 1..=n {
                let Some(e) = o.subs.get(&eds::SubIndex(s)) else { continue };
                elements += 1;
                let reference = format!("{}{s}", o.name.as_str());
                let named = lines.contains(format!("{s}={}", e.name).as_str());
                assert!(
                    e.name == reference || named,
                    "{} 0x{:04X} sub {s}: {:?}, not {reference:?} nor named in the file",
                    name(path),
                    index.0,
                    e.name
                );
            }
        }
    }
    // (The corpus has thousands of compact-array elements; with none, the check would be empty.)
    assert!(elements > 1000, "{elements} compact-array elements");
}

#[test]
fn strict_diagnostics_of_every_file() {
    let Some(files) = corpus() else { return };
    for path in &files {
        let bytes = std::fs::read(path).expect("read");
        let p = eds::parse(&name(path), &bytes, &Options::strict());
        let mut out = format!("{} objects; {}\n", p.model.objects.len(), eds::diag::summary(&p.diagnostics));
        for d in &p.diagnostics {
            let at = d.at.map(|lc| format!("{}:{}", lc.line, lc.col)).unwrap_or_else(|| "-".to_owned());
            out.push_str(&format!("{at} {}[{}] {}\n", d.severity, d.code, d.message));
        }
        let stem = name(path).replace(['+', '.'], "_");
        insta::assert_snapshot!(format!("strict_{stem}"), out);
        // Strict mode turns every deviation into an error and nothing else.
        for d in &p.diagnostics {
            assert_eq!(
                d.severity == Severity::Error,
                d.is_deviation() || eds::codes::info(d.code).is_some_and(|i| i.lenient == Severity::Error)
            );
        }
    }
}

#[test]
fn node_ids_of_the_dcfs() {
    let Some(files) = corpus() else { return };
    for path in files.iter().filter(|p| name(p).ends_with(".dcf")) {
        let p = eds::read_file(path, &Options::lenient()).expect("read");
        assert_eq!(p.model.kind, eds::FileKind::Dcf, "{}", name(path));
        if let Some(id) = p.model.node_id() {
            assert!((1..=127).contains(&id) || id == 255, "{}: node id {id}", name(path));
        }
    }
}
