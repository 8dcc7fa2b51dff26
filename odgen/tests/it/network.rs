//! `odgen::network`: DCFs for a network description.
//!
//! The example network (`networks/example.toml`, the three project devices) must give three DCFs
//! that read back strictly with the configured values. Every error path is checked against a
//! snapshot of its rendered diagnostic; those use the small fixture `tests/fixtures/drive.eds`,
//! so that the snapshots do not move when the project's device descriptions are edited.

use std::path::{Path, PathBuf};

use eds::model::{Radix, Value};
use odgen::network::{self, Outcome};

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().expect("odgen/ has a parent").to_path_buf()
}

fn example() -> Outcome {
    let path = repo().join("networks/example.toml");
    let text = std::fs::read_to_string(&path).expect("read networks/example.toml");
    network::build("networks/example.toml", &repo().join("networks"), &text)
}

/// Builds a network whose devices are in `odgen/tests/fixtures`.
fn fixture(toml: &str) -> Outcome {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures");
    network::build("tests/fixtures/net.toml", &dir, toml)
}

/// The rendered diagnostics of a network that must fail.
fn errors(toml: &str) -> String {
    let o = fixture(toml);
    assert!(o.has_errors(), "expected errors, got none for:\n{toml}");
    assert!(o.dcfs.is_empty(), "no DCF may be produced when there are errors");
    network::render_all(&o.diagnostics)
}

const HEAD: &str = "[network]\nbaud_rate = 500\n\n[nodes.axis]\ndevice = \"drive.eds\"\nnode_id = 5\n";

fn entry(m: &eds::Model, index: u16, sub: u8) -> &eds::Entry {
    m.entry(index, sub).unwrap_or_else(|| panic!("0x{index:04X} sub {sub} missing"))
}

fn pv(m: &eds::Model, index: u16, sub: u8) -> Option<i128> {
    entry(m, index, sub).parameter_value().and_then(|v| v.as_int())
}

