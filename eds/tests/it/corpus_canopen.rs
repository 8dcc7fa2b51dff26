//! The corpus read by this crate and by python-canopen (the reference master of the project)
//! must agree on every default value both can read: integers with `$NODEID` resolved, reals,
//! byte strings and text. Where python-canopen cannot read a value, the reason must be one this
//! crate reports (a leading-zero number, which python rejects, is checked explicitly).
//!
//! Needs `$EDS_CORPUS_DIR` and a Python with `canopen` (`$EDS_PYTHON`, else the repository's
//! `.venv/bin/python` that `scripts/venv.sh` makes); skipped, saying so, without them.

use std::path::{Path, PathBuf};
use std::process::Command;

use eds::model::{DataType, Radix, Value};
use eds::{Model, Options};

const NODE: u8 = 5;

fn python() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("EDS_PYTHON") {
        return Some(PathBuf::from(p));
    }
    let venv = Path::new(env!("CARGO_MANIFEST_DIR")).join("../.venv/bin/python");
    venv.exists().then_some(venv)
}

fn corpus() -> Option<Vec<PathBuf>> {
    let dir = std::env::var_os("EDS_CORPUS_DIR")?;
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .ok()?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().and_then(|e| e.to_str()).is_some_and(|e| e == "eds" || e == "dcf"))
        .collect();
    files.sort();
    Some(files)
}

/// What python-canopen read: per file, `Err(message)` or its entries.
fn python_reading(py: &Path, files: &[PathBuf]) -> Option<Vec<serde_json::Value>> {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/support/canopen_dump.py");
    let out = Command::new(py).arg(script).arg(NODE.to_string()).args(files).output().ok()?;
    if !out.status.success() {
        println!("python-canopen dump failed: {}", String::from_utf8_lossy(&out.stderr));
        return None;
    }
    serde_json::from_slice(&out.stdout).ok()
}

/// The two readings of one default value differ (a description), or agree (`None`).
fn compare(ours: &Value, theirs: &serde_json::Value, ty: DataType, raw: &str) -> Option<String> {
    let differ = |o: String, t: String| Some(format!("ours {o}, python-canopen {t}"));
    if let Some(t) = theirs.get("int").and_then(|v| v.as_str()).and_then(|s| s.parse::<i128>().ok()) {
        let Some(o) = ours.resolve(NODE) else { return differ(format!("{ours:?}"), t.to_string()) };
        // python-canopen reads defaults of signed types without two's complement (it applies
        // that to limits only): compare the bit patterns.
        let same = match ty.bits() {
            Some(bits) if ty.is_signed() => (o - t).rem_euclid(1i128 << bits) == 0,
            _ => o == t,
        };
        return if same { None } else { differ(o.to_string(), t.to_string()) };
    }
    if let Some(t) = theirs.get("real").and_then(|v| v.as_str()).and_then(|s| s.parse::<f64>().ok()) {
        let Value::Real(o) = *ours else { return differ(format!("{ours:?}"), t.to_string()) };
        let same = if ty == DataType::Real32 { (o as f32) == (t as f32) } else { o == t };
        return if same || (o.is_nan() && t.is_nan()) { None } else { differ(o.to_string(), t.to_string()) };
    }
    if let Some(t) = theirs.get("bytes").and_then(|v| v.as_str()) {
        let Value::Bytes(b) = ours else { return differ(format!("{ours:?}"), t.to_owned()) };
        let o: String = b.iter().map(|x| format!("{x:02x}")).collect();
        return if o == t { None } else { differ(o, t.to_owned()) };
    }
    if let Some(t) = theirs.get("text").and_then(|v| v.as_str()) {
        // configparser strips an inline ` ;comment`; CiA 306 text may contain `;`.
        if raw.contains(" ;") || raw.contains("\t;") {
            return None;
        }
        let Value::Text(o) = ours else { return differ(format!("{ours:?}"), t.to_owned()) };
        return if o == t { None } else { differ(o.clone(), t.to_owned()) };
    }
    None
}

