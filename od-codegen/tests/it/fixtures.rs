//! Snapshot tests of the code generated from the fixture device descriptions, and of the
//! diagnostics a broken description gets.

use std::path::Path;

use od_codegen::{Builder, Options, expand, render};

fn fixture(name: &str) -> (String, Vec<u8>) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures").join(name);
    (format!("tests/fixtures/{name}"), std::fs::read(&path).unwrap())
}

fn generate(name: &str) -> (String, od_codegen::Generated, eds::source::SourceFile) {
    generate_with(name, false)
}

fn generate_with(name: &str, strict: bool) -> (String, od_codegen::Generated, eds::source::SourceFile) {
    let (shown, bytes) = fixture(name);
    let parsed = eds::parse(&shown, &bytes, &eds::Options::lenient());
    // The broken fixture also has reader errors (the reader validates PDOs too); the
    // generator must still say what it cannot generate.
    assert!(name.starts_with("bad") || !parsed.has_errors(), "{:#?}", parsed.diagnostics);
    let source = eds::source::SourceFile::decode(shown.clone(), &bytes);
    let mut options = Options::new("mini", shown.clone());
    options.strict = strict;
    options.eds_text = Some(source.text.clone());
    // The sidecar beside the fixture, as the Builder would find it.
    let sidecar = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures").join(name).with_extension("toml");
    if sidecar.is_file() {
        options.sidecar = Some(od_codegen::sidecar::Sidecar::read(&sidecar).unwrap());
    }
    (shown, expand(&parsed.model, &options), source)
}

#[test]
fn mini_snapshot() {
    let (shown, g, source) = generate("mini.eds");
    let text = render(&g.tokens, &shown).unwrap();
    insta::assert_snapshot!("mini", text);
    insta::assert_snapshot!("mini_diagnostics", eds::diag::render_all(&g.diagnostics, &source));
}

#[test]
fn generation_is_byte_for_byte_deterministic() {
    let (shown, a, _) = generate("mini.eds");
    let (_, b, _) = generate("mini.eds");
    assert_eq!(render(&a.tokens, &shown).unwrap(), render(&b.tokens, &shown).unwrap());
}

#[test]
fn broken_pdos_get_located_diagnostics() {
    let (_, g, source) = generate_with("bad-pdo.eds", true);
    assert!(g.has_errors());
    let rendered = eds::diag::render_all(&g.diagnostics, &source);
    // Every diagnostic about a mapping points at a line of the file.
    for d in g.diagnostics.iter().filter(|d| d.code.0.starts_with("G01")) {
        assert!(d.at.is_some(), "{d:?}");
    }
    assert!(rendered.contains("--> tests/fixtures/bad-pdo.eds:"), "{rendered}");
}

/// Every code the generator reports from a device description (G0006, the module name, and
/// G0007, more than 65535 objects, come from the caller and are tested in code).
const DESCRIPTION_CODES: &[eds::diag::Code] = {
    use od_codegen::diag::*;
    &[
        NAME_COLLISION,
        UNSUPPORTED_TYPE,
        BAD_DEFAULT,
        LIMIT_IGNORED,
        NO_VALUE_OBJECT,
        PDO_TOO_LONG,
        PDO_NOT_MAPPABLE,
        PDO_ACCESS,
        PDO_NO_OBJECT,
        PDO_LENGTH,
        PDO_NO_COMM,
        PDO_MALFORMED,
        PDO_VARIABLE,
        PDO_PLACEHOLDER,
        LIMIT_CLIPPED,
        UNITS,
    ]
};

#[test]
fn bad_fixtures_cover_every_code_with_a_snapshot_each() {
    let mut seen = std::collections::BTreeSet::new();
    for name in ["bad-pdo.eds", "bad-codegen.eds", "vendor-quirks.eds"] {
        let (_, g, source) = generate(name);
        seen.extend(g.diagnostics.iter().map(|d| d.code.0));
        let snapshot = format!("{}_diagnostics", name.trim_end_matches(".eds").replace('-', "_"));
        insta::assert_snapshot!(snapshot, eds::diag::render_all(&g.diagnostics, &source));
    }
    for code in DESCRIPTION_CODES {
        assert!(seen.contains(code.0), "no bad fixture shows {}", code.0);
    }
}

