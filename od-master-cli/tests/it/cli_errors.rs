//! The command line's answers to what cannot work (#36): a write to an object the EDS says is
//! read-only, a position that is no whole raw value, a homing with method 0, and `axis` in
//! JSON lines.

use std::time::Instant;

use drive::node::DeviceKind;

use crate::cli::Rig;

const DRVI_EDS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../devices/camozzi-drvi.eds");
const AKD_EDS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../devices/kollmorgen-akd.eds");

#[test]
fn cli_refuses_what_cannot_work_and_axis_speaks_json() {
    let rig = Rig::start(&[(DeviceKind::Drvi, 5), (DeviceKind::Akd, 4)]);
    // The EDS says 6041h is read-only: refused before anything is sent (exit 2), by name or
    // by number.
    for object in ["statusword", "6041h"] {
        let out = rig.cli(&["--eds", DRVI_EDS, "write", "5", object, "6"]);
        assert_eq!(out.code, 2, "{}", out.stderr);
        assert_eq!(
            out.stderr,
            "od-master: 6041h sub 0 (statusword) is read-only in the EDS given (AccessType ro): not written\n"
        );
    }
    // Without an EDS the drive answers for itself: its abort, exit 1.
    assert_eq!(rig.cli(&["write", "5", "6041h", "u16:6"]).code, 1);

    // 1.5 user units on the AKD (1 user unit a raw unit): not rounded to 2, refused.
    let out = rig.cli(&["--eds", AKD_EDS, "axis", "4", "move", "--to", "1.5user", "--velocity", "1000"]);
    assert_eq!(out.code, 2, "{}", out.stderr);
    assert!(
        out.stderr.contains(
            "1.5 user is 1.5 raw units, and the drive takes whole ones: the nearest are 1 user (1) and 2 user (2)"
        ),
        "{}",
        out.stderr
    );

    // The AKD's 6098h is 0: `axis 4 home` ends at once, saying why (it ran 60 s before).
    let started = Instant::now();
    let out = rig.cli(&["axis", "4", "home"]);
    assert_eq!(out.code, 1, "{}", out.stderr);
    assert!(out.stderr.contains("homing method 0 (6098h) is no homing method"), "{}", out.stderr);
    assert!(started.elapsed().as_secs_f64() < 5.0, "{:?}", started.elapsed());

    // --json: one object a line for each axis command.
    let home = rig.cli(&["--json", "axis", "5", "home", "--method", "37"]);
    assert_eq!(home.code, 0, "{}", home.stderr);
    assert_eq!(home.json_lines(), [serde_json::json!({ "node": 5, "homed": true, "method": 37, "position": 0 })]);
    // The DRVI's 6081h is 0 out of the box: a move without --velocity is refused at once.
    let out = rig.cli(&["axis", "5", "move", "--to", "0"]);
    assert_eq!(out.code, 1, "{}", out.stderr);
    assert!(out.stderr.contains("profile velocity 6081h is 0"), "{}", out.stderr);
    let moved =
        rig.cli(&["--json", "axis", "5", "move", "--to", "3600", "--velocity", "36000", "--acceleration", "36000"]);
    assert_eq!(moved.code, 0, "{}", moved.stderr);
    assert_eq!(moved.json_lines(), [serde_json::json!({ "node": 5, "target": 3600, "position": 3600 })]);
    let enabled = rig.cli(&["--json", "axis", "5", "enable"]);
    assert_eq!(enabled.json_lines(), [serde_json::json!({ "node": 5, "state": "Operation enabled" })]);

    // scan honours --timeout (no 300 ms cap) and retries the first read.
    let out = rig.cli(&["--json", "--timeout", "500", "scan", "--last", "6", "--retries", "2"]);
    assert_eq!(out.code, 0, "{}", out.stderr);
    let nodes: Vec<u64> = out.json_lines().iter().map(|l| l["node"].as_u64().unwrap()).collect();
    assert_eq!(nodes, [4, 5]);
}
