//! Interoperability with python-canopen (`canopen` 2.4.1 from `scripts/venv.sh`): every EDS and
//! DCF we write — our fixtures, the devices in `devices/`, and each corpus file read and written
//! back — is imported with `canopen.import_od`, and its objects, names, types, access, PDO
//! mapping, defaults, ParameterValues, limits, node id and bit rate must be what our model says.
//! `tests/python/check_import.py` does the importing and documents python-canopen's own reading
//! rules, which the expectations account for.
//!
//! Without the venv (`.venv/bin/python`) the test is skipped with a message, unless `CI` is set:
//! then it builds the venv with `scripts/venv.sh`, and fails if it cannot.

use crate::write_common;

use std::path::{Path, PathBuf};
use std::process::Command;

use eds::model::*;
use serde_json::{Value as Json, json};

fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("eds/ has a parent").to_path_buf()
}

fn find_python() -> Option<PathBuf> {
    let root = repo_root();
    if let Ok(p) = std::env::var("ODGEN_PYTHON") {
        return Some(PathBuf::from(p));
    }
    let venv = root.join(".venv/bin/python");
    if venv.is_file() {
        // venv.sh is fast when nothing changed and installs what requirements-test.txt adds.
        let out = Command::new("bash").arg(root.join("scripts/venv.sh")).output();
        if let Ok(out) = out
            && out.status.success()
        {
            return Some(PathBuf::from(String::from_utf8_lossy(&out.stdout).trim()));
        }
        return Some(venv);
    }
    if std::env::var_os("CI").is_some() {
        let out = Command::new("bash").arg(root.join("scripts/venv.sh")).output().expect("run scripts/venv.sh");
        assert!(out.status.success(), "scripts/venv.sh failed: {}", String::from_utf8_lossy(&out.stderr));
        return Some(PathBuf::from(String::from_utf8_lossy(&out.stdout).trim()));
    }
    eprintln!("SKIPPED python_interop: no .venv (run scripts/venv.sh); set CI=1 to make this a failure");
    None
}

fn corpus_dir() -> Option<PathBuf> {
    let root = repo_root();
    let dir = match std::env::var_os("EDS_CORPUS_DIR") {
        Some(d) => {
            let d = PathBuf::from(d);
            if d.is_absolute() { d } else { root.join(d) }
        }
        None => root.join("../shared/eds-corpus"),
    };
    dir.is_dir().then_some(dir)
}

fn int_json(v: i128) -> Json {
    if let Ok(i) = i64::try_from(v) {
        json!(i)
    } else if let Ok(u) = u64::try_from(v) {
        json!(u)
    } else {
        json!(v.to_string())
    }
}

fn radix(r: Radix) -> &'static str {
    match r {
        Radix::Dec => "dec",
        Radix::Hex => "hex",
        Radix::Oct => "oct",
    }
}

fn value_json(v: &Option<Value>, ty: DataType) -> Json {
    let Some(v) = v else { return Json::Null };
    let text = eds::write::format_value(v, ty);
    match v {
        Value::Int { value, radix: r } => {
            json!({"kind": "int", "value": int_json(*value), "radix": radix(*r), "text": text})
        }
        Value::NodeIdPlus { offset, radix: r } => {
            json!({"kind": "nodeid", "value": int_json(*offset), "radix": radix(*r), "text": text})
        }
        Value::Real(x) => {
            json!({"kind": "real", "value": if x.is_finite() { json!(x) } else { Json::Null }, "text": text})
        }
        Value::Text(t) => json!({"kind": "text", "value": t, "text": text}),
        Value::Bytes(_) => json!({"kind": "bytes", "value": text, "text": text}),
    }
}

/// What our model says, in the terms check_import.py compares.
fn describe(path: &Path, m: &Model) -> Json {
    let written_dcf = m.kind == FileKind::Dcf && m.commissioning.is_some();
    let file_node_id = if written_dcf { m.node_id() } else { None };
    let node_id_arg: Option<u8> = if file_node_id.is_some() { None } else { Some(5) };
    let resolve = node_id_arg.or(file_node_id);
    let od_node_id = if written_dcf { resolve } else { None };
    let bitrate = if written_dcf { m.commissioning.as_ref().and_then(|c| c.baudrate) } else { None };
    // python-canopen cannot import a DEFSTRUCT with sub-sections or a partial [DummyUsage].
    let mut expect_import_error = Vec::new();
    if m.objects.values().any(|o| matches!(o.object_type, ObjectType::DefStruct) && !o.subs.is_empty()) {
        expect_import_error.push("DEFSTRUCT sub-sections");
    }
    if !m.dummy_usage.is_empty() && (1..=7).any(|i| !m.dummy_usage.contains_key(&i)) {
        expect_import_error.push("incomplete [DummyUsage]");
    }
    let objects: Vec<Json> = m
        .objects
        .values()
        .map(|o| {
            let compact = eds::write::compact_info(o);
            json!({
                "index": o.index.0,
                "name": o.name,
                "object_type": o.object_type.code(),
                "compact": compact.is_some(),
                "compact_default": compact.map(|c| value_json(&c.default, c.data_type)).unwrap_or(Json::Null),
                "entries": o.subs.values().map(|e| json!({
                    "sub": e.sub.0,
                    "name": e.name,
                    "data_type": e.data_type.code(),
                    "access": e.access.as_str(),
                    "pdo_mapping": e.pdo_mapping,
                    "default": value_json(&e.default, e.data_type),
                    "parameter_value": value_json(&e.parameter_value().cloned(), e.data_type),
                    "low_limit": value_json(&e.low_limit().cloned(), e.data_type),
                    "high_limit": value_json(&e.high_limit().cloned(), e.data_type),
                })).collect::<Vec<_>>(),
            })
        })
        .collect();
    let di = &m.device_info;
    json!({
        "path": path.display().to_string(),
        "node_id_arg": node_id_arg,
        "resolve_node_id": resolve,
        "od_node_id": od_node_id,
        "bitrate": bitrate,
        "expect_import_error": if expect_import_error.is_empty() { Json::Null } else { json!(expect_import_error.join(", ")) },
        "comments": m.comments,
        "device": {
            "vendor_name": di.vendor_name, "vendor_number": di.vendor_number,
            "product_name": di.product_name, "product_number": di.product_number,
            "revision_number": di.revision_number,
            "baud_rates": di.baud_rates.iter().filter(|(_, on)| **on).map(|(r, _)| *r).collect::<Vec<_>>(),
        },
        "objects": objects,
    })
}