#[test]
fn example_network_gives_three_dcfs_that_read_back_strictly() {
    let o = example();
    assert!(!o.has_errors(), "{}", network::render_all(&o.diagnostics));
    assert!(o.diagnostics.is_empty(), "{}", network::render_all(&o.diagnostics));
    let names: Vec<(&str, u8, &str)> = o.dcfs.iter().map(|d| (d.name.as_str(), d.node_id, d.device.as_str())).collect();
    assert_eq!(
        names,
        [
            ("x_axis", 2, "devices/camozzi-drvi.eds"),
            ("y_axis", 3, "devices/camozzi-drcs.eds"),
            ("z_axis", 4, "devices/kollmorgen-akd.eds"),
        ]
    );
    for dcf in &o.dcfs {
        let back = eds::parse(&dcf.file_name, dcf.text.as_bytes(), &eds::Options::strict());
        let errors: Vec<String> = back.errors().map(|d| eds::diag::render(d, &back.document.source)).collect();
        assert!(errors.is_empty(), "{}: {}", dcf.file_name, errors.join("\n"));
        assert_eq!(back.model, dcf.model, "{}: the text does not read back as the model", dcf.file_name);
        let m = &back.model;
        assert_eq!(m.kind, eds::FileKind::Dcf);
        assert_eq!(m.file_info.file_name.as_deref(), Some(dcf.file_name.as_str()));
        let c = m.commissioning.as_ref().expect("[DeviceComissioning]");
        assert_eq!(c.node_id, Some(dcf.node_id));
        assert_eq!(c.baudrate, Some(1000));
        assert_eq!(c.node_name.as_deref(), Some(dcf.name.as_str()));
        assert_eq!(c.network_name.as_deref(), Some("example"));
        let id = i128::from(dcf.node_id);

        // Mappings, as the network file names them.
        let (rpdo1_second, rpdo2_second) =
            if dcf.name == "z_axis" { (0x60FF_0020, 0x607A_0020) } else { (0x607A_0020, 0x60FF_0020) };
        assert_eq!(pv(m, 0x1600, 0), Some(2));
        assert_eq!(pv(m, 0x1600, 1), Some(0x6040_0010));
        assert_eq!(pv(m, 0x1600, 2), Some(rpdo1_second));
        assert_eq!(pv(m, 0x1601, 0), Some(2));
        assert_eq!(pv(m, 0x1601, 1), Some(0x6060_0008));
        assert_eq!(pv(m, 0x1601, 2), Some(rpdo2_second));
        assert_eq!(pv(m, 0x1A00, 0), Some(2));
        assert_eq!(pv(m, 0x1A00, 1), Some(0x6041_0010));
        assert_eq!(pv(m, 0x1A00, 2), Some(0x6064_0020));
        assert_eq!(pv(m, 0x1A01, 0), Some(2));
        assert_eq!(pv(m, 0x1A01, 1), Some(0x6061_0008));
        assert_eq!(pv(m, 0x1A01, 2), Some(0x606C_0020));
        // Communication settings.
        assert_eq!(pv(m, 0x1800, 2), Some(255));
        assert_eq!(pv(m, 0x1800, 5), Some(20));
        assert_eq!(pv(m, 0x1801, 2), Some(1));
        if dcf.name == "x_axis" {
            assert_eq!(pv(m, 0x1800, 3), Some(10));
        }
        // COB-IDs: resolved ParameterValue, DefaultValue keeps $NODEID; the PDOs are valid.
        for (index, base) in [(0x1400u16, 0x200), (0x1401, 0x300), (0x1800, 0x180), (0x1801, 0x280)] {
            let e = entry(m, index, 1);
            assert!(e.default.as_ref().is_some_and(Value::is_node_relative), "0x{index:04X}: {:?}", e.default);
            assert_eq!(
                e.parameter_value().cloned(),
                Some(Value::Int { value: base + id, radix: Radix::Hex }),
                "0x{index:04X}"
            );
        }
        // No $NODEID is left unresolved in a ParameterValue, and each one resolves as the default.
        for (_, e) in m.entries() {
            if let Some(d @ Value::NodeIdPlus { .. }) = &e.default {
                let p = e.parameter_value().expect("node-relative entries get a ParameterValue");
                assert!(!p.is_node_relative());
                if p.as_int() != d.resolve(dcf.node_id) {
                    // Only PDO COB-IDs may differ, in the valid bit (31).
                    assert_eq!(p.as_int().unwrap() | 0x8000_0000, d.resolve(dcf.node_id).unwrap() | 0x8000_0000);
                }
            }
        }
        // Parameters by name and by index.
        assert_eq!(pv(m, 0x1017, 0), Some(100));
        assert_eq!(pv(m, 0x6060, 0), Some(if dcf.name == "z_axis" { 3 } else { 1 }));
    }
}

#[test]
fn unmentioned_pdos_keep_their_defaults_and_an_empty_list_disables_a_pdo() {
    let o = fixture(&format!("{HEAD}tpdo1 = []\n"));
    assert!(!o.has_errors(), "{}", network::render_all(&o.diagnostics));
    let m = &o.dcfs[0].model;
    assert_eq!(pv(m, 0x1A00, 0), Some(0));
    assert_eq!(pv(m, 0x1800, 1), Some(0x8000_0185), "disabled: bit 31 set");
    assert_eq!(pv(m, 0x1600, 0), None, "RPDO 1 mapping untouched");
    assert_eq!(pv(m, 0x1400, 1), Some(0x205), "COB-ID resolved all the same");
    assert_eq!(pv(m, 0x1014, 0), Some(0x85));
    // Enabling a PDO whose default COB-ID is not valid clears bit 31.
    let o = fixture(&format!("{HEAD}rpdo2 = [\"target_velocity\"]\n"));
    assert!(!o.has_errors(), "{}", network::render_all(&o.diagnostics));
    assert_eq!(pv(&o.dcfs[0].model, 0x1401, 1), Some(0x305));
}

#[test]
fn values_by_name_index_string_bool_and_float() {
    let o = fixture(&format!(
        "{HEAD}\n[nodes.axis.parameters]\nmodes_of_operation = -3\n\"0x1017sub0\" = 0x64\n\"0x1800sub1\" = \"$NODEID+0x190\"\n"
    ));
    assert!(!o.has_errors(), "{}", network::render_all(&o.diagnostics));
    let m = &o.dcfs[0].model;
    assert_eq!(entry(m, 0x6060, 0).parameter_value().cloned(), Some(Value::int(-3)));
    assert_eq!(entry(m, 0x1017, 0).parameter_value().cloned(), Some(Value::hex(100)));
    assert_eq!(entry(m, 0x1800, 1).parameter_value().cloned(), Some(Value::hex(0x195)), "resolved for node 5");
    assert_eq!(entry(m, 0x1800, 1).default, Some(Value::NodeIdPlus { offset: 0x180, radix: Radix::Hex }));
}

