//! One fixture per diagnostic code (`fixtures/diag/EXXXX.eds`, each the conformant
//! `fixtures/base.eds` with one mistake): the code is reported, with the severity the code table
//! promises in each mode, and the rendered output is snapshot.

use std::path::{Path, PathBuf};

use eds::{Options, Severity, codes};

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures")
}

/// Reads a fixture under a short, machine-independent name.
fn read(path: &Path, options: &Options) -> eds::Parsed {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or("fixture.eds");
    eds::parse(name, &bytes, options)
}

#[test]
fn base_fixture_is_clean_even_in_strict_mode() {
    let parsed = read(&fixtures().join("base.eds"), &Options::strict());
    let text = eds::diag::render_all(&parsed.diagnostics, &parsed.document.source);
    assert!(parsed.diagnostics.is_empty(), "{text}");
    assert_eq!(parsed.model.objects.len(), 9);
}

#[test]
fn every_code_has_a_fixture_that_triggers_it() {
    let mut missing = Vec::new();
    for info in codes::ALL {
        let path = fixtures().join("diag").join(format!("{}.eds", info.code));
        if !path.exists() {
            missing.push(info.code.0);
            continue;
        }
        let lenient = read(&path, &Options::lenient());
        let strict = read(&path, &Options::strict());
        let hit = |p: &eds::Parsed| p.diagnostics.iter().find(|d| d.code == info.code).cloned();
        let l = hit(&lenient).unwrap_or_else(|| panic!("{} not reported: {:#?}", info.code, lenient.diagnostics));
        let s = hit(&strict).unwrap_or_else(|| panic!("{} not reported in strict mode", info.code));
        assert_eq!(l.severity, info.lenient, "{} lenient severity", info.code);
        let want = if info.deviation { Severity::Error } else { info.lenient };
        assert_eq!(s.severity, want, "{} strict severity", info.code);
        assert!(l.span.is_none() || l.at.is_some(), "{}: a span comes with a line and column", info.code);
        // Strict mode reports the same problems, only more severely.
        assert_eq!(lenient.diagnostics.len(), strict.diagnostics.len(), "{}", info.code);
        // The model is built either way.
        assert_eq!(lenient.model, strict.model, "{}", info.code);
    }
    assert!(missing.is_empty(), "codes without a fixture: {missing:?}");
}

#[test]
fn no_fixture_without_a_code() {
    for entry in std::fs::read_dir(fixtures().join("diag")).expect("fixtures/diag") {
        let path = entry.expect("dir entry").path();
        let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or_default().to_owned();
        assert!(codes::ALL.iter().any(|c| c.code.0 == stem), "{} names no code", path.display());
    }
}

#[test]
fn rendered_diagnostics() {
    for info in codes::ALL {
        let path = fixtures().join("diag").join(format!("{}.eds", info.code));
        let parsed = read(&path, &Options::lenient());
        let text = eds::diag::render_all(&parsed.diagnostics, &parsed.document.source);
        insta::assert_snapshot!(format!("diag_{}", info.code), text);
    }
}

#[test]
fn diagnostics_come_in_file_order() {
    for info in codes::ALL {
        let parsed = read(&fixtures().join("diag").join(format!("{}.eds", info.code)), &Options::lenient());
        let starts: Vec<u32> = parsed.diagnostics.iter().map(|d| d.span.map(|s| s.start).unwrap_or(u32::MAX)).collect();
        let mut sorted = starts.clone();
        sorted.sort();
        assert_eq!(starts, sorted, "{}", info.code);
    }
}

#[test]
fn json_output() {
    let parsed = read(&fixtures().join("diag/E0303.eds"), &Options::strict());
    let json = eds::diag::to_json(&parsed.diagnostics);
    let v: serde_json::Value = serde_json::from_str(&json).expect("valid JSON");
    let d = &v[0];
    assert_eq!(d["code"], "E0303");
    assert_eq!(d["severity"], "warning");
    assert_eq!(d["deviation"], false);
    assert_eq!(d["file"], "E0303.eds");
    assert!(d["at"]["line"].as_u64().is_some_and(|l| l > 1));
    insta::assert_snapshot!("json_E0303", json);
}

#[test]
fn rustc_like_layout() {
    let parsed = read(&fixtures().join("diag/E0301.eds"), &Options::strict());
    let d = parsed.diagnostics.iter().find(|d| d.code == codes::E0301).expect("E0301");
    let text = eds::diag::render(d, &parsed.document.source);
    let lines: Vec<&str> = text.lines().collect();
    assert!(lines[0].starts_with("error[E0301]: DefaultValue `fast` cannot be read as UNSIGNED16"), "{text}");
    assert!(lines[1].trim_start().starts_with("--> E0301.eds:"), "{text}");
    let src_line = lines.iter().position(|l| l.ends_with("| DefaultValue=fast")).expect("source line");
    let caret = lines[src_line + 1];
    let col = caret.find('^').expect("caret");
    assert_eq!(&lines[src_line][col..col + 4], "fast");
    assert_eq!(caret.matches('^').count(), 4);
    assert!(text.contains("= note: in object 0x2000 \"Target speed\""), "{text}");
    assert!(text.contains("= help: "), "{text}");
}

#[test]
fn breadcrumbs_name_object_and_sub() {
    let parsed = read(&fixtures().join("diag/E0210.eds"), &Options::lenient());
    let d = parsed.diagnostics.iter().find(|d| d.code == codes::E0210).expect("E0210");
    assert_eq!(d.context, vec!["object 0x1018 \"Identity Object\"", "sub 0 \"Highest sub-index supported\""]);
}

#[test]
fn hints_for_known_misspellings() {
    let hint = |code: &str, c| {
        let parsed = read(&fixtures().join(format!("diag/{code}.eds")), &Options::lenient());
        parsed.diagnostics.iter().find(|d| d.code == c).and_then(|d| d.hint.clone()).unwrap_or_default()
    };
    assert_eq!(hint("E0104", codes::E0104), "write `BaudRate_500`");
    assert!(hint("E0303", codes::E0303).contains("`10`"));
    assert!(hint("E0303", codes::E0303).contains("`0x8`"));
    let parsed = read(&fixtures().join("features/compact.dcf"), &Options::lenient());
    let d = parsed.diagnostics.iter().find(|d| d.code == codes::E0103).expect("E0103");
    assert!(d.hint.as_deref().unwrap_or_default().contains("[DeviceComissioning]"));
}
