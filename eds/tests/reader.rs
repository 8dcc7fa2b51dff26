//! `eds::Reader` (files read one after another into the memory of the ones before) gives what
//! `eds::read_file` gives, whatever the files and their order: large after small, small after
//! large, duplicate sections (whose entries are regrouped), other encodings (decoded into new
//! text), and the real corpus when it is at hand.

use std::path::{Path, PathBuf};

use eds::{Options, Parsed};

fn files_in(dir: &Path) -> Vec<PathBuf> {
    let Ok(entries) = std::fs::read_dir(dir) else { return Vec::new() };
    let mut files: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.extension()
                .and_then(|e| e.to_str())
                .is_some_and(|e| e.eq_ignore_ascii_case("eds") || e.eq_ignore_ascii_case("dcf"))
        })
        .collect();
    files.sort();
    files
}

/// The fixtures of every diagnostic code and feature, and the corpus if there is one.
fn inputs() -> Vec<PathBuf> {
    let here = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut files = files_in(&here.join("tests/fixtures"));
    files.extend(files_in(&here.join("tests/fixtures/diag")));
    files.extend(files_in(&here.join("tests/fixtures/features")));
    let corpus =
        std::env::var_os("EDS_CORPUS_DIR").map(PathBuf::from).unwrap_or_else(|| here.join("../../shared/eds-corpus"));
    files.extend(files_in(&corpus));
    assert!(files.len() > 50, "too few inputs: {}", files.len());
    files
}

/// Everything a caller can see of a read file, diagnostics rendered with their source lines.
fn seen(p: &Parsed) -> (String, eds::Model, Vec<eds::Diagnostic>, Vec<String>) {
    let rendered = p.diagnostics.iter().map(|d| eds::diag::render(d, &p.document.source)).collect();
    (p.document.source.text.clone(), p.model.clone(), p.diagnostics.clone(), rendered)
}

#[test]
fn a_reader_reads_every_file_as_read_file_does_in_any_order() {
    let files = inputs();
    let mut orders = vec![files.clone(), files.iter().rev().cloned().collect::<Vec<_>>()];
    // Largest first, then smallest first: buffers that are too large, then too small.
    let mut by_size = files.clone();
    by_size.sort_by_key(|p| std::cmp::Reverse(std::fs::metadata(p).map_or(0, |m| m.len())));
    orders.push(by_size.clone());
    orders.push(by_size.into_iter().rev().collect());
    for options in [Options::lenient(), Options::strict()] {
        let expected: Vec<_> = files.iter().map(|p| seen(&eds::read_file(p, &options).expect("readable"))).collect();
        for order in &orders {
            let mut reader = eds::Reader::new();
            for (i, path) in order.iter().enumerate() {
                let parsed = reader.read_file(path, &options).expect("readable");
                let at = files.iter().position(|f| f == path).expect("listed");
                assert!(seen(&parsed) == expected[at], "{} differs when read by a reader", path.display());
                // Every other file is dropped rather than given back: a reader works either way.
                if i % 2 == 0 {
                    reader.recycle(parsed);
                }
            }
        }
    }
}

#[test]
fn a_reader_reports_unreadable_files_and_goes_on() {
    let mut reader = eds::Reader::new();
    let good = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/base.eds");
    let first = reader.read_file(&good, &Options::lenient()).expect("readable");
    reader.recycle(first);
    assert!(reader.read_file("/nonexistent/x.eds", &Options::lenient()).is_err());
    assert!(reader.read_file(Path::new(env!("CARGO_MANIFEST_DIR")), &Options::lenient()).is_err());
    let again = reader.read_file(&good, &Options::lenient()).expect("readable");
    assert!(seen(&again) == seen(&eds::read_file(&good, &Options::lenient()).expect("readable")));
}
