//! `od-master boot` end to end: networks/example.toml booted on simulated drives behind a TCP
//! hub, its text and `--json` lines, a wrong device and a missing node (exit code 1, the node
//! and the object named), `--plan`, and bad input (exit code 2).

use drive::node::DeviceKind;

use crate::cli::{Rig, cli};

const EXAMPLE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../networks/example.toml");

const THREE: [(DeviceKind, u8); 3] = [(DeviceKind::Drvi, 2), (DeviceKind::Drcs, 3), (DeviceKind::Akd, 4)];

#[test]
fn boot_configures_and_starts_the_example_network() {
    let rig = Rig::start(&THREE);
    let out = rig.cli(&["boot", EXAMPLE, "--json"]);
    assert_eq!(out.code, 0, "{}", out.stderr);
    let lines = out.json_lines();
    assert_eq!(
        lines.iter().map(|l| (l["name"].as_str().unwrap(), l["node"].as_u64().unwrap())).collect::<Vec<_>>(),
        [("x_axis", 2), ("y_axis", 3), ("z_axis", 4)]
    );
    for l in &lines {
        assert_eq!(
            (&l["ok"], &l["started"], &l["error"]),
            (&true.into(), &true.into(), &serde_json::Value::Null),
            "{l}"
        );
        assert_eq!(l["written"], l["planned"], "{l}");
    }
    // The configuration is on the devices: x_axis's TPDO 1 event timer and its mapping.
    assert_eq!(rig.cli(&["read", "2", "1800h:5"]).stdout, "20\n");
    assert_eq!(rig.cli(&["read", "2", "0x1A00:2"]).stdout, "1617166368\n", "6064h sub 0, 32 bits");
    assert_eq!(rig.cli(&["read", "4", "6060h"]).stdout, "3\n");
    // Text: one line per node; a second boot of a configured network works the same.
    let out = rig.cli(&["boot", EXAMPLE]);
    assert_eq!(out.code, 0, "{}", out.stderr);
    assert_eq!(
        out.stdout,
        "x_axis (node 2): 29 writes, started\ny_axis (node 3): 28 writes, started\nz_axis (node 4): 28 writes, started\n"
    );
}

#[test]
fn boot_names_the_wrong_device_and_the_missing_node_and_starts_the_others() {
    // A DRVI where the DRCS belongs (node 3), and no node 4.
    let rig = Rig::start(&[(DeviceKind::Drvi, 2), (DeviceKind::Drvi, 3)]);
    let out = rig.cli(&["--timeout", "100", "boot", EXAMPLE]);
    assert_eq!(out.code, 1, "{}", out.stderr);
    assert_eq!(out.stdout, "x_axis (node 2): 29 writes, started\n");
    let errors: Vec<&str> = out.stderr.lines().collect();
    assert_eq!(errors.len(), 3, "{}", out.stderr);
    assert!(
        errors[0].starts_with("od-master: node 3 (y_axis): wrong device: 1000h:0 device type is 0xFF7A0192,")
            && errors[0].ends_with("expects 0xFF7C0192"),
        "{}",
        errors[0]
    );
    assert!(
        errors[1].starts_with("od-master: z_axis, checking the identity: node 4, upload of 1000h sub 0:"),
        "{}",
        errors[1]
    );
    assert!(errors[1].contains("timed out"), "{}", errors[1]);
    // JSON: the failing object of each node.
    let out = rig.cli(&["--timeout", "100", "--json", "boot", EXAMPLE, "--no-start"]);
    assert_eq!(out.code, 1);
    let lines = out.json_lines();
    let y = &lines[1];
    assert_eq!(
        (&y["ok"], &y["index"], &y["subindex"], &y["written"]),
        (&false.into(), &0x1000.into(), &0.into(), &0.into())
    );
    let z = &lines[2];
    assert_eq!((&z["ok"], &z["index"], &z["stage"]), (&false.into(), &0x1000.into(), &"checking the identity".into()));
    assert_eq!((&lines[0]["ok"], &lines[0]["started"]), (&true.into(), &false.into()));
}

#[test]
fn boot_plan_needs_no_bus_and_bad_input_is_usage() {
    let out = cli(&["boot", "--plan", EXAMPLE]);
    assert_eq!(out.code, 0, "{}", out.stderr);
    assert!(out.stdout.starts_with("x_axis (node 2, "), "{}", out.stdout);
    assert!(out.stdout.contains("  check 1018h:2 product code = 0x0000005A\n"), "{}", out.stdout);
    assert!(out.stdout.contains("  write 1A00h:2 = 20006460 (mapping_entry)\n"), "{}", out.stdout);
    let json = cli(&["boot", "--plan", "--json", EXAMPLE]);
    assert_eq!(json.json_lines().len(), 3);
    // No such file; a description with errors (every one printed); a network and DCFs mixed.
    let out = cli(&["--bus", "mem://boot-cli", "boot", "no-such-network.toml"]);
    assert_eq!(out.code, 2);
    assert!(out.stderr.contains("cannot read no-such-network.toml"), "{}", out.stderr);
    let dir = std::env::temp_dir().join(format!("od-master-boot-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let bad = dir.join("bad.toml");
    std::fs::write(&bad, "[network]\nbaud_rate = 1000\n[nodes.a]\ndevice = \"missing.eds\"\nnode_id = 200\n").unwrap();
    let out = cli(&["--bus", "mem://boot-cli", "boot", bad.to_str().unwrap()]);
    assert_eq!(out.code, 2, "{}", out.stderr);
    assert!(out.stderr.contains("N0201") && out.stderr.contains("N0101"), "{}", out.stderr);
    let out = cli(&["boot", "--plan", EXAMPLE, bad.to_str().unwrap()]);
    assert_eq!(out.code, 2);
    assert!(out.stderr.contains("a network description is given alone"), "{}", out.stderr);
    std::fs::remove_dir_all(dir).ok();
}