#[test]
fn defaults_agree_with_python_canopen() {
    let (Some(files), Some(py)) = (corpus(), python()) else {
        println!("EDS_CORPUS_DIR or a Python with canopen is missing: skipping the python-canopen comparison");
        return;
    };
    let Some(reading) = python_reading(&py, &files) else {
        println!("python-canopen is not importable with {}: skipping", py.display());
        return;
    };
    assert_eq!(reading.len(), files.len());
    let (mut compared, mut node_relative, mut python_failed_files) = (0usize, 0usize, Vec::new());
    let mut octal_checked = 0usize;
    let mut mismatches = Vec::new();
    for (path, theirs) in files.iter().zip(&reading) {
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or_default();
        let ours = eds::read_file(path, &Options::lenient()).expect("read");
        assert!(!ours.has_errors(), "{name} loads leniently");
        let Some(entries) = theirs.get("entries").and_then(|e| e.as_array()) else {
            python_failed_files.push(name.to_owned());
            continue;
        };
        let model: &Model = &ours.model;
        for e in entries {
            let (Some(index), Some(sub)) = (e["index"].as_u64(), e["sub"].as_u64()) else { continue };
            let Some(entry) = model.entry(index as u16, sub as u8) else { continue };
            if matches!(entry.data_type, DataType::Other(_)) {
                continue;
            }
            let raw = e["raw"].as_str().unwrap_or_default();
            match (&entry.default, &e["default"]) {
                (Some(o), t) if !t.is_null() => {
                    compared += 1;
                    node_relative += o.is_node_relative() as usize;
                    if let Some(why) = compare(o, t, entry.data_type, raw) {
                        mismatches.push(format!("{name} 0x{index:04X} sub {sub} `{raw}`: {why}"));
                    }
                }
                // python-canopen refuses numbers with leading zeros (`int("010", 0)` raises);
                // this crate reads them as CiA 306 octal and says so (E0303/E0305).
                (Some(Value::Int { radix: Radix::Oct, .. }), t) => {
                    assert!(t.is_null(), "{name} 0x{index:04X} sub {sub}: python read `{raw}` as {t}");
                    octal_checked += 1;
                }
                _ => {}
            }
        }
    }
    println!(
        "compared {compared} defaults ({node_relative} with $NODEID) in {} files; {octal_checked} leading-zero values python-canopen cannot read; python-canopen failed on {} files: {python_failed_files:?}",
        files.len() - python_failed_files.len(),
        python_failed_files.len()
    );
    assert!(mismatches.is_empty(), "{} mismatches:\n{}", mismatches.len(), mismatches.join("\n"));
    assert!(compared > 1000, "only {compared} values compared");
    assert!(node_relative > 50, "only {node_relative} $NODEID values compared");
}

/// The places where python-canopen and this crate read the same text differently, pinned down
/// on the crate's own fixtures (needs only the Python).
#[test]
fn known_differences_with_python_canopen() {
    let Some(py) = python() else {
        println!("no Python with canopen: skipping");
        return;
    };
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/features");
    let files = [dir.join("nodeid.eds"), dir.join("numbers.eds")];
    let Some(reading) = python_reading(&py, &files) else {
        println!("python-canopen is not importable with {}: skipping", py.display());
        return;
    };
    let theirs = |file: usize, index: u64, sub: u64| -> serde_json::Value {
        reading[file]["entries"]
            .as_array()
            .and_then(|es| es.iter().find(|e| e["index"] == index && e["sub"] == sub))
            .map(|e| e["default"].clone())
            .unwrap_or(serde_json::Value::Null)
    };
    let int = |v: serde_json::Value| v.get("int").and_then(|s| s.as_str()).and_then(|s| s.parse::<i128>().ok());
    let ours = |file: &Path, index: u16, sub: u8| {
        eds::read_file(file, &Options::lenient()).expect("read").model.entry(index, sub).and_then(|e| e.default.clone())
    };
    // $NODEID in every shape with an offset: both read the same.
    for sub in [1, 2, 3, 5] {
        let o = ours(&files[0], 0x1400, sub).and_then(|v| v.resolve(NODE));
        assert_eq!(o, int(theirs(0, 0x1400, sub as u64)), "nodeid sub {sub}");
    }
    // A bare `$NODEID` is beyond python-canopen (its regex leaves an empty number).
    assert_eq!(ours(&files[0], 0x1400, 4).and_then(|v| v.resolve(NODE)), Some(NODE as i128));
    assert!(theirs(0, 0x1400, 4).is_null());
    // Leading zeros: python-canopen cannot read `010`, `001` or `09`; this crate reads CiA 306
    // octal (8, 1) or decimal (9) and warns. All zeros both read as 0.
    for (sub, want) in [(1, 8), (2, 1), (4, 9)] {
        assert_eq!(ours(&files[1], 0x2000, sub).and_then(|v| v.as_int()), Some(want));
        assert!(theirs(1, 0x2000, sub as u64).is_null(), "python read sub {sub}");
    }
    assert_eq!(int(theirs(1, 0x2000, 3)), Some(0));
    assert_eq!(ours(&files[1], 0x2000, 3).and_then(|v| v.as_int()), Some(0));
    // `FALSE` for a BOOLEAN: python-canopen has no value, this crate reads 0 and warns.
    assert!(theirs(1, 0x2000, 6).is_null());
    assert_eq!(ours(&files[1], 0x2000, 6).and_then(|v| v.as_int()), Some(0));
}