#[test]
fn builder_fails_the_build_on_errors_and_names_the_location() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let out = std::env::temp_dir().join(format!("od-codegen-test-{}", std::process::id()));
    let err = Builder::new()
        .root(dir)
        .strict()
        .device("bad", "tests/fixtures/bad-pdo.eds")
        .out_dir(&out)
        .cargo_metadata(false)
        .compile()
        .unwrap_err();
    let text = err.to_string();
    assert!(text.contains("--> tests/fixtures/bad-pdo.eds:"), "{text}");
    assert!(text.contains("error[G0103]"), "{text}");
    assert!(!out.join("bad.rs").exists());
}

#[test]
fn builder_writes_only_when_the_content_changed() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let out = std::env::temp_dir().join(format!("od-codegen-write-{}", std::process::id()));
    let b = Builder::new().root(dir).device("mini", "tests/fixtures/mini.eds").out_dir(&out).cargo_metadata(false);
    b.compile().unwrap();
    let file = out.join("mini.rs");
    let first = std::fs::metadata(&file).unwrap().modified().unwrap();
    std::thread::sleep(std::time::Duration::from_millis(20));
    b.compile().unwrap();
    assert_eq!(std::fs::metadata(&file).unwrap().modified().unwrap(), first, "rewritten without a change");
    std::fs::write(&file, "stale").unwrap();
    b.compile().unwrap();
    let text = std::fs::read_to_string(&file).unwrap();
    assert!(text.starts_with(&format!(
        "// @generated by od-codegen {} from tests/fixtures/mini.eds;",
        env!("CARGO_PKG_VERSION")
    )));
    let _ = std::fs::remove_dir_all(&out);
}

/// The rules real vendor files break, one instance each (`vendor-quirks.eds`): lenient, each is
/// a located warning and the device generates without errors, with no typed layout for the
/// broken mappings (the mapping parameters stay in the dictionary); strict, the very same
/// diagnostics are errors.
#[test]
fn vendor_quirks_are_warnings_when_lenient_and_errors_when_strict() {
    let (shown, lenient, _) = generate_with("vendor-quirks.eds", false);
    let (_, strict, _) = generate_with("vendor-quirks.eds", true);
    assert!(!lenient.has_errors(), "{}", od_codegen::diag::render_plain(&lenient.diagnostics));
    // (code, line and column, message) of each deviation.
    type Deviation = (String, Option<(u32, u32)>, String);
    let deviations = |g: &od_codegen::Generated| -> Vec<Deviation> {
        g.diagnostics
            .iter()
            .filter(|d| od_codegen::diag::DEVIATIONS.contains(&d.code))
            .map(|d| (d.code.0.to_owned(), d.at.map(|a| (a.line, a.col)), d.message.clone()))
            .collect()
    };
    let found = deviations(&lenient);
    assert_eq!(found, deviations(&strict), "strict reports other deviations than lenient");
    for d in lenient.diagnostics.iter().filter(|d| od_codegen::diag::DEVIATIONS.contains(&d.code)) {
        assert_eq!(d.severity, eds::Severity::Warning, "{d:?}");
        assert!(d.at.is_some(), "not located: {d:?}");
    }
    for d in strict.diagnostics.iter().filter(|d| od_codegen::diag::DEVIATIONS.contains(&d.code)) {
        assert_eq!(d.severity, eds::Severity::Error, "{d:?}");
    }
    // One per broken mapping (eight), one clipped limit.
    let codes: Vec<&str> = found.iter().map(|(c, _, _)| c.as_str()).collect();
    assert_eq!(codes, ["G0108", "G0103", "G0105", "G0102", "G0105", "G0106", "G0104", "G0108", "G0008"], "{found:#?}");
    let text = render(&lenient.tokens, &shown).unwrap();
    assert!(!text.contains("pub struct Rpdo") && !text.contains("pub struct Tpdo"), "a broken mapping got a layout");
    // The mapping parameters stay in the dictionary, as data.
    for index in ["0x1600", "0x1601", "0x1A01", "0x1A03"] {
        assert!(text.contains(&format!("index: {index},")), "{index} left the dictionary");
    }
    // The clipped limit: 0x80000000 on an UNSIGNED16 is the type's maximum.
    assert!(text.contains("if v < 65535"), "the limit is not clipped to the type");
}

