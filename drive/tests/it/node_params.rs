//! DCF values (`--dcf`) on a running node: applied at start and at every reset, under the
//! values a master stored, with every problem of a bad DCF reported with its place.

use std::path::PathBuf;

use drive::node::{DefaultApps, DeviceKind, NodeConfig, NodeSetupError, Sim, VirtualBus};
use od_bus::{CanFrame, Endpoint, LocalEndpoint};

/// The DRVI's EDS with `ParameterValue=` lines added to the named sections and, when given,
/// a `[DeviceComissioning]` section: a DCF as a configuration tool writes one.
fn drvi_dcf(values: &[(&str, &str)], node_id: Option<u8>) -> String {
    let mut out = String::new();
    for line in generated::drvi::EDS.lines() {
        out.push_str(line);
        out.push('\n');
        if let Some(&(_, value)) = values.iter().find(|(section, _)| line == format!("[{section}]")) {
            out.push_str(&format!("ParameterValue={value}\n"));
        }
    }
    if let Some(id) = node_id {
        out.push_str(&format!("\n[DeviceComissioning]\nNodeID={id}\nNodeName=axis\nBaudrate=1000\n"));
    }
    out
}

struct TempFile(PathBuf);

impl TempFile {
    fn new(name: &str, text: &str) -> Self {
        let path = std::env::temp_dir().join(format!("drive-node-params-{}-{name}", std::process::id()));
        std::fs::write(&path, text).unwrap();
        Self(path)
    }
}

