//! What `odgen check` prints: levels (notes counted, shown on request), JSON that keeps
//! everything, and SARIF 2.1.0 whose structure is checked against the standard's rules.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use serde_json::Value;

fn odgen(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_odgen")).args(args).output().expect("run odgen")
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../eds/tests/fixtures").join(name)
}

/// Every diagnostic fixture: together they have errors, warnings and notes.
fn all_fixtures() -> Vec<String> {
    let mut v: Vec<String> =
        std::fs::read_dir(fixture("diag")).unwrap().map(|e| e.unwrap().path().to_string_lossy().into_owned()).collect();
    v.sort();
    v
}

fn json(o: &Output) -> Value {
    serde_json::from_slice(&o.stdout).unwrap_or_else(|e| panic!("not JSON ({e}): {}", stdout(o)))
}

/// Counts of `error[`, `warning[` and `note[` headings in human output.
fn headings(text: &str) -> [usize; 3] {
    ["error[", "warning[", "note["].map(|h| text.lines().filter(|l| l.starts_with(h)).count())
}

/// Human output prints errors and warnings and counts the notes in the summary; `--notes` (or
/// `--level note`) prints them too, `--level error` only errors. JSON keeps everything. The
/// counts in every form agree.
#[test]
fn levels_hide_notes_by_default_and_json_keeps_them() {
    let files = all_fixtures();
    let run = |extra: &[&str]| {
        let mut args = vec!["check", "--jobs", "2"];
        args.extend(extra);
        args.extend(files.iter().map(String::as_str));
        odgen(&args)
    };
    let v = json(&run(&["--format", "json"]));
    let total = |k: &str| v[k].as_u64().unwrap() as usize;
    let (errors, warnings, notes) = (total("errors"), total("warnings"), total("notes"));
    assert!(errors > 0 && warnings > 0 && notes > 0, "{v:#}");
    let listed: usize = v["files"].as_array().unwrap().iter().map(|f| f["diagnostics"].as_array().unwrap().len()).sum();
    assert_eq!(listed, errors + warnings + notes, "JSON lists every diagnostic");

    let default = stdout(&run(&[]));
    assert_eq!(headings(&default), [errors, warnings, 0], "{default}");
    let summary = default.lines().last().unwrap();
    assert!(summary.contains(&format!("{notes} notes (not shown; --notes shows them)")), "{summary}");
    for flag in [&["--notes"][..], &["--level", "note"]] {
        let all = stdout(&run(flag));
        assert_eq!(headings(&all), [errors, warnings, notes], "{flag:?}");
        assert!(!all.contains("not shown"), "{flag:?}");
    }
    let only_errors = stdout(&run(&["--level", "error"]));
    assert_eq!(headings(&only_errors), [errors, 0, 0]);
    assert!(only_errors.contains(&format!("{warnings} warnings (not shown")), "{only_errors}");
    // JSON restricted by an explicit level lists less but counts the same.
    let v = json(&run(&["--format", "json", "--level", "warning"]));
    let listed: usize = v["files"].as_array().unwrap().iter().map(|f| f["diagnostics"].as_array().unwrap().len()).sum();
    assert_eq!((listed, total("notes")), (errors + warnings, notes));
}

