//! `odgen gen`, run as a real process: the same bytes as `od_codegen::Builder` for the same
//! file and settings (the project's devices with their sidecars, od-codegen's fixtures, and
//! every file of `$EDS_CORPUS_DIR` when it is set), exit 1 on errors, 2 on usage errors and
//! unreadable files.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap().to_path_buf()
}

/// Runs `odgen` in the workspace root, so relative paths name files as the Builder shows them.
fn odgen(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_odgen")).args(args).current_dir(root()).output().expect("run odgen")
}

fn builder_text(file: &str, module: &str, strict: bool, embed: bool, client: bool) -> String {
    let mut b = od_codegen::Builder::new()
        .root(root())
        .cargo_metadata(false)
        .embed_eds(embed)
        .client(client)
        .device(module, file);
    if strict {
        b = b.strict();
    }
    let mut all = b.generate_all();
    all.pop().unwrap().unwrap_or_else(|e| panic!("{file}: {e}")).text
}

fn same_as_builder(file: &str, extra: &[&str]) {
    let stem = Path::new(file).file_stem().unwrap().to_str().unwrap();
    let module = od_codegen::ident::snake(stem).unwrap();
    let mut args = vec!["gen", file];
    args.extend_from_slice(extra);
    let out = odgen(&args);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{file}: {stderr}");
    let expected = builder_text(
        file,
        &module,
        extra.contains(&"--strict"),
        extra.contains(&"--embed-eds"),
        extra.contains(&"--client"),
    );
    assert!(out.stdout == expected.as_bytes(), "{file}: odgen gen differs from the Builder");
    assert!(stderr.contains(&format!("generated {module}.rs from {file}:")), "{stderr}");
}

#[test]
fn the_devices_and_fixtures_match_the_builder_byte_for_byte() {
    for d in ["devices/camozzi-drvi.eds", "devices/camozzi-drcs.eds", "devices/kollmorgen-akd.eds"] {
        same_as_builder(d, &["--strict", "--embed-eds"]);
        same_as_builder(d, &["--client"]);
    }
    same_as_builder("od-codegen/tests/fixtures/mini.eds", &[]);
    same_as_builder("od-codegen/tests/fixtures/vendor-quirks.eds", &[]);
}

#[test]
fn every_corpus_file_matches_the_builder_byte_for_byte() {
    let Some(dir) = std::env::var_os("EDS_CORPUS_DIR") else {
        println!("SKIPPED: EDS_CORPUS_DIR is not set");
        return;
    };
    let dir = root().join(dir); // an absolute path stays as it is
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .filter(|p| matches!(p.extension().and_then(|e| e.to_str()), Some("eds" | "dcf")))
        .collect();
    files.sort();
    assert!(!files.is_empty());
    for f in &files {
        let shown = f.to_str().unwrap();
        same_as_builder(shown, &[]);
    }
    println!("{} corpus files: odgen gen = Builder", files.len());
}

#[test]
fn errors_exit_1_and_write_nothing_usage_errors_exit_2() {
    let out_file = std::env::temp_dir().join(format!("odgen-gen-{}.rs", std::process::id()));
    let out_arg = out_file.to_str().unwrap();
    let quirks = "od-codegen/tests/fixtures/vendor-quirks.eds";

    // Lenient: warnings, the file is written.
    let out = odgen(&["gen", quirks, "--module", "io", "-o", out_arg]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(0), "{stderr}");
    assert!(
        stderr.contains("warning[G0108]") && stderr.contains("--> od-codegen/tests/fixtures/vendor-quirks.eds:"),
        "{stderr}"
    );
    assert!(out.stdout.is_empty());
    let text = std::fs::read_to_string(&out_file).unwrap();
    assert_eq!(text, builder_text(quirks, "io", false, false, false));
    std::fs::remove_file(&out_file).unwrap();

    // Strict: the same deviations as errors, exit 1, nothing written.
    let out = odgen(&["gen", quirks, "--strict", "-o", out_arg]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("error[G0108]") && stderr.contains("9 errors"), "{stderr}");
    assert!(!out_file.exists());

    // Usage errors and unreadable files: 2.
    assert_eq!(odgen(&["gen"]).status.code(), Some(2));
    assert_eq!(odgen(&["gen", quirks, "--no-such-flag"]).status.code(), Some(2));
    assert_eq!(odgen(&["gen", "no/such/file.eds"]).status.code(), Some(2));
    assert_eq!(odgen(&["gen", quirks, "--sidecar", "no/such/sidecar.toml"]).status.code(), Some(1));
}

/// `-o` writes as `fmt` and `dcf -o` do: through a symbolic link to its target (the link
/// stays a link), keeping the target's mode; a device or a read-only file is refused and left
/// as it was; `-o -` is standard output.
#[cfg(unix)]
#[test]
fn output_files_are_written_safely() {
    use std::os::unix::fs::PermissionsExt as _;
    let dir = std::env::temp_dir().join(format!("odgen-gen-out-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let file = "od-codegen/tests/fixtures/mini.eds";
    let expected = builder_text(file, "mini", false, false, false);

    let target = dir.join("target.rs");
    std::fs::write(&target, "old").unwrap();
    std::fs::set_permissions(&target, std::fs::Permissions::from_mode(0o600)).unwrap();
    let link = dir.join("link.rs");
    std::os::unix::fs::symlink(&target, &link).unwrap();
    let out = odgen(&["gen", file, "-o", link.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(std::fs::symlink_metadata(&link).unwrap().file_type().is_symlink(), "the link stays a link");
    assert_eq!(std::fs::read_to_string(&target).unwrap(), expected);
    assert_eq!(std::fs::metadata(&target).unwrap().permissions().mode() & 0o777, 0o600);

    let read_only = dir.join("ro.rs");
    std::fs::write(&read_only, "keep").unwrap();
    std::fs::set_permissions(&read_only, std::fs::Permissions::from_mode(0o444)).unwrap();
    let out = odgen(&["gen", file, "-o", read_only.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("read-only"));
    assert_eq!(std::fs::read_to_string(&read_only).unwrap(), "keep");

    let out = odgen(&["gen", file, "-o", "-"]);
    assert_eq!(out.status.code(), Some(0));
    assert!(out.stdout == expected.as_bytes());
    let _ = std::fs::remove_dir_all(&dir);
}