impl Drop for TempFile {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

fn frame(text: &str) -> CanFrame {
    text.parse().unwrap()
}

fn drain(ep: &mut LocalEndpoint) -> Vec<String> {
    let mut out = Vec::new();
    while let Some(f) = ep.try_recv().unwrap() {
        out.push(f.to_string());
    }
    out
}

/// A frame of the test's own on the raw endpoint, and what came back at the same instant.
fn exchange(sim: &mut VirtualBus, master: &mut LocalEndpoint, request: &str) -> Vec<String> {
    master.send(frame(request)).unwrap();
    sim.advance(0);
    drain(master)
}

/// The whole value of an SDO upload by od-master (expedited or segmented, as the device
/// answers); the transfer's frames are taken off the raw endpoint.
fn upload(sim: &mut VirtualBus, master: &mut LocalEndpoint, node: u8, index: u16, sub: u8) -> Vec<u8> {
    let drive = sim.bus().node(node).unwrap();
    let value = sim.run(drive.read_bytes(index, sub)).unwrap_or_else(|e| panic!("upload {index:04X}h sub {sub}: {e}"));
    drain(master);
    value
}

fn u32_of(bytes: &[u8]) -> u32 {
    let mut b = [0u8; 4];
    b[..bytes.len()].copy_from_slice(bytes);
    u32::from_le_bytes(b)
}

/// The node on a simulation with od-master on its bus, and a raw endpoint for the tests' own
/// frames.
fn sim_with_dcf(text: &str, name: &str, node_id: Option<u8>) -> (VirtualBus, LocalEndpoint, TempFile) {
    let file = TempFile::new(name, text);
    let node = DeviceKind::Drvi
        .build(&NodeConfig { node_id, dcf: Some(file.0.clone()), ..NodeConfig::default() }, &DefaultApps)
        .unwrap();
    let mut sim = Sim::new();
    let master = sim.endpoint();
    sim.add(node);
    (VirtualBus::new(sim, od_master::Config::default()).unwrap(), master, file)
}

const VALUES: &[(&str, &str)] = &[
    ("1008", "DRVI simulated by drive-sim"),
    ("1017", "250"),
    ("6083", "5000"),
    ("1801sub1", "$NODEID+0x280"),
    ("1A01sub0", "1"),
    ("1A01sub1", "0x60640020"),
];

#[test]
fn dcf_values_apply_at_start_and_after_every_reset() {
    let (mut sim, mut master, _file) = sim_with_dcf(&drvi_dcf(VALUES, None), "start.dcf", Some(5));
    sim.advance(0);
    assert_eq!(drain(&mut master), ["705#00"]);
    assert_eq!(upload(&mut sim, &mut master, 5, 0x1008, 0), b"DRVI simulated by drive-sim");
    assert_eq!(u32_of(&upload(&mut sim, &mut master, 5, 0x6083, 0)), 5000);
    assert_eq!(u32_of(&upload(&mut sim, &mut master, 5, 0x1801, 1)), 0x285);
    // The heartbeat of the DCF runs from the start: 250 ms.
    sim.advance(250_000);
    assert_eq!(drain(&mut master), ["705#7F"]);
    // TPDO2 as the DCF configured it (valid, actual position): sent on entering Operational.
    assert_eq!(exchange(&mut sim, &mut master, "000#0105"), ["185#4002", "285#00000000"]);

    // Changed over SDO, then reset node: the DCF's value again.
    assert_eq!(exchange(&mut sim, &mut master, "605#2383600001000000"), ["585#6083600000000000"]);
    assert_eq!(exchange(&mut sim, &mut master, "000#8105"), ["705#00"]);
    assert_eq!(u32_of(&upload(&mut sim, &mut master, 5, 0x6083, 0)), 5000);
    // Reset communication restores the communication area only.
    assert_eq!(exchange(&mut sim, &mut master, "605#2B17100000000000"), ["585#6017100000000000"]);
    assert_eq!(exchange(&mut sim, &mut master, "605#2383600002000000"), ["585#6083600000000000"]);
    assert_eq!(exchange(&mut sim, &mut master, "000#8205"), ["705#00"]);
    assert_eq!(u32_of(&upload(&mut sim, &mut master, 5, 0x1017, 0)), 250);
    assert_eq!(u32_of(&upload(&mut sim, &mut master, 5, 0x6083, 0)), 2);
}

#[test]
fn stored_values_win_and_restoring_defaults_returns_to_the_dcf() {
    let (mut sim, mut master, _file) = sim_with_dcf(&drvi_dcf(VALUES, None), "stored.dcf", Some(5));
    sim.advance(0);
    drain(&mut master);
    assert_eq!(exchange(&mut sim, &mut master, "605#2383600007000000"), ["585#6083600000000000"]);
    // Save all ("save"), reset node: the stored 7 wins over the DCF's 5000.
    assert_eq!(exchange(&mut sim, &mut master, "605#2310100173617665"), ["585#6010100100000000"]);
    assert_eq!(exchange(&mut sim, &mut master, "000#8105"), ["705#00"]);
    assert_eq!(u32_of(&upload(&mut sim, &mut master, 5, 0x6083, 0)), 7);
    // Restore defaults ("load"), reset node: the DCF's value, not the EDS default (0).
    assert_eq!(exchange(&mut sim, &mut master, "605#231110016C6F6164"), ["585#6011100100000000"]);
    assert_eq!(exchange(&mut sim, &mut master, "000#8105"), ["705#00"]);
    assert_eq!(u32_of(&upload(&mut sim, &mut master, 5, 0x6083, 0)), 5000);
}

#[test]
fn the_dcf_node_id_is_used_when_none_is_given() {
    let (mut sim, mut master, _file) = sim_with_dcf(&drvi_dcf(VALUES, Some(9)), "nodeid.dcf", None);
    sim.advance(0);
    assert_eq!(drain(&mut master), ["709#00"]);
    assert_eq!(u32_of(&upload(&mut sim, &mut master, 9, 0x1801, 1)), 0x289);
    // A node id given explicitly wins over the DCF's.
    let (mut sim, mut master, _file) = sim_with_dcf(&drvi_dcf(VALUES, Some(9)), "nodeid2.dcf", Some(12));
    sim.advance(0);
    assert_eq!(drain(&mut master), ["70C#00"]);
    assert_eq!(u32_of(&upload(&mut sim, &mut master, 12, 0x1801, 1)), 0x28C);
}

#[test]
fn a_bad_dcf_is_refused_with_every_problem_and_its_line() {
    let mut text = drvi_dcf(&[("6083", "99999999999"), ("6071", "20000"), ("1017", "$NODEID+1")], None);
    text.push_str("\n[2FFF]\nParameterName=Not a DRVI object\nObjectType=0x7\nDataType=0x0007\nAccessType=rw\nDefaultValue=0\nParameterValue=1\nPDOMapping=0\n");
    let line_of = |needle: &str| text.lines().position(|l| l == needle).unwrap() + 1;
    let (l6083, l6071, l2fff) = (line_of("[6083]"), line_of("[6071]"), line_of("[2FFF]"));
    let file = TempFile::new("bad.dcf", &text);
    let err = DeviceKind::Drvi
        .build(&NodeConfig { node_id: Some(3), dcf: Some(file.0.clone()), ..NodeConfig::default() }, &DefaultApps)
        .err()
        .expect("the DCF is refused");
    let NodeSetupError::Dcf { error, .. } = &err else { panic!("{err}") };
    let text = err.to_string();
    assert_eq!(error.problems.len(), 3, "{text}");
    // Each problem names the file and the line of the entry (its section header).
    assert!(
        error
            .problems
            .iter()
            .any(|p| p.contains(&format!("bad.dcf:{l6083}:")) && p.contains("does not fit in 32 bits")),
        "{text}"
    );
    assert!(error.problems.iter().any(|p| p.contains(&format!(":{l6071}:")) && p.contains("HighLimit")), "{text}");
    assert!(
        error.problems.iter().any(|p| p.contains(&format!(":{l2fff}:")) && p.contains("no entry 0x2FFFsub0")),
        "{text}"
    );
}

#[test]
fn node_relative_values_need_a_node_id() {
    let file = TempFile::new("noid.dcf", &drvi_dcf(&[("1801sub1", "$NODEID+0x280")], None));
    let err = DeviceKind::Drvi
        .build(&NodeConfig { dcf: Some(file.0.clone()), ..NodeConfig::default() }, &DefaultApps)
        .err()
        .expect("refused");
    assert!(err.to_string().contains("$NODEID"), "{err}");
    // Without a DCF, no node id at all.
    let err = DeviceKind::Drvi.build(&NodeConfig::default(), &DefaultApps).err().unwrap();
    assert!(matches!(err, NodeSetupError::NoNodeId), "{err}");
    let err =
        DeviceKind::Akd.build(&NodeConfig { node_id: Some(128), ..NodeConfig::default() }, &DefaultApps).err().unwrap();
    assert!(matches!(err, NodeSetupError::BadNodeId(128)), "{err}");
}

#[test]
fn a_missing_dcf_file_is_an_error() {
    let path = std::env::temp_dir().join(format!("drive-node-params-{}-absent.dcf", std::process::id()));
    let err = DeviceKind::Drcs
        .build(&NodeConfig { node_id: Some(3), dcf: Some(path.clone()), ..NodeConfig::default() }, &DefaultApps)
        .err()
        .unwrap();
    assert!(err.to_string().contains(&path.display().to_string()), "{err}");
}
