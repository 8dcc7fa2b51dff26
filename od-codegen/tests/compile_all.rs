//! "The tokens always compile": the code generated for every file of the EDS corpus
//! (`$EDS_CORPUS_DIR`, skipped with a message when unset) and for every fixture of this crate,
//! bad ones included, goes into one `#![no_std]` crate, a module per file, which `cargo check`
//! must accept with warnings denied.
//!
//! Generation is lenient (the default): every file the reader loads without errors must
//! generate without errors. Beside the files, the crate holds models built at random (a fixed
//! seed, so a failure reproduces) from the parts real files get wrong: names that collide or
//! are keywords, ordinals, non-ASCII, defaults and limits outside the type (REAL32 beyond
//! `f32`, NaN), `$NODEID` values, unsupported types, and PDO mappings of absent, unmappable,
//! mistyped and placeholder entries. The crate lives in the target directory
//! (`target/od-codegen-compile-all`) and keeps its own target directory between runs, so a run
//! after a small change rechecks only what changed; files are written only when they change.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use od_codegen::{Builder, Severity};

fn workspace_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("od-codegen/ has a parent").to_path_buf()
}

fn target_dir() -> PathBuf {
    match std::env::var_os("CARGO_TARGET_DIR") {
        Some(d) => {
            let d = PathBuf::from(d);
            if d.is_absolute() { d } else { workspace_root().join(d) }
        }
        None => workspace_root().join("target"),
    }
}

fn description_files(dir: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .flatten()
        .map(|e| e.path())
        .filter(|p| {
            p.extension()
                .and_then(|e| e.to_str())
                .is_some_and(|e| e.eq_ignore_ascii_case("eds") || e.eq_ignore_ascii_case("dcf"))
        })
        .collect();
    v.sort();
    v
}

/// The corpus files, or `None` (with a message) when `$EDS_CORPUS_DIR` is not set.
fn corpus() -> Option<Vec<PathBuf>> {
    let Some(dir) = std::env::var_os("EDS_CORPUS_DIR") else {
        println!("SKIPPED the corpus part: EDS_CORPUS_DIR is not set (only the fixtures are compiled)");
        return None;
    };
    let dir = PathBuf::from(dir);
    let dir = if dir.is_absolute() { dir } else { workspace_root().join(dir) };
    Some(description_files(&dir))
}

/// A module name for a file: its stem in snake case, numbered to stay unique and short.
fn module_name(i: usize, path: &Path) -> String {
    let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("");
    let tail: String = stem.rsplit("__").next().unwrap_or(stem).to_owned();
    let snake = od_codegen::ident::snake(&tail).unwrap_or_else(|| "device".to_owned());
    format!("f{i:02}_{}", snake.trim_end_matches('_'))
}

