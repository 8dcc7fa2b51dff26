//! Read+validate throughput over the EDS/DCF corpus, in bytes per second.
//!
//! The corpus is the directory named by `EDS_CORPUS_DIR` (relative paths are taken from the
//! repository root), default `../shared/eds-corpus`; without it the bench falls back to the
//! project's own `devices/*.eds`. Run with `cargo bench -p canopen-eds --bench read`.
//! `scripts/bench-read.sh` compares the same work against python-canopen.

extern crate canopen_eds as eds;

use std::path::{Path, PathBuf};

use criterion::{Criterion, Throughput, criterion_group, criterion_main};

fn corpus() -> (String, Vec<(String, Vec<u8>)>) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap_or(Path::new(".")).to_path_buf();
    let dir = match std::env::var_os("EDS_CORPUS_DIR") {
        Some(d) => {
            let d = PathBuf::from(d);
            if d.is_absolute() { d } else { root.join(d) }
        }
        None => root.join("../shared/eds-corpus"),
    };
    let dir = if dir.is_dir() {
        dir
    } else {
        eprintln!("note: no corpus at {} (set EDS_CORPUS_DIR); using devices/", dir.display());
        root.join("devices")
    };
    let mut files: Vec<(String, Vec<u8>)> = std::fs::read_dir(&dir)
        .map(|rd| {
            rd.flatten()
                .map(|e| e.path())
                .filter(|p| {
                    matches!(
                        p.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase()).as_deref(),
                        Some("eds" | "dcf")
                    )
                })
                .filter_map(|p| Some((p.display().to_string(), std::fs::read(&p).ok()?)))
                .collect()
        })
        .unwrap_or_default();
    files.sort();
    (dir.display().to_string(), files)
}

fn read(c: &mut Criterion) {
    let (dir, files) = corpus();
    let bytes: usize = files.iter().map(|(_, b)| b.len()).sum();
    eprintln!("corpus {dir}: {} files, {bytes} bytes", files.len());
    let mut group = c.benchmark_group("read");
    group.throughput(Throughput::Bytes(bytes as u64));
    for (label, options) in [("lenient", eds::Options::lenient()), ("strict", eds::Options::strict())] {
        group.bench_function(format!("corpus_{label}"), |b| {
            b.iter(|| {
                let mut objects = 0;
                for (name, data) in &files {
                    objects += eds::parse(name, data, &options).model.objects.len();
                }
                std::hint::black_box(objects)
            })
        });
    }
    let models: Vec<eds::Model> =
        files.iter().map(|(name, data)| eds::parse(name, data, &eds::Options::lenient()).model).collect();
    group.bench_function("corpus_write", |b| {
        b.iter(|| models.iter().map(|m| eds::write::write(m).len()).sum::<usize>())
    });
    group.finish();
}

criterion_group!(benches, read);
criterion_main!(benches);