#[test]
fn names_are_the_generated_accessors() {
    // Every name the network resolves must be an accessor of the code od-codegen generates for
    // the device, and for every entry of the generated table there is one name.
    for file in ["camozzi-drvi.eds", "camozzi-drcs.eds", "kollmorgen-akd.eds"] {
        let path = repo().join("devices").join(file);
        let parsed = eds::read_file(&path, &eds::Options::lenient()).unwrap();
        let options = od_codegen::Options::new("dev", file);
        let generated = od_codegen::expand(&parsed.model, &options);
        let text = od_codegen::render(&generated.tokens, file).expect("generated code parses");
        let names = network::names::NameIndex::new(&parsed.model);
        let mut count = 0;
        for (name, (index, sub)) in names.iter() {
            let getter = format!("fn {name}(");
            assert!(text.contains(&getter), "{file}: 0x{index:04X} sub {sub}: no `{getter}` in the generated code");
            count += 1;
        }
        assert!(count > 100, "{file}: only {count} names");
        assert_eq!(names.name_of(0x6041, 0), Some("statusword"));
        assert_eq!(names.name_of(0x1018, 1), Some("identity_object_vendor_id"));
    }
}

#[test]
fn cli_writes_the_example_network() {
    let out = std::env::temp_dir().join(format!("odgen-network-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_odgen"))
        .current_dir(repo())
        .args(["dcf", "--network", "networks/example.toml", "-o"])
        .arg(&out)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    assert!(stderr.contains("x_axis.dcf (node 2, devices/camozzi-drvi.eds)"), "{stderr}");
    for dcf in example().dcfs {
        let written = std::fs::read_to_string(out.join(&dcf.file_name)).unwrap();
        assert_eq!(written, dcf.text, "{}", dcf.file_name);
    }
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn cli_writes_nothing_when_the_network_has_errors() {
    let dir = std::env::temp_dir().join(format!("odgen-network-bad-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/drive.eds");
    let net = dir.join("net.toml");
    std::fs::write(
        &net,
        format!(
            "[network]\nbaud_rate = 500\n[nodes.a]\ndevice = {:?}\nnode_id = 5\n[nodes.b]\ndevice = {:?}\nnode_id = 200\n",
            fixtures.display().to_string(),
            fixtures.display().to_string()
        ),
    )
    .unwrap();
    let out = dir.join("out");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_odgen"))
        .args(["dcf", "--network"])
        .arg(&net)
        .arg("-o")
        .arg(&out)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("error[N0201]: node id 200 is outside 1..=127"), "{stderr}");
    assert!(stderr.contains("no DCF written (1 problem)"), "{stderr}");
    assert!(!out.exists(), "nothing is written, not even the good node's DCF");
    // A missing network file is trouble (2), as is --network without -o.
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_odgen"))
        .args(["dcf", "--network", "/nonexistent/net.toml", "-o"])
        .arg(&out)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("cannot read /nonexistent/net.toml"));
    let o =
        std::process::Command::new(env!("CARGO_BIN_EXE_odgen")).args(["dcf", "--network"]).arg(&net).output().unwrap();
    assert_eq!(o.status.code(), Some(2));
    let _ = std::fs::remove_dir_all(&dir);
}

// ---- Error paths: one snapshot of the rendered diagnostics each. ----

#[test]
fn unknown_object_with_hint() {
    insta::assert_snapshot!(errors(&format!("{HEAD}tpdo1 = [\"statusward\", \"position_actual\"]\n")));
}

#[test]
fn parameter_name_not_in_snake_case() {
    insta::assert_snapshot!(errors(&format!("{HEAD}\n[nodes.axis.parameters]\n\"Producer heartbeat time\" = 100\n")));
}

