//! `odgen::diff` and `odgen diff`: fixtures `tests/fixtures/diff/{old,new}.eds` differ in every
//! way the report knows (objects and entries added and removed; name, type, access, default,
//! limit, PDO mapping and `[DeviceInfo]` changes) and in one way it must not report (a default
//! written `0x0000` in one and `0` in the other).

use std::path::{Path, PathBuf};
use std::process::Command;

use odgen::diff::{self, Kind};

fn fixture(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/diff").join(name)
}

fn model(name: &str) -> eds::Model {
    let p = eds::read_file(fixture(name), &eds::Options::strict()).expect("fixture");
    assert!(!p.has_errors(), "{name} has errors");
    p.model
}

fn odgen(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_odgen"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(args)
        .output()
        .expect("run odgen")
}

#[test]
fn every_kind_of_change_is_reported() {
    let d = diff::diff(&model("old.eds"), &model("new.eds"));
    let rows: Vec<(String, Kind, Option<&str>)> =
        d.changes.iter().map(|c| (c.location(), c.kind, c.field.as_deref())).collect();
    let has = |loc: &str, kind: Kind, field: Option<&str>| {
        assert!(
            rows.iter().any(|(l, k, f)| l == loc && *k == kind && *f == field),
            "no {kind:?} {field:?} at {loc} in {rows:#?}"
        )
    };
    has("0x1008", Kind::Removed, None);
    has("0x6502", Kind::Added, None);
    has("0x1018sub3", Kind::Added, None);
    has("0x1A00sub4", Kind::Removed, None);
    has("0x1018sub0", Kind::Changed, Some("DefaultValue"));
    has("0x6060", Kind::Changed, Some("AccessType"));
    has("0x6060", Kind::Changed, Some("HighLimit"));
    has("0x607A", Kind::Changed, Some("PDOMapping"));
    has("0x6064", Kind::Changed, Some("ParameterName"));
    has("0x606C", Kind::Changed, Some("DataType"));
    has("0x1800sub1", Kind::Changed, Some("DefaultValue"));
    has("[DeviceInfo]", Kind::Changed, Some("BaudRate (kbit/s)"));
    assert!(!rows.iter().any(|(l, _, _)| l == "0x6040"), "a change of radix is no change: {rows:#?}");
    let s = d.summary();
    assert_eq!((s.objects_added, s.objects_removed, s.entries_added, s.entries_removed), (1, 1, 1, 1));

    // Reversed, additions become removals and old and new swap.
    let back = diff::diff(&model("new.eds"), &model("old.eds"));
    assert_eq!(back.changes.len(), d.changes.len());
    for (a, b) in d.changes.iter().zip(&back.changes) {
        let swapped = match a.kind {
            Kind::Added => Kind::Removed,
            Kind::Removed => Kind::Added,
            Kind::Changed => Kind::Changed,
        };
        assert_eq!((b.kind, &b.old, &b.new), (swapped, &a.new, &a.old), "{a:?} / {b:?}");
    }
}

#[test]
fn identical_descriptions_have_no_differences() {
    let m = model("old.eds");
    let d = diff::diff(&m, &m);
    assert!(d.is_empty());
    assert_eq!(diff::render_table(&d), "no differences\n");
    // A DCF's ParameterValue is compared too.
    let mut configured = m.clone();
    configured
        .objects
        .get_mut(&eds::Index(0x1017))
        .unwrap()
        .subs
        .get_mut(&eds::SubIndex(0))
        .unwrap()
        .set_parameter_value(Some(eds::Value::int(100)));
    let d = diff::diff(&m, &configured);
    assert_eq!(d.changes.len(), 1);
    assert_eq!(d.changes[0].field.as_deref(), Some("ParameterValue"));
    assert_eq!((d.changes[0].old.as_deref(), d.changes[0].new.as_deref()), (None, Some("100")));
}

#[test]
fn table_snapshot() {
    let d = diff::diff(&model("old.eds"), &model("new.eds"));
    insta::assert_snapshot!(diff::render_table(&d));
}

#[test]
fn json_snapshot() {
    let d = diff::diff(&model("old.eds"), &model("new.eds"));
    let json = diff::render_json(&d);
    let v: serde_json::Value = serde_json::from_str(&json).expect("valid JSON");
    assert_eq!(v["identical"], false);
    assert_eq!(v["changes"].as_array().unwrap().len(), d.changes.len());
    insta::assert_snapshot!(json);
}

#[test]
fn cli_exit_codes_and_formats() {
    let o = odgen(&["diff", "tests/fixtures/diff/old.eds", "tests/fixtures/diff/new.eds"]);
    assert_eq!(o.status.code(), Some(1), "different: exit 1");
    let d = diff::diff(&model("old.eds"), &model("new.eds"));
    assert_eq!(String::from_utf8_lossy(&o.stdout), diff::render_table(&d));

    let o = odgen(&["diff", "--format", "json", "tests/fixtures/diff/old.eds", "tests/fixtures/diff/new.eds"]);
    assert_eq!(o.status.code(), Some(1));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("JSON");
    assert_eq!(v["old"], "tests/fixtures/diff/old.eds");
    assert_eq!(v["new"], "tests/fixtures/diff/new.eds");
    assert_eq!(v["summary"]["fields_changed"], d.summary().fields_changed);

    let o = odgen(&["diff", "tests/fixtures/diff/old.eds", "tests/fixtures/diff/old.eds"]);
    assert_eq!(o.status.code(), Some(0), "identical: exit 0");
    assert_eq!(String::from_utf8_lossy(&o.stdout), "no differences\n");

    let o = odgen(&["diff", "tests/fixtures/diff/old.eds", "tests/fixtures/diff/missing.eds"]);
    assert_eq!(o.status.code(), Some(2), "unreadable: exit 2");
    assert!(String::from_utf8_lossy(&o.stderr).contains("cannot read tests/fixtures/diff/missing.eds"));

    // A file with errors is refused (its model would be partial).
    let dir = std::env::temp_dir().join(format!("odgen-diff-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let broken = dir.join("broken.eds");
    let text = std::fs::read_to_string(fixture("old.eds")).unwrap().replacen("DataType=0x0006\n", "", 1);
    std::fs::write(&broken, text).unwrap();
    let o = odgen(&["diff", "tests/fixtures/diff/old.eds", broken.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("has errors; fix them before comparing it"));
    let _ = std::fs::remove_dir_all(&dir);
}
