//! python-canopen (2.4.1, from `scripts/venv.sh`) imports the DCFs of the example network and
//! reads from them what our model says: node id, bit rate, every integer ParameterValue, and
//! each PDO's COB-ID, transmission type, event timer and mapping as a master reads them from the
//! dictionary (`tests/python/import_network.py`).
//!
//! Without the venv (`.venv/bin/python`, or `ODGEN_PYTHON`) the test says it is skipped, unless
//! `CI` is set: then it builds the venv with `scripts/venv.sh`, and fails if it cannot.

use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::{Value as Json, json};

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("odgen/ has a parent").to_path_buf()
}

fn find_python() -> Option<PathBuf> {
    if let Ok(p) = std::env::var("ODGEN_PYTHON") {
        return Some(PathBuf::from(p));
    }
    let venv = repo().join(".venv/bin/python");
    if venv.is_file() {
        return Some(venv);
    }
    if std::env::var_os("CI").is_some() {
        let out = Command::new("bash").arg(repo().join("scripts/venv.sh")).output().expect("run scripts/venv.sh");
        assert!(out.status.success(), "scripts/venv.sh failed: {}", String::from_utf8_lossy(&out.stderr));
        return Some(PathBuf::from(String::from_utf8_lossy(&out.stdout).trim()));
    }
    eprintln!("SKIPPED network_python: no .venv (run scripts/venv.sh); set CI=1 to make this a failure");
    None
}

/// The value of an entry as the DCF gives it: ParameterValue, else DefaultValue, resolved.
fn effective(m: &eds::Model, index: u16, sub: u8, node_id: u8) -> Option<i128> {
    let e = m.entry(index, sub)?;
    e.parameter_value().or(e.default.as_ref())?.resolve(node_id)
}

fn pdos(m: &eds::Model, node_id: u8, comm_base: u16, map_base: u16, count: u16) -> Json {
    let mut out = serde_json::Map::new();
    for n in 0..count {
        let (comm, map) = (comm_base + n, map_base + n);
        let Some(cob) = effective(m, comm, 1, node_id) else { continue };
        let trans_type = effective(m, comm, 2, node_id).unwrap_or(0);
        let entries = effective(m, map, 0, node_id).unwrap_or(0) as u8;
        let mapping: Vec<Json> = (1..=entries)
            .filter_map(|s| effective(m, map, s, node_id))
            .map(|raw| {
                let e = eds::PdoMappingEntry::from_u32(raw as u32);
                json!([e.index.0, e.sub.0, e.bits])
            })
            .filter(|v| v[0] != 0 && v[2] != 0)
            .collect();
        // python-canopen reads the event timer only for event-driven PDOs (type 254/255).
        let event_timer = if trans_type >= 254 { effective(m, comm, 5, node_id) } else { None };
        out.insert(
            (n + 1).to_string(),
            json!({
                "cob_id": (cob as u32) & 0x1FFF_FFFF,
                "enabled": cob as u32 & 0x8000_0000 == 0,
                "trans_type": trans_type,
                "event_timer": event_timer,
                "map": mapping,
            }),
        );
    }
    Json::Object(out)
}

#[test]
fn python_canopen_reads_the_example_network_dcfs() {
    let Some(python) = find_python() else { return };
    let text = std::fs::read_to_string(repo().join("networks/example.toml")).unwrap();
    let outcome = odgen::network::build("networks/example.toml", &repo().join("networks"), &text);
    assert!(!outcome.has_errors(), "{}", odgen::network::render_all(&outcome.diagnostics));
    let dir = std::env::temp_dir().join(format!("odgen-network-python-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let mut files = Vec::new();
    for dcf in &outcome.dcfs {
        let path = dir.join(&dcf.file_name);
        std::fs::write(&path, &dcf.text).unwrap();
        let m = &dcf.model;
        let values: Vec<Json> = m
            .entries()
            .filter(|(o, _)| {
                matches!(o.object_type, eds::ObjectType::Var | eds::ObjectType::Array | eds::ObjectType::Record)
            })
            .filter_map(|(o, e)| {
                let v = e.parameter_value()?.as_int()?;
                Some(json!([o.index.0, e.sub.0, v]))
            })
            .collect();
        assert!(values.len() > 20, "{}: only {} configured values", dcf.file_name, values.len());
        let di = &m.device_info;
        files.push(json!({
            "path": path.display().to_string(),
            "node_id": dcf.node_id,
            "bitrate": u32::from(m.commissioning.as_ref().and_then(|c| c.baudrate).unwrap()) * 1000,
            "values": values,
            "tpdo": pdos(m, dcf.node_id, 0x1800, 0x1A00, di.nr_of_tx_pdo.unwrap_or(0)),
            "rpdo": pdos(m, dcf.node_id, 0x1400, 0x1600, di.nr_of_rx_pdo.unwrap_or(0)),
        }));
    }
    let manifest = dir.join("manifest.json");
    std::fs::write(&manifest, serde_json::to_string(&json!({ "files": files })).unwrap()).unwrap();
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/python/import_network.py");
    let out = Command::new(&python).arg(&script).arg(&manifest).output().expect("run python");
    assert!(out.status.success(), "import_network.py failed: {}", String::from_utf8_lossy(&out.stderr));
    let report: Json = serde_json::from_slice(&out.stdout).expect("JSON report");
    let results = report["results"].as_array().unwrap();
    assert_eq!(results.len(), 3);
    for r in results {
        let mismatches = r["mismatches"].as_array().unwrap();
        assert!(mismatches.is_empty(), "{}: {mismatches:#?}", r["path"]);
        assert!(r["checked"].as_u64().unwrap() > 30, "{r}");
    }
    // The example's own intent, as python-canopen sees it (not only "same as our model").
    let tpdo1 = &files[0]["tpdo"]["1"];
    assert_eq!(tpdo1["map"], json!([[0x6041, 0, 16], [0x6064, 0, 32]]));
    assert_eq!(tpdo1["cob_id"], 0x182);
    let _ = std::fs::remove_dir_all(&dir);
}