#[test]
fn every_description_generates_code_that_compiles_with_warnings_denied() {
    let mut files = description_files(&Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures"));
    let fixtures = files.len();
    if let Some(c) = corpus() {
        files.extend(c);
    }
    let krate = target_dir().join("od-codegen-compile-all");
    let src = krate.join("src");
    std::fs::create_dir_all(&src).unwrap();

    let mut builder = Builder::new().cargo_metadata(false).out_dir(&src);
    let mut modules = Vec::new();
    let mut read_errors = Vec::new();
    for (i, f) in files.iter().enumerate() {
        // Files the reader refuses are not the generator's to build (a corpus file with reader
        // errors would show up in eds/tests/corpus.rs); bad fixtures have errors by design, and
        // their code must compile all the same, so they are read leniently too.
        let parsed = eds::read_file(f, &eds::Options::lenient()).unwrap();
        if parsed.has_errors() && i >= fixtures {
            read_errors.push(f.display().to_string());
            continue;
        }
        let m = module_name(i, f);
        builder = builder.device(&m, f).no_sidecar();
        modules.push((m, i < fixtures));
    }
    assert!(read_errors.is_empty(), "corpus files the reader refuses: {read_errors:#?}");

    let started = std::time::Instant::now();
    let results = builder.generate_each();
    let generated_in = started.elapsed();
    let mut failures = Vec::new();
    let mut deviations = 0usize;
    for (r, (m, is_fixture)) in results.iter().zip(&modules) {
        match r {
            Ok(o) => {
                deviations += o.diagnostics.iter().filter(|d| od_codegen::diag::DEVIATIONS.contains(&d.code)).count();
                od_codegen::write_if_changed(&src.join(&o.file_name), &o.text).unwrap();
            }
            // A bad fixture fails on its reader errors: its code is still what the tokens are,
            // so write it (through `expand`, which `generate_each` does not hand out then).
            Err(od_codegen::Error::Device { .. }) if *is_fixture => {
                let f = &files[modules.iter().position(|(n, _)| n == m).unwrap()];
                let parsed = eds::read_file(f, &eds::Options::lenient()).unwrap();
                let g = od_codegen::expand(&parsed.model, &od_codegen::Options::new(m.clone(), m.clone()));
                assert!(
                    g.diagnostics.iter().all(|d| d.severity != Severity::Error || d.code.0.starts_with("G02")),
                    "{m}: {}",
                    od_codegen::diag::render_plain(&g.diagnostics)
                );
                let text = od_codegen::render(&g.tokens, m).unwrap();
                od_codegen::write_if_changed(&src.join(format!("{m}.rs")), &text).unwrap();
            }
            Err(e) => failures.push(format!("{m}: {e}")),
        }
    }
    assert!(failures.is_empty(), "lenient generation failed:\n{}", failures.join("\n\n"));

    // `ODCODEGEN_RANDOM_MODELS=N` checks more (or fewer) of them.
    let random_models: u64 = std::env::var("ODCODEGEN_RANDOM_MODELS").ok().and_then(|n| n.parse().ok()).unwrap_or(40);
    for seed in 0..random_models {
        let m = format!("random_{seed:02}");
        let model = random::model(seed);
        let g = od_codegen::expand(&model, &od_codegen::Options::new(m.clone(), format!("{m}.eds")));
        let errors: Vec<_> = g.diagnostics.iter().filter(|d| d.severity == Severity::Error).cloned().collect();
        assert!(errors.is_empty(), "seed {seed}: {}", od_codegen::diag::render_plain(&errors));
        let text = od_codegen::render(&g.tokens, &m).unwrap_or_else(|e| panic!("seed {seed}: {e}"));
        od_codegen::write_if_changed(&src.join(format!("{m}.rs")), &text).unwrap();
        modules.push((m, false));
    }

    let mut lib = String::from(
        "//! Every description's generated module (written by od-codegen's tests/compile_all.rs).\n\
         #![no_std]\n#![deny(warnings)]\n\n",
    );
    for (m, _) in &modules {
        lib.push_str(&format!("include!(\"{m}.rs\");\n"));
    }
    od_codegen::write_if_changed(&src.join("lib.rs"), &lib).unwrap();
    let runtime = workspace_root().join("od-runtime");
    let manifest = format!(
        "[package]\nname = \"od-codegen-compile-all\"\nversion = \"0.0.0\"\nedition = \"2024\"\npublish = false\n\n\
         [dependencies]\nod-runtime = {{ path = {:?} }}\n\n[workspace]\n",
        runtime.display().to_string()
    );
    od_codegen::write_if_changed(&krate.join("Cargo.toml"), &manifest).unwrap();

    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let started = std::time::Instant::now();
    let out = Command::new(cargo)
        .arg("check")
        .arg("--quiet")
        .arg("--offline")
        .arg("--manifest-path")
        .arg(krate.join("Cargo.toml"))
        .arg("--target-dir")
        .arg(krate.join("target"))
        // The outer `cargo test`'s settings are not the inner build's.
        .env_remove("RUSTFLAGS")
        .env_remove("CARGO_ENCODED_RUSTFLAGS")
        .env_remove("CARGO_TARGET_DIR")
        .env_remove("CARGO_BUILD_TARGET_DIR")
        .output()
        .expect("run cargo check");
    let stderr = String::from_utf8_lossy(&out.stderr);
    println!(
        "{} descriptions ({fixtures} fixtures), {deviations} deviations (warnings), generated in {:.1?}, checked in {:.1?}",
        modules.len(),
        generated_in,
        started.elapsed()
    );
    assert!(out.status.success(), "the generated code does not compile (crate at {}):\n{stderr}", krate.display());
}

/// Models built at random from the parts real files get wrong.
mod random {
    use super::common::*;
    use eds::model::{Access, DataType as D, Model, ObjectType, Radix, Value};

    /// A small deterministic generator (SplitMix64), so a failing seed reproduces.
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> u64 {
            self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            z ^ (z >> 31)
        }
        fn below(&mut self, n: usize) -> usize {
            (self.next() % n as u64) as usize
        }
        fn pick<'a, T>(&mut self, v: &'a [T]) -> &'a T {
            &v[self.below(v.len())]
        }
        fn chance(&mut self, percent: usize) -> bool {
            self.below(100) < percent
        }
    }

    const NAMES: &[&str] = &[
        "Speed",
        "speed",
        "Set speed",
        "Point",
        "Set point",
        "type",
        "new",
        "read",
        "1st receive PDO parameter",
        "2nd",
        "COB-IDs",
        "Übergröße °C",
        "",
        " -- ",
        "Error history",
        "Error history 1",
        "Mapped object",
        "Highest sub-index supported",
        "Self",
        "self",
        "a very long parameter name that goes on with many words describing the maximum value of something",
        "Input interrupt mask low-to-high for digital inputs 1-32",
        "RPDO mapping parameter",
        "Trace",
        "x",
        "set_",
        "Über",
    ];

    const TYPES: &[D] = &[
        D::Boolean,
        D::Integer8,
        D::Integer16,
        D::Integer24,
        D::Integer32,
        D::Integer40,
        D::Integer64,
        D::Unsigned8,
        D::Unsigned16,
        D::Unsigned24,
        D::Unsigned32,
        D::Unsigned48,
        D::Unsigned64,
        D::Real32,
        D::Real64,
        D::VisibleString,
        D::OctetString,
        D::UnicodeString,
        D::Domain,
        D::TimeOfDay,
        D::Other(0x0020),
    ];

    const ACCESS: &[Access] = &[Access::Ro, Access::Wo, Access::Rw, Access::Rwr, Access::Rww, Access::Const];

    const INTS: &[i128] = &[
        0,
        1,
        -1,
        127,
        128,
        255,
        256,
        -129,
        65535,
        0x8000_0000,
        -0x8000_0000,
        0xFFFF_FFFF,
        1 << 40,
        i64::MAX as i128,
        u64::MAX as i128,
        i64::MIN as i128,
    ];

    fn value(r: &mut Rng) -> Option<Value> {
        Some(match r.below(9) {
            0 => return None,
            1..=3 => Value::Int { value: *r.pick(INTS), radix: if r.chance(50) { Radix::Hex } else { Radix::Dec } },
            4 => Value::NodeIdPlus { offset: *r.pick(&[0, 0x180, -1, 0x7FFF_FFFF, -200]), radix: Radix::Hex },
            5 => Value::Real(*r.pick(&[0.5, -2.25, 1e300, -1e300, f64::NAN, f64::INFINITY, 3.4e38, 1e-300])),
            6 => Value::Text(r.pick(&["", "abc", "Ünïcode \"quoted\" #", "a\nb"]).to_string()),
            7 => Value::Bytes(vec![0xAB; r.below(40)]),
            _ => Value::Int { value: r.below(3) as i128, radix: Radix::Dec },
        })
    }

    fn entry_at(r: &mut Rng, sub: u8, name: &str) -> eds::model::Entry {
        let mut e = entry(sub, name, *r.pick(TYPES), *r.pick(ACCESS), value(r), r.chance(50));
        if r.chance(30) {
            e.extras_mut().low_limit = value(r);
        }
        if r.chance(30) {
            e.extras_mut().high_limit = value(r);
        }
        if r.chance(10) {
            e.extras_mut().parameter_value = value(r);
        }
        e
    }

    pub fn model(seed: u64) -> Model {
        let mut r = Rng(seed.wrapping_mul(0x2545_F491_4F6C_DD1D) ^ 0x5EED);
        let mut objects = Vec::new();
        let mut used = std::collections::BTreeSet::new();
        let n = 3 + r.below(30);
        let mut indexes = Vec::new();
        for _ in 0..n {
            let index = match r.below(4) {
                0 => 0x1000 + r.below(0x20) as u16,
                1 => 0x2000 + r.below(0x40) as u16,
                2 => 0x6000 + r.below(0x80) as u16,
                _ => 0x1400 + r.below(4) as u16 * 0x200 + r.below(3) as u16,
            };
            if !used.insert(index) {
                continue;
            }
            let name = *r.pick(NAMES);
            let obj = match r.below(3) {
                0 => {
                    let mut o = object(index, name, ObjectType::Var, vec![entry_at(&mut r, 0, name)]);
                    o.subs.values_mut().for_each(|e| e.name = name.to_owned());
                    o
                }
                kind => {
                    let subs = 1 + r.below(6);
                    let mut entries = vec![entry(
                        0,
                        "Highest sub-index supported",
                        D::Unsigned8,
                        Access::Ro,
                        Some(Value::int(subs as i128)),
                        false,
                    )];
                    for s in 1..=subs {
                        let sub_name = if r.chance(40) { name.to_owned() } else { r.pick(NAMES).to_string() };
                        entries.push(entry_at(&mut r, s as u8, &sub_name));
                    }
                    object(index, name, if kind == 1 { ObjectType::Array } else { ObjectType::Record }, entries)
                }
            };
            indexes.push(index);
            objects.push(obj);
        }
        // Default PDO mappings of present, absent and dummy entries, placeholders, wrong lengths.
        for map_index in [0x1600u16, 0x1601, 0x1A00, 0x1A01] {
            if used.contains(&map_index) || !r.chance(60) {
                continue;
            }
            let count = r.below(5);
            let raw: Vec<u32> = (0..count)
                .map(|_| match r.below(5) {
                    0 => 0,
                    1 => 0x0005_0008,
                    _ => {
                        let i = if indexes.is_empty() { 0x7000 } else { *r.pick(&indexes) };
                        let sub = r.below(3) as u32;
                        let bits = *r.pick(&[1u32, 8, 16, 28, 32, 64]);
                        (i as u32) << 16 | sub << 8 | bits
                    }
                })
                .collect();
            let mut m = mapping(map_index, &raw);
            if r.chance(20) {
                // sub 0 counts more entries than there are.
                if let Some(e) = m.subs.values_mut().next() {
                    e.default = Some(Value::hex(0xFE));
                }
            }
            objects.push(m);
        }
        super::common::model(objects)
    }
}