/// JSON and SARIF name a file that could not be read and say why.
#[test]
fn unreadable_files_have_path_and_reason() {
    let o = odgen(&["check", "--format", "json", "/nonexistent/x.eds", fixture("base.eds").to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    let v = json(&o);
    assert_eq!(v["unreadable"], 1);
    assert_eq!(v["unreadable_files"][0]["file"], "/nonexistent/x.eds");
    assert!(v["unreadable_files"][0]["reason"].as_str().unwrap().contains("No such file"), "{v:#}");
    assert_eq!(v["files"].as_array().unwrap().len(), 1);
    let o = odgen(&["check", "--format", "sarif", "/nonexistent/x.eds"]);
    assert_eq!(o.status.code(), Some(2));
    let v = json(&o);
    let inv = &v["runs"][0]["invocations"][0];
    assert_eq!(inv["executionSuccessful"], false);
    let note = &inv["toolExecutionNotifications"][0];
    assert_eq!(note["level"], "error");
    assert!(note["message"]["text"].as_str().unwrap().contains("/nonexistent/x.eds: No such file"), "{note:#}");
}

/// Whether `v` is an object with only `allowed` keys and all of `required`.
fn keys(v: &Value, required: &[&str], allowed: &[&str], what: &str) {
    let map = v.as_object().unwrap_or_else(|| panic!("{what} is not an object: {v}"));
    for k in required {
        assert!(map.contains_key(*k), "{what} lacks `{k}`: {v}");
    }
    for k in map.keys() {
        assert!(required.contains(&k.as_str()) || allowed.contains(&k.as_str()), "{what} has `{k}`");
    }
}

fn message(v: &Value, what: &str) {
    keys(v, &["text"], &[], what);
    assert!(!v["text"].as_str().unwrap().is_empty(), "{what}");
}

fn physical_location(v: &Value, what: &str) {
    keys(v, &["artifactLocation"], &["region"], what);
    keys(&v["artifactLocation"], &["uri"], &[], what);
    let uri = v["artifactLocation"]["uri"].as_str().unwrap();
    assert!(!uri.contains(' ') && !uri.is_empty(), "{what}: uri {uri}");
    if let Some(r) = v.get("region") {
        keys(r, &["startLine"], &["startColumn", "endLine", "endColumn"], what);
        let n = |k: &str| r[k].as_u64();
        assert!(n("startLine").unwrap() >= 1 && n("startColumn").unwrap_or(1) >= 1, "{what}: {r}");
        if let Some(end) = n("endLine") {
            assert!(end >= n("startLine").unwrap(), "{what}: {r}");
            if end == n("startLine").unwrap() {
                assert!(n("endColumn").unwrap() >= n("startColumn").unwrap(), "{what}: {r}");
            }
        }
    }
}

/// The SARIF log has the shape SARIF 2.1.0 prescribes (the properties the standard requires,
/// only properties it defines, levels from its list, a `ruleIndex` that points at the rule of
/// the `ruleId`, 1-based regions), and one result per diagnostic at the place JSON gives.
#[test]
fn sarif_follows_the_standard() {
    let files = all_fixtures();
    let mut args = vec!["check", "--strict", "--format", "sarif"];
    args.extend(files.iter().map(String::as_str));
    let o = odgen(&args);
    assert_eq!(o.status.code(), Some(1));
    let v = json(&o);
    keys(&v, &["version", "runs"], &["$schema"], "sarifLog");
    assert_eq!(v["version"], "2.1.0");
    let runs = v["runs"].as_array().unwrap();
    assert_eq!(runs.len(), 1);
    let run = &runs[0];
    keys(run, &["tool"], &["results", "invocations", "columnKind"], "run");
    assert_eq!(run["columnKind"], "unicodeCodePoints");
    keys(&run["tool"], &["driver"], &[], "tool");
    let driver = &run["tool"]["driver"];
    keys(driver, &["name"], &["version", "rules"], "driver");
    let rules = driver["rules"].as_array().unwrap();
    assert_eq!(rules.len(), eds::codes::ALL.len() + od_codegen::diag::ALL.len());
    for r in rules {
        keys(r, &["id"], &["shortDescription", "defaultConfiguration", "properties"], "rule");
        message(&r["shortDescription"], "shortDescription");
        assert!(["error", "warning", "note"].contains(&r["defaultConfiguration"]["level"].as_str().unwrap()));
    }
    let results = run["results"].as_array().unwrap();
    let mut by_place = Vec::new();
    for r in results {
        keys(r, &["message"], &["ruleId", "ruleIndex", "level", "locations"], "result");
        message(&r["message"], "result message");
        assert!(["none", "note", "warning", "error"].contains(&r["level"].as_str().unwrap()), "{r}");
        let i = r["ruleIndex"].as_u64().unwrap() as usize;
        assert_eq!(rules[i]["id"], r["ruleId"], "ruleIndex points at the rule");
        let locations = r["locations"].as_array().unwrap();
        assert_eq!(locations.len(), 1);
        keys(&locations[0], &["physicalLocation"], &[], "location");
        physical_location(&locations[0]["physicalLocation"], "physicalLocation");
        let region = &locations[0]["physicalLocation"]["region"];
        by_place.push((
            r["ruleId"].as_str().unwrap().to_owned(),
            region["startLine"].as_u64(),
            region["startColumn"].as_u64(),
        ));
    }
    keys(&run["invocations"][0], &["executionSuccessful"], &["toolExecutionNotifications"], "invocation");
    // The same diagnostics as JSON, at the same places.
    let mut args = vec!["check", "--strict", "--format", "json"];
    args.extend(files.iter().map(String::as_str));
    let j = json(&odgen(&args));
    let want: Vec<_> = j["files"]
        .as_array()
        .unwrap()
        .iter()
        .flat_map(|f| f["diagnostics"].as_array().unwrap().iter())
        .map(|d| (d["code"].as_str().unwrap().to_owned(), d["at"]["line"].as_u64(), d["at"]["col"].as_u64()))
        .collect();
    assert_eq!(by_place, want);
}
