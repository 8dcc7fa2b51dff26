//! A build script with `od_codegen::Builder` says each diagnostic of a file once per change of
//! the file, not on every build (Cargo replays a cached build script's `cargo:warning` lines,
//! so the builder arranges one silent rerun after a change: see `Builder::compile`); an
//! allowed code is not printed; the codes printed are `odgen check --format json`'s for the
//! same file.
//!
//! The project lives in the target directory (`target/odgen-build-once`). It builds in the
//! target directory of trybuild's project (`target/tests/trybuild`, see ui-tests/tests/ui.rs),
//! kept between runs: its build script's dependencies (od-codegen, the reader, syn,
//! prettyplease, serde) are the host side of od-macros there, compiled with the same settings
//! (no flags: trybuild's apply to its target's units only), so the workspace's tests compile
//! that chain once, not once for each project (a fresh run of this test took 36 s, about half
//! of it building the chain). A run compiles the project's build script once, then only
//! reruns it.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap().to_path_buf()
}

/// `cargo build` of the project at `krate` in `target_dir`. `CARGO_INCREMENTAL` is left as the
/// outer `cargo test` has it, as trybuild leaves it: it is part of each local crate's
/// fingerprint, so two settings would rebuild the shared chain in turn.
fn cargo_build(krate: &Path, target_dir: &Path) -> String {
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let out = Command::new(cargo)
        .args(["build", "--offline", "--manifest-path"])
        .arg(krate.join("Cargo.toml"))
        .arg("--target-dir")
        .arg(target_dir)
        .env_remove("RUSTFLAGS")
        .env_remove("CARGO_ENCODED_RUSTFLAGS")
        .env_remove("CARGO_TARGET_DIR")
        .env_remove("CARGO_BUILD_TARGET_DIR")
        .env("CARGO_TERM_COLOR", "never")
        .output()
        .expect("run cargo build");
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "the build failed:\n{stderr}");
    stderr
}

/// The codes of the build script's warning lines (`warning: build-once@0.0.0: …
/// warning[G0108]: …`).
fn build_codes(stderr: &str) -> Vec<String> {
    stderr
        .lines()
        .filter(|l| l.starts_with("warning: build-once@"))
        .filter_map(|l| l.split_once("warning[").and_then(|(_, r)| r.split_once(']')).map(|(c, _)| c.to_owned()))
        .collect()
}

#[test]
fn a_build_script_reports_each_diagnostic_once_allowed_codes_never_and_the_codes_of_odgen_check() {
    let root = root();
    let target = std::env::var_os("CARGO_TARGET_DIR").map(PathBuf::from).unwrap_or_else(|| root.join("target"));
    let target = if target.is_absolute() { target } else { root.join(target) };
    let krate = target.join("odgen-build-once");
    let target_dir = target.join("tests").join("trybuild");
    std::fs::create_dir_all(krate.join("src")).unwrap();
    let manifest = format!(
        "[package]\nname = \"build-once\"\nversion = \"0.0.0\"\nedition = \"2024\"\npublish = false\n\n\
         [dependencies]\nod-runtime = {{ path = {:?} }}\n\n[build-dependencies]\nod-codegen = {{ path = {:?} }}\n\n[workspace]\n",
        root.join("od-runtime").display().to_string(),
        root.join("od-codegen").display().to_string()
    );
    od_codegen::write_if_changed(&krate.join("Cargo.toml"), &manifest).unwrap();
    if !krate.join("Cargo.lock").exists() {
        std::fs::copy(root.join("Cargo.lock"), krate.join("Cargo.lock")).unwrap();
    }
    let build_rs = "fn main() {\n    od_codegen::Builder::new()\n        .device(\"quirks\", \"quirks.eds\")\n        \
                    .allow(\"G0105\")\n        .compile()\n        .unwrap_or_else(|e| panic!(\"{e}\"));\n}\n";
    od_codegen::write_if_changed(&krate.join("build.rs"), build_rs).unwrap();
    od_codegen::write_if_changed(
        &krate.join("src/lib.rs"),
        "#![no_std]\ninclude!(concat!(env!(\"OUT_DIR\"), \"/quirks.rs\"));\n",
    )
    .unwrap();
    // The file changes on every run (a comment with the time), so the first build below is
    // the first after a change, whatever a previous run left.
    let quirks = std::fs::read_to_string(root.join("od-codegen/tests/fixtures/vendor-quirks.eds")).unwrap();
    let stamp = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).unwrap().as_nanos();
    std::fs::write(krate.join("quirks.eds"), format!("{quirks}\n; run {stamp}\n")).unwrap();

    let first = cargo_build(&krate, &target_dir);
    let codes = build_codes(&first);
    assert!(!codes.is_empty(), "the first build after a change shows the warnings:\n{first}");
    assert!(!codes.iter().any(|c| c == "G0105"), "an allowed code is not printed:\n{first}");
    for l in first.lines().filter(|l| l.starts_with("warning: build-once@") && l.contains("warning[")) {
        assert!(l.len() < 300, "one short line each: {l}");
    }
    let second = cargo_build(&krate, &target_dir);
    assert!(build_codes(&second).is_empty(), "not again on the second build:\n{second}");
    let third = cargo_build(&krate, &target_dir);
    assert!(build_codes(&third).is_empty(), "nor on the third:\n{third}");
    assert!(!third.contains("Compiling build-once"), "the third build reruns nothing:\n{third}");

    // The same codes as `odgen check --format json --allow G0105` (at the build's level:
    // warnings and errors).
    let out = Command::new(env!("CARGO_BIN_EXE_odgen"))
        .args(["check", "--format", "json", "--level", "warning", "--allow", "G0105", "quirks.eds"])
        .current_dir(&krate)
        .output()
        .unwrap();
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).expect("odgen check's JSON");
    let checked: Vec<String> = json["files"][0]["diagnostics"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| d["code"].as_str().unwrap().to_owned())
        .collect();
    let (a, b): (BTreeSet<&String>, BTreeSet<&String>) = (codes.iter().collect(), checked.iter().collect());
    assert_eq!(a, b, "the build's codes and odgen check's");
    let (mut a, mut b) = (codes.clone(), checked.clone());
    a.sort();
    b.sort();
    assert_eq!(a, b, "as many of each");
}