/// Writes `model` to `dir/name`, checks that our reader gives the same model back, and returns
/// the description of what was written.
fn write_and_describe(dir: &Path, name: &str, model: &Model) -> Json {
    let text = eds::write::write(model);
    let path = dir.join(name);
    std::fs::write(&path, &text).expect("write temp file");
    let back = eds::parse(name, text.as_bytes(), &eds::Options::lenient());
    assert!(!back.has_errors(), "{name}: our own output has errors: {:#?}", back.errors().collect::<Vec<_>>());
    assert_eq!(back.model, *model, "{name}: reading what we wrote gives a different model");
    describe(&path, model)
}

#[test]
fn python_canopen_reads_what_we_write() {
    let Some(python) = find_python() else { return };
    let dir = std::env::temp_dir().join(format!("eds-python-interop-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let mut files = vec![
        write_and_describe(&dir, "fixture-full.eds", &write_common::full_eds()),
        write_and_describe(&dir, "fixture-full.dcf", &write_common::full_dcf()),
    ];
    let mut sources: Vec<PathBuf> = Vec::new();
    for d in [repo_root().join("devices")].into_iter().chain(corpus_dir()) {
        let mut found: Vec<PathBuf> = std::fs::read_dir(&d)
            .expect("list directory")
            .flatten()
            .map(|e| e.path())
            .filter(|p| matches!(p.extension().and_then(|e| e.to_str()), Some("eds" | "dcf")))
            .collect();
        found.sort();
        sources.extend(found);
    }
    if corpus_dir().is_none() {
        eprintln!("note: corpus not found (set EDS_CORPUS_DIR); checking fixtures and devices only");
    }
    let mut skipped = Vec::new();
    for src in &sources {
        let parsed = eds::read_file(src, &eds::Options::lenient()).expect("read source file");
        if parsed.has_errors() {
            skipped.push(src.display().to_string());
            continue;
        }
        let name = format!("rt-{}", src.file_name().unwrap().to_string_lossy());
        let mut described = write_and_describe(&dir, &name, &parsed.model);
        described["original"] = json!(src.display().to_string());
        files.push(described);
    }
    let manifest = dir.join("manifest.json");
    std::fs::write(&manifest, serde_json::to_string(&json!({ "files": files })).unwrap()).unwrap();
    let script = repo_root().join("tests/python/check_import.py");
    let out =
        Command::new(&python).arg(&script).arg(&manifest).env("PYTHONUTF8", "1").output().expect("run the venv python");
    assert!(
        out.status.success(),
        "check_import.py failed:\n{}\n{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    let report: Json = serde_json::from_slice(&out.stdout).expect("check_import.py prints JSON");
    let results = report["results"].as_array().expect("results");
    assert_eq!(results.len(), files.len());
    let mut failures = Vec::new();
    let mut checked = 0;
    for r in results {
        if let Some(note) = r["note"].as_str() {
            eprintln!("note: {}: {note}", r["path"]);
        }
        checked += r["checked"].as_u64().unwrap_or(0);
        for m in r["mismatches"].as_array().into_iter().flatten() {
            failures.push(format!(
                "{}: {} {}: ours {} python {}",
                r["path"], m["where"], m["what"], m["ours"], m["python"]
            ));
        }
    }
    eprintln!(
        "python-canopen {} imported {} files, {} checks, {} mismatches; {} sources skipped for read errors: {:?}",
        report["canopen_version"],
        files.len(),
        checked,
        failures.len(),
        skipped.len(),
        skipped
    );
    assert!(failures.is_empty(), "python-canopen disagrees:\n{}", failures.join("\n"));
    assert!(checked > 100, "too few checks ({checked}): the comparison did not run");
    let _ = std::fs::remove_dir_all(&dir);
}
