//! Generation costs: `cargo bench -p od-codegen`. (A build script runs unoptimised: for that
//! profile, `cargo run -p od-codegen --example gen_time -- FILE`.)

use std::hint::black_box;
use std::path::Path;

use criterion::{Criterion, criterion_group, criterion_main};

fn generation(c: &mut Criterion) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    for (module, file) in [("akd", "devices/kollmorgen-akd.eds"), ("drvi", "devices/camozzi-drvi.eds")] {
        let Ok(bytes) = std::fs::read(root.join(file)) else { continue };
        let parsed = eds::parse(file, &bytes, &eds::Options::lenient());
        let mut options = od_codegen::Options::new(module, file);
        options.eds_text = Some(String::from_utf8_lossy(&bytes).into_owned());
        if let Ok(sc) = od_codegen::sidecar::Sidecar::read(&root.join(file).with_extension("toml")) {
            options.sidecar = Some(sc);
        }
        let n = parsed.model.entries().count();
        c.bench_function(&format!("generate: {module} ({n} entries), tokens"), |b| {
            b.iter(|| od_codegen::generate(black_box(&parsed.model), &options))
        });
        let tokens = od_codegen::generate(&parsed.model, &options);
        c.bench_function(&format!("generate: {module}, render with prettyplease"), |b| {
            b.iter(|| od_codegen::render(black_box(&tokens), file).map(|s| s.len()))
        });
        // What the Builder runs: the large parts as text, the rest through prettyplease.
        c.bench_function(&format!("generate: {module}, text path (expand_text + render)"), |b| {
            b.iter(|| od_codegen::expand_text(black_box(&parsed.model), &options).render(file).map(|s| s.len()))
        });
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20);
    targets = generation
}
criterion_main!(benches);