/// One device's errors never hide another's file, and the error names the failing device.
#[test]
fn builder_errors_are_per_device() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let out = std::env::temp_dir().join(format!("od-codegen-per-device-{}", std::process::id()));
    let err = Builder::new()
        .root(dir)
        .strict()
        .device("bad", "tests/fixtures/bad-pdo.eds")
        .device("good", "tests/fixtures/mini.eds")
        .out_dir(&out)
        .cargo_metadata(false)
        .compile()
        .unwrap_err();
    match &err {
        od_codegen::Error::Device { module, path, .. } => {
            assert_eq!((module.as_str(), path.as_str()), ("bad", "tests/fixtures/bad-pdo.eds"))
        }
        other => panic!("{other:?}"),
    }
    assert!(err.to_string().starts_with("device `bad` (tests/fixtures/bad-pdo.eds) has errors:"), "{err}");
    assert!(out.join("good.rs").is_file(), "the good device's file was not written");
    assert!(!out.join("bad.rs").exists());

    // Two failing devices: both named.
    let err = Builder::new()
        .root(dir)
        .strict()
        .device("bad1", "tests/fixtures/bad-pdo.eds")
        .device("bad2", "tests/fixtures/vendor-quirks.eds")
        .out_dir(&out)
        .cargo_metadata(false)
        .compile()
        .unwrap_err();
    assert!(err.to_string().starts_with("2 devices failed (`bad1`, `bad2`):"), "{err}");
    let _ = std::fs::remove_dir_all(&out);
}

/// What a build script prints: one headline per warning, each with its location.
#[test]
fn builder_warnings_are_one_located_line_each() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let outputs = Builder::new().root(dir).device("io", "tests/fixtures/vendor-quirks.eds").generate().unwrap();
    let o = &outputs[0];
    let warnings = o.diagnostics.iter().filter(|d| d.severity == eds::Severity::Warning).count();
    let lines = o.short_lines(eds::Severity::Warning);
    assert_eq!(lines.len(), warnings);
    // The reader's warnings (E…) and the generator's (G…), as `odgen check` has them.
    assert!(lines.iter().any(|l| l.contains(": warning[G")), "{lines:#?}");
    for l in &lines {
        assert!(l.starts_with("tests/fixtures/vendor-quirks.eds:") && l.contains(": warning["), "{l}");
        assert!(!l.contains("(hint:") && l.len() < 300, "one short line: {l}");
    }
    assert!(!o.text.contains("pub const EDS"), "EDS embedded without embed_eds(true)");
}

/// The header names the description relative to the crate, also when given an absolute path.
#[test]
fn the_header_never_holds_an_absolute_path() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let abs = dir.join("tests/fixtures/mini.eds");
    let outputs = Builder::new().root(dir).device("mini", &abs).generate().unwrap();
    let first = outputs[0].text.lines().next().unwrap();
    assert_eq!(first, od_codegen::header("tests/fixtures/mini.eds"));
    assert!(!first.contains("xtask"));
    let outputs = Builder::new().root(dir.join("src")).device("mini", &abs).generate().unwrap();
    assert_eq!(outputs[0].text.lines().next().unwrap(), od_codegen::header("../tests/fixtures/mini.eds"));
}

#[test]
fn lss_supported_gives_the_dictionary_lss() {
    let (shown, bytes) = fixture("mini.eds");
    let text = String::from_utf8(bytes).unwrap();
    for (value, want) in [("1", true), ("0", false)] {
        let edited = if text.contains("LSS_Supported=") {
            text.replace("LSS_Supported=0", &format!("LSS_Supported={value}"))
                .replace("LSS_Supported=1", &format!("LSS_Supported={value}"))
        } else {
            text.replacen("[DeviceInfo]", &format!("[DeviceInfo]\nLSS_Supported={value}"), 1)
        };
        let parsed = eds::parse(&shown, edited.as_bytes(), &eds::Options::lenient());
        assert_eq!(parsed.model.device_info.lss_supported, Some(want));
        let g = expand(&parsed.model, &Options::new("mini", shown.clone()));
        let out = render(&g.tokens, &shown).unwrap();
        assert_eq!(out.contains("const LSS: bool = true;"), want, "LSS_Supported={value}");
    }
}
