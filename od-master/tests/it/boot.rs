//! A network configured at boot (`od_master::boot`) against the simulated drives on the
//! in-memory bus in virtual time: networks/example.toml on the three drives, a wrong device on
//! a node id, a node that does not answer, and the frames of one PDO remap.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Duration;

use drive::node::DeviceKind;
use od_bus::Endpoint;
use od_master::boot::{self, BootError, BootNode, Stage};
use od_master::{AbortCode, BootOptions, Error, Network, NmtState, NodeReport, TransferError};
use od_runtime::master::SdoError;

use crate::harness::{Net, net, pass};

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn example() -> Network {
    Network::from_description(&repo().join("networks/example.toml")).expect("the example network")
}

const EXAMPLE_SIMS: [(DeviceKind, u8); 3] = [(DeviceKind::Drvi, 2), (DeviceKind::Drcs, 3), (DeviceKind::Akd, 4)];

/// The NMT state of the simulated node at `position` (the order the nodes were given in).
fn nmt_state(n: &Net, position: usize) -> NmtState {
    n.sim.lock().unwrap().node(position).nmt_state()
}

/// The value each object holds after the plan: the last write to it.
fn final_values(node: &BootNode) -> BTreeMap<(u16, u8), Vec<u8>> {
    node.plan.writes.iter().map(|w| ((w.index, w.sub), w.data.clone())).collect()
}

/// Every value the plan wrote reads back over SDO.
async fn check_configured(n: &Net, node: &BootNode) {
    let sdo = n.bus.node(node.node_id).unwrap();
    let values = final_values(node);
    assert!(values.len() > 10, "{}: {} objects configured", node.name, values.len());
    for ((index, sub), want) in values {
        let got = sdo.read_bytes(index, sub).await.unwrap_or_else(|e| panic!("{}: {e}", node.name));
        assert_eq!(got, want, "{}: {index:04X}h sub {sub}", node.name);
    }
}

fn ok(reports: &[NodeReport], name: &str) -> bool {
    let r = reports.iter().find(|r| r.name == name).unwrap();
    r.result.is_ok() && r.started && r.written == r.planned
}

#[tokio::test(start_paused = true)]
async fn the_example_network_boots_on_the_three_drives() {
    let n = net(&EXAMPLE_SIMS);
    pass(Duration::from_millis(10)).await;
    let network = example();
    assert_eq!(
        network.nodes.iter().map(|b| (b.name.as_str(), b.node_id)).collect::<Vec<_>>(),
        [("x_axis", 2), ("y_axis", 3), ("z_axis", 4)]
    );
    for concurrent in [true, false] {
        let reports =
            boot::boot(&n.bus, &network, &BootOptions { start: true, concurrent, ..BootOptions::default() }).await;
        for r in &reports {
            assert!(ok(&reports, &r.name), "{r:?}");
        }
        pass(Duration::from_millis(5)).await;
        for (position, node) in network.nodes.iter().enumerate() {
            check_configured(&n, node).await;
            assert_eq!(nmt_state(&n, position), NmtState::Operational, "{}", node.name);
        }
    }
    // The PDOs work as mapped: x_axis's TPDO 1 (COB-ID 182h) carries statusword and position.
    let mut frames = n.bus.frames();
    pass(Duration::from_millis(50)).await;
    let mut seen = false;
    while let Ok(f) = frames.try_recv() {
        if f.id() == 0x182 {
            assert_eq!(f.data().len(), 6, "statusword (2) + position actual value (4)");
            seen = true;
        }
    }
    assert!(seen, "x_axis sends TPDO 1 every 20 ms (event timer)");
}

/// The example network with y_axis's device description replaced by `eds`.
fn example_with_y(eds: &Path) -> Network {
    let text = std::fs::read_to_string(repo().join("networks/example.toml")).unwrap();
    let text = text.replace("\"../devices/camozzi-drcs.eds\"", &format!("{:?}", eds.display().to_string()));
    Network::from_description_text("networks/example.toml", &repo().join("networks"), &text).unwrap()
}

