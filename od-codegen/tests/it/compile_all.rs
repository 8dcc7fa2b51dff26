//! "The tokens always compile": the code generated for every file of the EDS corpus
//! (`$EDS_CORPUS_DIR`, skipped with a message when unset) and for every fixture of this crate,
//! bad ones included, each with its client (the master's view, `Builder::client`), goes into
//! `#![no_std]` crates on `od-master`, a module per file, which `cargo check` must accept with
//! warnings denied.
//!
//! Generation is lenient (the default): every file the reader loads without errors must
//! generate without errors. Beside the files, the crates hold models built at random (a fixed
//! seed, so a failure reproduces) from the parts real files get wrong: names that collide or
//! are keywords, ordinals, non-ASCII, defaults and limits outside the type (REAL32 beyond
//! `f32`, NaN), `$NODEID` values, unsupported types, and PDO mappings of absent, unmappable,
//! mistyped and placeholder entries. Everything is generated on the text path (`expand_text`,
//! the Builder's), which `text_path.rs` holds byte for byte to the token path (`expand` and
//! `render`) on these same files and random models (the clients on the random models). The
//! crates, two halves of one workspace, live in the target directory
//! (`target/od-codegen-compile-all`) and are checked in trybuild's (`target/tests/trybuild`);
//! files are written only when they change, so a run with nothing changed checks nothing
//! again. The check is not incremental: a change rechecks a half whole (about 15 s), less than
//! one incremental fresh check.

use crate::common;

use common::{description_files, workspace_root};

use std::path::{Path, PathBuf};
use std::process::Command;

use od_codegen::{Builder, Severity};

fn target_dir() -> PathBuf {
    match std::env::var_os("CARGO_TARGET_DIR") {
        Some(d) => {
            let d = PathBuf::from(d);
            if d.is_absolute() { d } else { workspace_root().join(d) }
        }
        None => workspace_root().join("target"),
    }
}

// trybuild's flags (the file says why they are shared).
#[path = "../../../ui-tests/tests/shared/trybuild_flags.rs"]
mod trybuild_flags;

/// This machine's target triple (`rustc -vV`), as trybuild passes it to its builds.
fn host_triple() -> String {
    let out = Command::new("rustc").arg("-vV").output().expect("run rustc -vV");
    let text = String::from_utf8_lossy(&out.stdout);
    text.lines().find_map(|l| l.strip_prefix("host: ")).expect("rustc -vV names the host").to_owned()
}

/// The generated crate's two halves, packages of one workspace: `cargo check` of one crate of
/// ~50 MB is one core's work (25 s, 2026-12-07), and runs after the dependencies, when the
/// suite's other tests have ended; two halves of it took 15 s on two cores, for 2 s more of CPU.
const HALVES: [&str; 2] = ["od-codegen-compile-all-a", "od-codegen-compile-all-b"];