#[test]
fn pdo_over_64_bits() {
    insta::assert_snapshot!(errors(&format!(
        "{HEAD}tpdo1 = [\"statusword\", \"position_actual_value\", \"velocity_actual_value\"]\n"
    )));
}

#[test]
fn non_mappable_object() {
    insta::assert_snapshot!(errors(&format!("{HEAD}tpdo1 = [\"producer_heartbeat_time\"]\n")));
}

#[test]
fn rpdo_mapping_a_read_only_object() {
    insta::assert_snapshot!(errors(&format!("{HEAD}rpdo1 = [\"controlword\", \"statusword\"]\n")));
}

#[test]
fn too_many_pdos() {
    insta::assert_snapshot!(errors(&format!("{HEAD}tpdo3 = [\"statusword\"]\n")));
}

#[test]
fn fixed_mapping_and_too_many_entries() {
    insta::assert_snapshot!(errors(&format!(
        "{HEAD}tpdo2 = [\"statusword\"]\nrpdo1 = [\"modes_of_operation\", \"modes_of_operation\", \"modes_of_operation\", \"modes_of_operation\", \"modes_of_operation\"]\n"
    )));
}

#[test]
fn strings_cannot_be_mapped_by_name() {
    insta::assert_snapshot!(errors(&format!("{HEAD}tpdo1 = [\"manufacturer_device_name\"]\n")));
}

#[test]
fn bad_node_id() {
    insta::assert_snapshot!(errors(
        "[network]\nbaud_rate = 500\n\n[nodes.a]\ndevice = \"drive.eds\"\nnode_id = 0\n\n[nodes.b]\ndevice = \"drive.eds\"\nnode_id = 128\n\n[nodes.c]\ndevice = \"drive.eds\"\nnode_id = \"5\"\n"
    ));
}

#[test]
fn node_id_collision() {
    insta::assert_snapshot!(errors(
        "[network]\nbaud_rate = 500\n\n[nodes.left]\ndevice = \"drive.eds\"\nnode_id = 1\n\n[nodes.right]\ndevice = \"drive.eds\"\nnode_id = 1\n"
    ));
}

#[test]
fn baud_rate_the_device_does_not_support() {
    insta::assert_snapshot!(errors(
        "[network]\nbaud_rate = 800\n\n[nodes.axis]\ndevice = \"drive.eds\"\nnode_id = 5\n"
    ));
}

#[test]
fn baud_rate_not_canopen_and_mismatched() {
    insta::assert_snapshot!(errors(
        "[network]\nbaud_rate = 300\n\n[nodes.a]\ndevice = \"drive.eds\"\nnode_id = 5\nbaud_rate = 500\n"
    ));
    insta::assert_snapshot!(errors("[nodes.a]\ndevice = \"drive.eds\"\nnode_id = 5\n"));
}

#[test]
fn bad_values() {
    insta::assert_snapshot!(errors(&format!(
        "{HEAD}\n[nodes.axis.parameters]\nmodes_of_operation = 11\ndevice_type = 1\nproducer_heartbeat_time = \"fast\"\nidentity_object = 1\n\"0x6065\" = 1\n"
    )));
}

#[test]
fn configured_twice() {
    insta::assert_snapshot!(errors(&format!(
        "{HEAD}tpdo1 = [\"statusword\"]\n\n[nodes.axis.parameters]\n\"0x1A00sub1\" = 0x60410010\n"
    )));
}

#[test]
fn pdo_settings() {
    insta::assert_snapshot!(errors(&format!(
        "{HEAD}\n[nodes.axis.rpdo1]\nmap = [\"controlword\"]\ninhibit_time = 10\nevent_timer = 5\n\n[nodes.axis.tpdo1]\nmap = [\"statusword\"]\ntransmission_type = 245\ninhibit_time = 70000\n"
    )));
}

#[test]
fn file_level_problems() {
    insta::assert_snapshot!(errors(
        "[network]\nbaud_rate = 500\nnmae = \"x\"\n\n[nodes.\"a b\"]\nnode_id = 5\ntpod1 = []\n"
    ));
    insta::assert_snapshot!(errors("[network\nbaud_rate = 500\n"));
    insta::assert_snapshot!(errors("[network]\nbaud_rate = 500\n[nodes.a]\ndevice = \"missing.eds\"\nnode_id = 5\n"));
}
