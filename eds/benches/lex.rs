//! Lexer and full-reader throughput over real files.
//!
//! Reads every `.eds`/`.dcf` in `$EDS_CORPUS_DIR`, falling back to the crate's own fixtures, and
//! measures bytes per second for: the lexer alone (`lex`), decoding plus lexing (`decode+lex`),
//! and the whole reader with validation (`parse`, lenient and strict).
//!
//! `cargo bench -p canopen-eds --bench lex`

extern crate canopen_eds as eds;

use std::path::{Path, PathBuf};

use criterion::{Criterion, Throughput, criterion_group, criterion_main};

fn inputs() -> Vec<(String, Vec<u8>)> {
    let dirs: Vec<PathBuf> = match std::env::var_os("EDS_CORPUS_DIR") {
        Some(d) => vec![PathBuf::from(d)],
        None => {
            let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures");
            eprintln!("EDS_CORPUS_DIR is not set: benchmarking the crate's fixtures");
            vec![root.clone(), root.join("features"), root.join("diag")]
        }
    };
    let mut out = Vec::new();
    for dir in dirs {
        let Ok(rd) = std::fs::read_dir(&dir) else { continue };
        let mut paths: Vec<PathBuf> = rd.filter_map(|e| e.ok().map(|e| e.path())).collect();
        paths.sort();
        for p in paths {
            let ext = p.extension().and_then(|e| e.to_str()).unwrap_or("").to_ascii_lowercase();
            if (ext == "eds" || ext == "dcf")
                && let Ok(bytes) = std::fs::read(&p)
            {
                out.push((p.file_name().and_then(|n| n.to_str()).unwrap_or("").to_owned(), bytes));
            }
        }
    }
    out
}

fn bench(c: &mut Criterion) {
    let files = inputs();
    let total: usize = files.iter().map(|(_, b)| b.len()).sum();
    let texts: Vec<String> = files.iter().map(|(n, b)| eds::source::SourceFile::decode(n.as_str(), b).text).collect();
    let mut g = c.benchmark_group("eds");
    g.throughput(Throughput::Bytes(total as u64));
    g.bench_function("lex", |b| {
        b.iter(|| texts.iter().map(|t| eds::lex::lex_lines(t).len()).sum::<usize>());
    });
    g.bench_function("decode+lex", |b| {
        b.iter(|| {
            files
                .iter()
                .map(|(n, bytes)| {
                    eds::ast::Document::lexed(eds::source::SourceFile::decode(n.as_str(), bytes)).lines().len()
                })
                .sum::<usize>()
        });
    });
    for (label, options) in [("parse lenient", eds::Options::lenient()), ("parse strict", eds::Options::strict())] {
        g.bench_function(label, |b| {
            b.iter(|| files.iter().map(|(n, bytes)| eds::parse(n, bytes, &options).diagnostics.len()).sum::<usize>());
        });
    }
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