/// `cargo check` of the generated crates of the workspace at `krate`, in trybuild's target directory
/// (`target/tests/trybuild`, see ui-tests/tests/ui.rs) with trybuild's settings: the crate has
/// the dependencies of trybuild's project (od-master and od-runtime, which its code names, and
/// the reader, the generator and the proc macro, which it does not), checked for this
/// machine's triple with trybuild's flags, so cargo resolves the same features and the two
/// projects check their dependencies once (tokio, serde, the reader, od-master: about 40 s of
/// CPU) instead of once each. trybuild's flags change no check here: `-A dead_code` is what the
/// generated modules allow themselves, the rest is a cfg nothing reads and the output's form.
/// Incremental compilation is off for these crates only (a fresh check of ~50 MB of source costs
/// three times more with it); the dependencies keep the outer `cargo test`'s setting, as
/// trybuild's build of them does.
fn check(krate: &Path) -> std::process::Output {
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    Command::new(cargo)
        .arg("check")
        .arg("--quiet")
        .arg("--offline")
        .arg("--manifest-path")
        .arg(krate.join("Cargo.toml"))
        .arg("--target-dir")
        .arg(target_dir().join("tests").join("trybuild"))
        .arg("--target")
        .arg(host_triple())
        .arg("--workspace")
        .args(
            HALVES.iter().flat_map(|h| ["--config".to_owned(), format!("profile.dev.package.{h}.incremental = false")]),
        )
        .env_remove("RUSTFLAGS")
        .env("CARGO_ENCODED_RUSTFLAGS", trybuild_flags::TRYBUILD_FLAGS)
        .env_remove("CARGO_TARGET_DIR")
        .env_remove("CARGO_BUILD_TARGET_DIR")
        .output()
        .expect("run cargo check")
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

/// The dictionary text of `client`, the same description's code with its client: the client
/// is the dictionary's module with a `remote` module added before its closing brace, so the
/// text before that is `plain`'s, byte for byte (what makes checking the clients a check of the
/// dictionaries too). `Err` says where they part.
fn client_adds_only_remote(plain: &str, client: &str) -> Result<(), String> {
    let Some(head) = plain.trim_end().strip_suffix('}') else {
        return Err("the dictionary's code does not end with its module's closing brace".to_owned());
    };
    let Some(rest) = client.strip_prefix(head) else {
        let at = plain.bytes().zip(client.bytes()).take_while(|(a, b)| a == b).count();
        let line = plain[..at].lines().count();
        return Err(format!("the client's code differs from the dictionary's at line {line}"));
    };
    if !rest.contains("pub mod remote {") || !rest.trim_end().ends_with('}') {
        return Err("the client adds something other than a `remote` module".to_owned());
    }
    Ok(())
}

/// Every corpus file, every fixture (those with reader errors too: their code is still what the
/// tokens are) and random models generate a dictionary and a client (`Builder::client`), and
/// the three devices theirs with their sidecars (units, PDO layouts); all of it goes into two
/// `#![no_std]` crates on `od-master` ([`HALVES`] of about the same size, each with the program
/// written against the standard names), a module per description, which `cargo check` must
/// accept with warnings denied (`target/od-codegen-compile-all`, checked in trybuild's target
/// directory: [`check`]). A client is its dictionary with a `remote` module added
/// ([`client_adds_only_remote`], checked against a generation without the client for every
/// description that has one), so the crate checks the dictionaries as a firmware gets them, in a
/// crate without `std`, and the clients as a master gets them: the client's code names nothing
/// of `std` but through `od_master`. The same crates rather than crates of dictionaries and crates
/// of clients: the dictionaries, 80% of the clients' code, were checked twice (21 s of one core,
/// 2026-12-07).
#[test]
fn every_description_generates_code_and_a_client_that_compile_with_warnings_denied() {
    let root = workspace_root();
    let mut files = description_files(&Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures"));
    let fixtures = files.len();
    if let Some(c) = corpus() {
        files.extend(c);
    }
    let krate = target_dir().join("od-codegen-compile-all");
    let src = krate.join("src");
    std::fs::create_dir_all(&src).unwrap();
    // The same descriptions without and with the client, to hold the two to each other.
    let mut plain = Builder::new().cargo_metadata(false).out_dir(&src);
    let mut builder = Builder::new().cargo_metadata(false).client(true).out_dir(&src);
    let mut modules = Vec::new();
    let mut read_errors = Vec::new();
    let mut failures = Vec::new();
    // The vendor files' own methods of CiA 402's motion objects, typed by dimension without a
    // sidecar, and a program written once against the standard names, used with every drive's
    // client (the corpus's CiA 402 files, the project's DRVI, DRCS and AKD).
    let mut standard_users = std::collections::BTreeMap::new();
    let mut drives = Vec::new();
    // Each corpus module's objects, to check that every PDO method has both its objects.
    let mut pdo_objects: std::collections::BTreeMap<String, std::collections::BTreeSet<u16>> = Default::default();
    let mut pdo_methods = 0;
    for (i, f) in files.iter().enumerate() {
        // Files the reader refuses are not the generator's to build (a corpus file with reader
        // errors would show up in eds/tests/corpus.rs); bad fixtures have errors by design, and
        // their code must compile all the same, so they are read leniently too, and their
        // dictionary is written through `expand` (the Builder refuses a file with errors; a
        // client is for a description a master can trust, so they get none).
        let parsed = eds::read_file(f, &eds::Options::lenient()).unwrap();
        let m = module_name(i, f);
        if parsed.has_errors() {
            if i >= fixtures {
                read_errors.push(f.display().to_string());
                continue;
            }
            let g = od_codegen::expand_text(&parsed.model, &od_codegen::Options::new(m.clone(), m.clone()));
            assert!(
                g.diagnostics.iter().all(|d| d.severity != Severity::Error || d.code.0.starts_with("G02")),
                "{m}: {}",
                od_codegen::diag::render_plain(&g.diagnostics)
            );
            let text = g.render(&m).unwrap();
            od_codegen::write_if_changed(&src.join(format!("{m}.rs")), &text).unwrap();
            modules.push(m);
            continue;
        }
        plain = plain.device(&m, f).no_sidecar();
        builder = builder.device(&m, f).no_sidecar();
        standard_users.insert(m.clone(), typed_by_dimension(&m, &parsed.model));
        pdo_objects.insert(m.clone(), parsed.model.objects.keys().map(|i| i.0).collect());
        if od_codegen::standard::has_cia402(&parsed.model) {
            drives.push(m.clone());
        }
        modules.push(m);
    }
    assert!(read_errors.is_empty(), "corpus files the reader refuses: {read_errors:#?}");
    for (m, file) in [("drvi", "camozzi-drvi.eds"), ("drcs", "camozzi-drcs.eds"), ("akd", "kollmorgen-akd.eds")] {
        builder = builder.device(m, root.join("devices").join(file));
        modules.push(m.to_owned());
        drives.push(m.to_owned());
    }

    // Generation is lenient (the default): every file the reader loads without errors must
    // generate without errors.
    let started = std::time::Instant::now();
    let plain: std::collections::BTreeMap<String, _> = plain
        .generate_each()
        .into_iter()
        .map(|r| r.map(|o| (o.module.clone(), o)))
        .collect::<Result<_, _>>()
        .unwrap_or_else(|e| panic!("lenient generation failed: {e}"));
    let mut deviations = 0usize;
    for r in builder.generate_each() {
        match r {
            Ok(o) => {
                if let Some(p) = plain.get(&o.module) {
                    deviations +=
                        p.diagnostics.iter().filter(|d| od_codegen::diag::DEVIATIONS.contains(&d.code)).count();
                    if let Err(e) = client_adds_only_remote(&p.text, &o.text) {
                        failures.push(format!("{}: {e}", o.module));
                    }
                }
                if let Some(objects) = pdo_objects.get(&o.module) {
                    for (comm, mapping) in pdo_methods_objects(&o.text) {
                        pdo_methods += 1;
                        for index in [comm, mapping] {
                            if !objects.contains(&index) {
                                failures.push(format!(
                                    "{}: a PDO method whose object {index:04X}h is not in the description",
                                    o.module
                                ));
                            }
                        }
                    }
                }
                od_codegen::write_if_changed(&src.join(&o.file_name), &o.text).unwrap();
            }
            Err(e) => failures.push(e.to_string()),
        }
    }
    let generated_in = started.elapsed();
    assert!(failures.is_empty(), "lenient generation failed:\n{}", failures.join("\n\n"));
    assert!(pdo_methods > 0 || corpus().is_none(), "the corpus gives PDO methods");

    // `ODCODEGEN_RANDOM_MODELS=N` checks more (or fewer) of them.
    let random_models: u64 = std::env::var("ODCODEGEN_RANDOM_MODELS").ok().and_then(|n| n.parse().ok()).unwrap_or(40);
    for seed in 0..random_models {
        let m = format!("random_{seed:02}");
        let model = common::random::model(seed);
        let mut options = od_codegen::Options::new(m.clone(), format!("{m}.eds"));
        let dictionary = od_codegen::expand_text(&model, &options);
        let errors: Vec<_> = dictionary.diagnostics.iter().filter(|d| d.severity == Severity::Error).cloned().collect();
        assert!(errors.is_empty(), "seed {seed}: {}", od_codegen::diag::render_plain(&errors));
        let dictionary = dictionary.render(&m).unwrap_or_else(|e| panic!("seed {seed}: {e}"));
        options.client = true;
        let text = od_codegen::expand_text(&model, &options).render(&m).unwrap_or_else(|e| panic!("seed {seed}: {e}"));
        client_adds_only_remote(&dictionary, &text).unwrap_or_else(|e| panic!("seed {seed}: {e}"));
        od_codegen::write_if_changed(&src.join(format!("{m}.rs")), &text).unwrap();
        modules.push(m);
    }

    // The modules split into two halves of about the same size, each with the program written
    // against the standard names and its drives' uses of it.
    let mut halves: [(u64, Vec<&String>); 2] = Default::default();
    let mut by_size: Vec<(u64, &String)> =
        modules.iter().map(|m| (std::fs::metadata(src.join(format!("{m}.rs"))).unwrap().len(), m)).collect();
    by_size.sort_by(|a, b| b.cmp(a));
    for (size, m) in by_size {
        let half = if halves[0].0 <= halves[1].0 { 0 } else { 1 };
        halves[half].0 += size;
        halves[half].1.push(m);
    }
    // The dependencies of trybuild's project (ui-tests' dev-dependencies): the code names
    // od_master and od_runtime only; the other three make cargo resolve the features trybuild's
    // project gets, so that both check against the same compiled dependencies (`check`).
    // od-runtime's features are its defaults either way, as the dictionaries' alone would get.
    let dependencies = format!(
        "[dependencies]\nod-runtime = {{ path = {:?} }}\nod-master = {{ path = {:?} }}\n\
         eds = {{ path = {:?}, package = \"canopen-eds\" }}\nod-codegen = {{ path = {:?} }}\nod-macros = {{ path = {:?} }}\n",
        root.join("od-runtime").display().to_string(),
        root.join("od-master").display().to_string(),
        root.join("eds").display().to_string(),
        root.join("od-codegen").display().to_string(),
        root.join("od-macros").display().to_string()
    );
    for (name, (_, half)) in HALVES.iter().zip(&halves) {
        let dir = krate.join(name);
        std::fs::create_dir_all(&dir).unwrap();
        let mut lib = String::from(
            "//! Half of the descriptions' generated modules with their clients (written by od-codegen's tests/compile_all.rs).\n\
             #![no_std]\n#![deny(warnings)]\n\n",
        );
        for m in half {
            lib.push_str(&format!("include!(\"../src/{m}.rs\");\n"));
        }
        lib.push_str(STANDARD_USER);
        lib.push_str("\n/// Every drive's client through the one program.\npub fn every_drive() {\n");
        for d in drives.iter().filter(|d| half.contains(d)) {
            lib.push_str(&format!("    let _ = standard_user::move_to::<{d}::remote::Remote>;\n"));
        }
        lib.push_str("}\n");
        for m in half {
            lib.push_str(standard_users.get(*m).map_or("", String::as_str));
        }
        od_codegen::write_if_changed(&dir.join("lib.rs"), &lib).unwrap();
        let manifest = format!(
            "[package]\nname = \"{name}\"\nversion = \"0.0.0\"\nedition = \"2024\"\npublish = false\n\n\
             [lib]\npath = \"lib.rs\"\n\n{dependencies}"
        );
        od_codegen::write_if_changed(&dir.join("Cargo.toml"), &manifest).unwrap();
    }
    // (The crate of an older layout, and the target directory it had of its own.)
    let _ = std::fs::remove_file(src.join("lib.rs"));
    let _ = std::fs::remove_dir_all(krate.join("target"));
    let workspace =
        format!("[workspace]\nresolver = \"3\"\nmembers = [{}]\n", HALVES.map(|h| format!("{h:?}")).join(", "));
    od_codegen::write_if_changed(&krate.join("Cargo.toml"), &workspace).unwrap();
    // The workspace's lock file, so the inner build resolves offline to the versions already built.
    // (Cargo trims it to the crate's dependencies; one without od-master is an older layout's.)
    let lock = std::fs::read_to_string(root.join("Cargo.lock")).unwrap();
    let lock_path = krate.join("Cargo.lock");
    if !std::fs::read_to_string(&lock_path).is_ok_and(|l| l.contains("name = \"od-master\"")) {
        std::fs::write(&lock_path, lock).unwrap();
    }
    let started = std::time::Instant::now();
    let out = check(&krate);
    let stderr = String::from_utf8_lossy(&out.stderr);
    println!(
        "{} descriptions ({fixtures} fixtures, {} random), {deviations} deviations (warnings), {pdo_methods} PDO methods of \
         corpus clients, each with its communication and mapping objects; generated in {:.1?}, checked in {:.1?}",
        modules.len(),
        random_models,
        generated_in,
        started.elapsed()
    );
    assert!(out.status.success(), "the generated code does not compile (crates at {}):\n{stderr}", krate.display());
}

/// A program written once against the standard names (`od_master::profile`), for any drive.
const STANDARD_USER: &str = r#"
/// Written against the standard names only.
pub mod standard_user {
    use od_master::profile::Cia402;
    use od_master::remote::{Quantity, Scaling, dim};

    /// Sets the profile velocity, moves, reads the state and the identity.
    pub async fn move_to<D: Cia402>(
        drive: &D,
        units: &dyn Scaling,
        to: Quantity<dim::Position>,
        speed: Quantity<dim::Velocity>,
    ) -> Result<u16, od_master::Error> {
        drive.profile_velocity()?.write_in(units, speed).await?;
        drive.target_position()?.write_in(units, to).await?;
        drive.controlword()?.write(0x003F).await?;
        let _at: Quantity<dim::Position> = drive.position_actual_value()?.read_in(units).await?;
        let _vendor = drive.vendor_id()?.read().await?;
        drive.statusword()?.read().await
    }

    /// Takes only a handle of a position.
    pub fn position<T, A>(_: &od_master::remote::Object<'_, T, A, dim::Position>) {}
    /// Takes only a handle of a velocity.
    pub fn velocity<T, A>(_: &od_master::remote::Object<'_, T, A, dim::Velocity>) {}
}
"#;

/// For a description's module `m`: a function that hands its own methods of 607Ah, 6064h
/// (positions) and 60FFh, 6081h (velocities) to functions that take only handles of that
/// dimension, so the crate compiles only if they are typed by dimension (no sidecar).
fn typed_by_dimension(m: &str, model: &eds::model::Model) -> String {
    let names = od_codegen::accessor_names(model);
    let name = |index: u16| names.iter().find(|(i, s, _)| *i == index && *s == 0).map(|(_, _, n)| n.clone());
    let mut body = String::new();
    for (index, check) in [(0x607A, "position"), (0x6064, "position"), (0x60FF, "velocity"), (0x6081, "velocity")] {
        let integer = model.entry(index, 0).is_some_and(|e| {
            e.data_type.bits().is_some_and(|b| b > 1 && b <= 64)
                && !matches!(e.data_type, eds::model::DataType::Real32 | eds::model::DataType::Real64)
        });
        if let Some(n) = name(index).filter(|_| integer) {
            body.push_str(&format!("    standard_user::{check}(&r.{n}());\n"));
        }
    }
    if body.is_empty() {
        return String::new();
    }
    format!(
        "\n/// `{m}`'s motion objects, typed by dimension.\npub fn typed_{m}(r: &{m}::remote::Remote) {{\n{body}}}\n"
    )
}

/// The communication and mapping objects of each PDO a generated client has a method for
/// (from its `PdoLayout` impls: `DIRECTION` and `NUMBER`).
fn pdo_methods_objects(text: &str) -> Vec<(u16, u16)> {
    let mut out = Vec::new();
    for block in text.split("impl ::od_master::remote::PdoLayout for").skip(1) {
        let receive = block
            .split("const DIRECTION: ::od_runtime::pdo::Direction = ::od_runtime::pdo::Direction::")
            .nth(1)
            .expect("a PdoLayout impl has DIRECTION")
            .starts_with("Receive");
        let number: u16 = block
            .split("const NUMBER: u16 = ")
            .nth(1)
            .and_then(|r| r.split(';').next())
            .and_then(|n| n.trim().parse().ok())
            .expect("a PdoLayout impl has NUMBER");
        let n = number - 1;
        out.push(if receive { (0x1400 + n, 0x1600 + n) } else { (0x1800 + n, 0x1A00 + n) });
    }
    out
}