/// A copy of the DRCS's description with another product code (in `[DeviceInfo]` and 1018h).
fn drcs_with_product(code: u32) -> PathBuf {
    let text = std::fs::read_to_string(repo().join("devices/camozzi-drcs.eds")).unwrap();
    let mut out = String::new();
    let mut section = String::new();
    for line in text.lines() {
        if line.starts_with('[') {
            section = line.trim().to_ascii_lowercase();
        }
        let key = line.split('=').next().unwrap_or("").trim();
        if (section == "[deviceinfo]" && key.eq_ignore_ascii_case("ProductNumber"))
            || (section == "[1018sub2]" && key.eq_ignore_ascii_case("DefaultValue"))
        {
            out.push_str(&format!("{key}=0x{code:08X}\r\n"));
        } else {
            out.push_str(line);
            out.push_str("\r\n");
        }
    }
    let dir = std::env::temp_dir().join(format!("od-master-boot-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(format!("drcs-{code:x}.eds"));
    std::fs::write(&path, out).unwrap();
    path
}

#[tokio::test(start_paused = true)]
async fn a_wrong_device_is_named_by_object_and_both_values_and_the_others_start() {
    // The network expects product code 0x5B at node 3; the DRCS there says 0x5A.
    let n = net(&EXAMPLE_SIMS);
    pass(Duration::from_millis(10)).await;
    let eds = drcs_with_product(0x5B);
    let network = example_with_y(&eds);
    let reports = boot::boot(&n.bus, &network, &BootOptions::default()).await;
    let y = reports.iter().find(|r| r.name == "y_axis").unwrap();
    match &y.result {
        Err(e @ BootError::Identity { node: 3, index: 0x1018, sub: 2, expected: 0x5B, found: 0x5A, .. }) => {
            let text = e.to_string();
            assert!(text.contains("node 3 (y_axis)") && text.contains("1018h:2 product code"), "{text}");
            assert!(text.contains("0x0000005A") && text.contains("0x0000005B"), "{text}");
            assert_eq!(e.object(), Some((0x1018, 2)));
        }
        other => panic!("{other:?}"),
    }
    assert_eq!((y.written, y.started), (0, false), "nothing is written to a wrong device");
    assert!(ok(&reports, "x_axis") && ok(&reports, "z_axis"), "{reports:?}");
    pass(Duration::from_millis(5)).await;
    assert_eq!(nmt_state(&n, 0), NmtState::Operational);
    assert_eq!(nmt_state(&n, 2), NmtState::Operational);
    assert_eq!(nmt_state(&n, 1), NmtState::PreOperational, "the wrong device is not started");

    // Another device altogether (a DRVI where the DRCS belongs): its device type differs
    // first (1000h, checked before 1018h as CiA 302-2 does).
    let n = net(&[(DeviceKind::Drvi, 2), (DeviceKind::Drvi, 3), (DeviceKind::Akd, 4)]);
    pass(Duration::from_millis(10)).await;
    let reports = boot::boot(&n.bus, &example(), &BootOptions::default()).await;
    let y = reports.iter().find(|r| r.name == "y_axis").unwrap();
    let text = y.result.as_ref().unwrap_err().to_string();
    assert!(text.contains("1000h:0 device type is 0xFF7A0192") && text.contains("expects 0xFF7C0192"), "{text}");
    assert!(ok(&reports, "x_axis") && ok(&reports, "z_axis"), "{reports:?}");
    std::fs::remove_file(eds).ok();
}

#[tokio::test(start_paused = true)]
async fn a_node_that_does_not_answer_times_out_on_its_first_object_and_the_others_start() {
    let n = net(&[(DeviceKind::Drvi, 2), (DeviceKind::Akd, 4)]);
    pass(Duration::from_millis(10)).await;
    let reports = boot::boot(&n.bus, &example(), &BootOptions::default()).await;
    let y = reports.iter().find(|r| r.name == "y_axis").unwrap();
    match &y.result {
        Err(
            e @ BootError::Bus {
                stage: Stage::Identity,
                error:
                    Error::Sdo {
                        error:
                            TransferError {
                                node: 3,
                                index: 0x1000,
                                sub: 0,
                                error: SdoError::Client(AbortCode::TIMEOUT),
                                ..
                            },
                        ..
                    },
                ..
            },
        ) => {
            let text = e.to_string();
            assert!(text.starts_with("y_axis, checking the identity: node 3, upload of 1000h sub 0"), "{text}");
        }
        other => panic!("{other:?}"),
    }
    assert!(ok(&reports, "x_axis") && ok(&reports, "z_axis"), "{reports:?}");
    pass(Duration::from_millis(5)).await;
    assert_eq!(nmt_state(&n, 0), NmtState::Operational);
    assert_eq!(nmt_state(&n, 1), NmtState::Operational);
}

/// One TPDO remapped (the DRVI's TPDO 1 carries the statusword alone by default): the frames
/// on the bus, exactly, in CiA 301's order.
#[tokio::test(start_paused = true)]
async fn one_pdo_remap_is_written_in_cia_301_order_frame_by_frame() {
    let n = net(&[(DeviceKind::Drvi, 2)]);
    let mut listener = n.sim.lock().unwrap().endpoint();
    pass(Duration::from_millis(10)).await;
    let text = r#"
[network]
baud_rate = 1000
[nodes.x_axis]
device = "../devices/camozzi-drvi.eds"
node_id = 2
tpdo1 = ["statusword", "position_actual_value"]
"#;
    let network = Network::from_description_text("networks/one.toml", &repo().join("networks"), text).unwrap();
    while listener.recv_timeout(Duration::ZERO).unwrap().is_some() {}
    let reports = boot::boot(&n.bus, &network, &BootOptions::default()).await;
    assert!(ok(&reports, "x_axis"), "{reports:?}");
    let mut sent = Vec::new();
    while let Some(f) = listener.recv_timeout(Duration::ZERO).unwrap() {
        // The master's frames: SDO requests to node 2 and NMT.
        if f.id() == 0x602 || f.id() == 0x000 {
            sent.push((f.id(), f.data().to_vec()));
        }
    }
    let sdo = |cs: u8, index: u16, sub: u8, data: &[u8]| {
        let mut d = vec![cs, index as u8, (index >> 8) as u8, sub];
        d.extend_from_slice(data);
        d.resize(8, 0);
        (0x602, d)
    };
    let want = vec![
        // Identity: 1000h, 1018h sub 1..3 (uploads).
        sdo(0x40, 0x1000, 0, &[]),
        sdo(0x40, 0x1018, 1, &[]),
        sdo(0x40, 0x1018, 2, &[]),
        sdo(0x40, 0x1018, 3, &[]),
        // Enter pre-operational.
        (0x000, vec![0x80, 2]),
        // TPDO 1: disabled, mapping count 0, the entry, count 1, enabled.
        sdo(0x23, 0x1800, 1, &0x8000_0182u32.to_le_bytes()),
        sdo(0x2F, 0x1A00, 0, &[0]),
        sdo(0x23, 0x1A00, 1, &0x6041_0010u32.to_le_bytes()),
        sdo(0x23, 0x1A00, 2, &0x6064_0020u32.to_le_bytes()),
        sdo(0x2F, 0x1A00, 0, &[2]),
        sdo(0x23, 0x1800, 1, &0x0000_0182u32.to_le_bytes()),
        // Every node configured: start all.
        (0x000, vec![0x01, 0]),
    ];
    assert_eq!(sent, want);
}

/// The checked-in DCFs of the example (generated/networks/example, `cargo xtask gen`) plan the
/// same checks and writes as the description they were written from.
#[test]
fn the_example_dcfs_plan_what_the_description_plans() {
    let dir = repo().join("generated/networks/example");
    let dcfs: Vec<PathBuf> = ["x_axis", "y_axis", "z_axis"].iter().map(|n| dir.join(format!("{n}.dcf"))).collect();
    let from_dcfs = Network::load(&dcfs).unwrap();
    let from_description = example();
    assert_eq!(from_dcfs.nodes.len(), 3);
    for (a, b) in from_dcfs.nodes.iter().zip(&from_description.nodes) {
        assert_eq!((&a.name, a.node_id), (&b.name, b.node_id));
        assert_eq!(a.plan, b.plan, "{}", a.name);
    }
}

/// Files that cannot be booted: each problem said, nothing sent.
#[test]
fn files_that_cannot_be_booted_are_refused_with_the_reason() {
    let dir = repo().join("generated/networks/example");
    let x = dir.join("x_axis.dcf");
    let err = |files: &[PathBuf]| Network::load(files).unwrap_err().to_string();
    // One DCF twice: one node id twice.
    assert!(err(&[x.clone(), x.clone()]).contains("x_axis and x_axis both have node id 2"));
    // A description with DCFs.
    assert!(err(&[x.clone(), repo().join("networks/example.toml")]).contains("given alone"));
    // An EDS (no [DeviceComissioning] NodeID).
    let e = err(&[repo().join("devices/camozzi-drvi.eds")]);
    assert!(e.contains("no node id") && e.contains("camozzi-drvi.eds"), "{e}");
    // No such file; nothing at all.
    assert!(err(&[dir.join("nope.dcf")]).starts_with("cannot read "));
    assert!(err(&[]).contains("no network description"));
    // A description with errors: the diagnostics, as odgen prints them.
    let e = Network::from_description_text("net.toml", &repo().join("networks"), "[network]\nbaud_rate = 999\n")
        .unwrap_err()
        .to_string();
    assert!(e.contains("N0301") && e.contains("N0006"), "{e}");
}

/// A node that takes its configuration and the NMT start but sends no heartbeat although its
/// 1017h says it will: boot waits three heartbeat periods and says so (CiA 302-2's error K).
#[tokio::test(start_paused = true)]
async fn a_started_node_without_its_heartbeat_is_reported() {
    let network = example();
    let x = network.nodes[0].clone();
    assert_eq!(x.plan.heartbeat_ms, 100);
    let n = net(&[]);
    // An SDO server for node 2 answering uploads with the identity the plan expects and every
    // expedited download with success; it never sends a heartbeat.
    let mut device = n.sim.lock().unwrap().endpoint();
    let identity: BTreeMap<(u16, u8), u32> = x.plan.identity.checks().iter().map(|c| ((c.0, c.1), c.3)).collect();
    tokio::spawn(async move {
        loop {
            while let Ok(Some(f)) = device.recv_timeout(Duration::ZERO) {
                if f.id() != 0x602 || f.data().len() != 8 {
                    continue;
                }
                let d = f.data();
                let (index, sub) = (u16::from_le_bytes([d[1], d[2]]), d[3]);
                let mut answer = [0u8; 8];
                answer[1..4].copy_from_slice(&d[1..4]);
                if d[0] == 0x40 {
                    answer[0] = 0x43;
                    answer[4..].copy_from_slice(&identity.get(&(index, sub)).copied().unwrap_or(0).to_le_bytes());
                } else {
                    answer[0] = 0x60;
                }
                device.send(od_bus::CanFrame::standard(0x582, &answer).unwrap()).unwrap();
            }
            tokio::time::sleep(Duration::from_micros(200)).await;
        }
    });
    let one = Network { nodes: vec![x], ..Network::default() };
    let reports = boot::boot(&n.bus, &one, &BootOptions::default()).await;
    let r = &reports[0];
    assert!(r.started && r.written == r.planned, "{r:?}");
    match &r.result {
        Err(e @ BootError::NoHeartbeat { node: 2, heartbeat_ms: 100, waited_ms: 300, .. }) => {
            assert_eq!(
                e.to_string(),
                "node 2 (x_axis): no heartbeat saying Operational within 300 ms of the NMT start (1017h = 100 ms)"
            );
            assert_eq!(e.object(), Some((0x1017, 0)));
        }
        other => panic!("{other:?}"),
    }
}
