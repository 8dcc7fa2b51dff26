//! Commissioning with LSS (`od_master::lss`) against the simulated drives in virtual time:
//! three drives without a node-ID found by fastscan, given nodes 2, 3 and 4 from a copy of
//! networks/example.toml with serial numbers, booted after a power cycle; three drives that all
//! start as node 1; duplicate identities, a device that is not there, a bit rate outside the
//! table.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use drive::drives::DeviceApps;
use drive::node::{AnyNode, DeviceKind, NodeConfig, Sim};
use od_master::lss::{self, ErrorKind, Identity, Lss, Step};
use od_master::{BootOptions, Bus, Config, Error, Network, boot};

use crate::harness::{STEP, pass};

const DRIVES: [(DeviceKind, u32); 3] = [(DeviceKind::Drvi, 1001), (DeviceKind::Drcs, 1002), (DeviceKind::Akd, 1003)];

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// A fresh state directory for one test.
fn state_dir(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("od-master-lss-{test}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

/// networks/example.toml with `serial = N` in each node's table (x, y, z: 1001, 1002, 1003).
fn example_with_serials() -> Network {
    let text = std::fs::read_to_string(repo().join("networks/example.toml")).unwrap();
    let mut out = String::new();
    let mut serials = DRIVES.iter().map(|d| d.1);
    for line in text.lines() {
        out.push_str(line);
        out.push('\n');
        if line.starts_with("node_id = ") {
            out.push_str(&format!("serial = {}\n", serials.next().unwrap()));
        }
    }
    Network::from_description_text("example-lss.toml", &repo().join("networks"), &out)
        .expect("the example with serials")
}

fn drive(kind: DeviceKind, node_id: u8, serial: u32, dir: &Path) -> Box<dyn AnyNode> {
    let config =
        NodeConfig { node_id: Some(node_id), serial: Some(serial), state_dir: Some(dir.into()), ..Default::default() };
    kind.build(&config, &DeviceApps::new()).expect("a simulated drive")
}

struct Net {
    bus: Bus,
    sim: Arc<Mutex<Sim>>,
}

fn net(nodes: Vec<Box<dyn AnyNode>>) -> Net {
    let mut sim = Sim::new();
    for n in nodes {
        sim.add(n);
    }
    let (bus, sim) = drive::node::spawn_with_master(sim, Config::default(), STEP);
    Net { bus, sim }
}

fn active_ids(n: &Net) -> Vec<Option<u8>> {
    let sim = n.sim.lock().unwrap();
    (0..DRIVES.len()).map(|i| sim.node(i).active_node_id().map(|id| id.get())).collect()
}

fn unconfigured(dir: &Path) -> Net {
    net(DRIVES.iter().map(|&(kind, serial)| drive(kind, 255, serial, dir)).collect())
}

#[tokio::test(start_paused = true)]
async fn three_drives_without_node_id_are_found_assigned_and_boot_after_a_power_cycle() {
    let dir = state_dir("three");
    let network = example_with_serials();
    let plan = network.lss_plan();
    assert_eq!(plan.iter().map(|p| (p.0.serial, p.1)).collect::<Vec<_>>(), [(1001, 2), (1002, 3), (1003, 4)]);
    {
        let n = unconfigured(&dir);
        let mut frames = n.bus.frames();
        pass(Duration::from_millis(20)).await;
        assert_eq!(active_ids(&n), [None, None, None]);
        assert!(frames.try_recv().is_err(), "no boot-up from a drive without a node-ID");

        let mut session = Lss::new(&n.bus);
        // Answers come within a simulation step (200 µs): a short step timeout keeps the test cheap.
        session.set_timeout(Duration::from_millis(5));
        let mut found = session.scan([None; 4]).await.unwrap();
        found.sort_by_key(|id| id.serial);
        let want: Vec<Identity> = plan.iter().map(|p| p.0).collect();
        assert_eq!(found, want, "fastscan finds each drive with the identity of its EDS and serial");

        let start = tokio::time::Instant::now();
        let report = session.assign(&plan).await.unwrap();
        assert_eq!(report.assigned, plan);
        assert!(report.unknown.is_empty() && report.missing.is_empty(), "{report:?}");
        assert!(start.elapsed() < Duration::from_secs(3), "assignment took {:?}", start.elapsed());
        pass(Duration::from_millis(5)).await;
        assert_eq!(active_ids(&n), [Some(2), Some(3), Some(4)]);
    }
    // Power cycle: the same drives, made without a node-ID again, start with the stored ones.
    let n = unconfigured(&dir);
    pass(Duration::from_millis(20)).await;
    assert_eq!(active_ids(&n), [Some(2), Some(3), Some(4)]);
    let reports = boot::boot(&n.bus, &network, &BootOptions::default()).await;
    for r in &reports {
        assert!(r.result.is_ok() && r.started, "{r:?}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[tokio::test(start_paused = true)]
async fn three_drives_all_at_node_1_unconfigure_all_then_assign() {
    let dir = state_dir("node1");
    let network = example_with_serials();
    let n = net(DRIVES.iter().map(|&(kind, serial)| drive(kind, 1, serial, &dir)).collect());
    pass(Duration::from_millis(20)).await;
    assert_eq!(active_ids(&n), [Some(1), Some(1), Some(1)]);
    let mut session = Lss::new(&n.bus);
    session.set_timeout(Duration::from_millis(5));
    // All at node 1: fastscan sees none of them.
    assert_eq!(session.scan([None; 4]).await.unwrap(), []);
    session.unconfigure_all().await.unwrap();
    pass(Duration::from_millis(5)).await;
    assert_eq!(active_ids(&n), [None, None, None]);
    let report = session.assign(&network.lss_plan()).await.unwrap();
    assert_eq!(report.assigned.len(), 3, "{report:?}");
    pass(Duration::from_millis(5)).await;
    assert_eq!(active_ids(&n), [Some(2), Some(3), Some(4)]);
    let reports = boot::boot(&n.bus, &network, &BootOptions::default()).await;
    assert!(reports.iter().all(|r| r.result.is_ok()), "{reports:?}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[tokio::test(start_paused = true)]
async fn unknown_devices_are_listed_missing_ones_reported() {
    let dir = state_dir("unknown");
    let network = example_with_serials();
    // The DRCS has a serial number the description does not know; the AKD is not there.
    let n = net(vec![drive(DeviceKind::Drvi, 255, 1001, &dir), drive(DeviceKind::Drcs, 255, 77, &dir)]);
    pass(Duration::from_millis(20)).await;
    let mut session = Lss::new(&n.bus);
    session.set_timeout(Duration::from_millis(5));
    let report = session.assign(&network.lss_plan()).await.unwrap();
    assert_eq!(report.assigned.iter().map(|a| (a.0.serial, a.1)).collect::<Vec<_>>(), [(1001, 2)]);
    assert_eq!(report.unknown.iter().map(|i| i.serial).collect::<Vec<_>>(), [77]);
    assert_eq!(report.missing.iter().map(|m| (m.0.serial, m.1)).collect::<Vec<_>>(), [(1002, 3), (1003, 4)]);
    let sim = n.sim.lock().unwrap();
    assert_eq!(sim.node(1).active_node_id(), None, "an unknown device is left alone");
    drop(sim);
    let _ = std::fs::remove_dir_all(&dir);
}

#[tokio::test(start_paused = true)]
async fn duplicate_identity_absent_device_and_bad_bit_rate_are_clear_errors() {
    let dir = state_dir("dup");
    let n = net(vec![drive(DeviceKind::Drvi, 255, 7, &dir), drive(DeviceKind::Drvi, 255, 7, &dir.join("b"))]);
    pass(Duration::from_millis(20)).await;
    let mut session = Lss::new(&n.bus);
    let start = tokio::time::Instant::now();
    let e = session.scan([None; 4]).await.unwrap_err();
    let Error::Lss { error, .. } = &e else { panic!("{e}") };
    assert_eq!(error.kind, ErrorKind::Duplicate(2), "{e}");
    assert!(e.to_string().contains("2 devices answered: two devices have this identity"), "{e}");
    assert!(start.elapsed() < Duration::from_secs(3), "bounded: {:?}", start.elapsed());

    let id = Identity { vendor: 0x97, product: 0x5A, revision: 1, serial: 7 };
    let e = session.set_node_id(id, 5, true).await.unwrap_err();
    assert!(matches!(&e, Error::Lss { error, .. } if error.kind == ErrorKind::Duplicate(2)), "{e}");

    let absent = Identity { serial: 99, ..id };
    let e = session.set_node_id(absent, 5, true).await.unwrap_err();
    assert_eq!(
        e.to_string(),
        "LSS switch state selective (vendor 00000097h, product 0000005Ah, revision 00000001h, serial 00000063h): no answer within 20 ms"
    );
    assert!(matches!(&e, Error::Lss { error, .. } if matches!(error.step, Step::SwitchSelective(_))));

    let before = session.frames_sent();
    let e = session.configure_bit_rate(100).await.unwrap_err();
    assert_eq!(
        e.to_string(),
        "LSS configure bit timing 100 kbit/s: not a bit rate of the CiA 305 table (1000, 800, 500, 250, 125, 50, 20, 10 kbit/s)"
    );
    assert_eq!(session.frames_sent(), before, "refused before sending");
    // Nobody in configuration: configure node-ID times out, naming the step.
    let e = session.configure_node_id(5).await.unwrap_err();
    assert_eq!(e.to_string(), "LSS configure node-ID 5: no answer within 20 ms");
    let _ = std::fs::remove_dir_all(&dir);
}

#[tokio::test(start_paused = true)]
async fn inquire_bit_rate_and_identify() {
    let dir = state_dir("inquire");
    let n = net(vec![drive(DeviceKind::Akd, 255, 4242, &dir)]);
    pass(Duration::from_millis(20)).await;
    let mut session = Lss::new(&n.bus);
    session.set_timeout(Duration::from_millis(5));
    assert_eq!(session.timeout(), Duration::from_millis(5));
    assert_eq!(session.identify_non_configured().await.unwrap(), 1);
    let found = session.fastscan([None; 4]).await.unwrap().expect("the AKD");
    assert_eq!(found.serial, 4242);
    assert_eq!(session.inquire_identity().await.unwrap(), found);
    assert_eq!(session.inquire_node_id().await.unwrap(), None);
    session.configure_bit_rate(500).await.unwrap();
    session.activate_bit_timing(Duration::from_millis(10)).await.unwrap();
    session.configure_node_id(9).await.unwrap();
    session.store().await.unwrap();
    session.switch_global(lss::Mode::Waiting).await.unwrap();
    pass(Duration::from_millis(5)).await;
    assert_eq!(session.identify_non_configured().await.unwrap(), 0);
    assert_eq!(session.identify_remote(found.vendor, found.product, 0..=u32::MAX, 4000..=5000).await.unwrap(), 1);
    assert_eq!(session.identify_remote(found.vendor, found.product, 0..=u32::MAX, 0..=4000).await.unwrap(), 0);
    let stored = std::fs::read_to_string(dir.join("akd-sn4242.lss")).unwrap();
    assert_eq!(stored, "node_id = 9\nbit_rate = 2\n");
    let _ = std::fs::remove_dir_all(&dir);
}

/// networks/example.toml with the serial numbers of `DRIVES` (x, y, z) and `lss = true` in the
/// nodes `marked` names.
fn example_marked(marked: &[&str]) -> Network {
    let text = std::fs::read_to_string(repo().join("networks/example.toml")).unwrap();
    let mut out = String::new();
    let mut serials = DRIVES.iter().map(|d| d.1);
    let mut node = String::new();
    for line in text.lines() {
        out.push_str(line);
        out.push('\n');
        if let Some(name) = line.strip_prefix("[nodes.") {
            node = name.trim_end_matches(']').to_owned();
        }
        if line.starts_with("node_id = ") {
            out.push_str(&format!("serial = {}\n", serials.next().unwrap()));
            if marked.contains(&node.as_str()) {
                out.push_str("lss = true\n");
            }
        }
    }
    Network::from_description_text("example-lss.toml", &repo().join("networks"), &out).expect("the marked example")
}

#[tokio::test(start_paused = true)]
async fn boot_gives_the_marked_nodes_their_node_id_first_then_boots_them() {
    let dir = state_dir("boot-lss");
    let network = example_marked(&["x_axis", "y_axis", "z_axis"]);
    assert!(network.nodes.iter().all(|n| n.lss && n.lss_store));
    let n = unconfigured(&dir);
    pass(Duration::from_millis(20)).await;
    assert_eq!(active_ids(&n), [None, None, None]);
    let start = tokio::time::Instant::now();
    let outcome = boot::boot_network(&n.bus, &network, &BootOptions::default()).await;
    let took = start.elapsed();
    let lss = outcome.lss.expect("an LSS step");
    assert_eq!(
        lss.assigned.iter().map(|a| (a.0.serial, a.1, a.2)).collect::<Vec<_>>(),
        [(1001, 2, None), (1002, 3, None), (1003, 4, None)]
    );
    assert!(lss.unknown.is_empty() && lss.in_place.is_empty() && lss.failed.is_empty(), "{lss:?}");
    for r in &outcome.nodes {
        assert!(r.result.is_ok() && r.started, "{r:?}");
    }
    assert_eq!(active_ids(&n), [Some(2), Some(3), Some(4)]);
    // Three switch-selective steps, the boot (SDO, heartbeats at 100 ms): well under a second.
    assert!(took < Duration::from_secs(1), "boot with LSS took {took:?}");
    // Stored: the next boot finds them in place and configures no node-ID.
    let outcome = boot::boot_network(&n.bus, &network, &BootOptions::default()).await;
    let lss = outcome.lss.expect("an LSS step");
    assert!(lss.assigned.is_empty(), "{lss:?}");
    assert_eq!(lss.in_place.iter().map(|p| p.1).collect::<Vec<_>>(), [2, 3, 4]);
    assert!(outcome.nodes.iter().all(|r| r.result.is_ok()), "{:?}", outcome.nodes);
    assert!(std::fs::read_to_string(dir.join("drvi-sn1001.lss")).unwrap().starts_with("node_id = 2\n"));
    let _ = std::fs::remove_dir_all(&dir);
}

#[tokio::test(start_paused = true)]
async fn boot_fails_a_marked_node_whose_device_is_missing_and_leaves_others_alone() {
    let dir = state_dir("boot-lss-missing");
    // x and y are marked; the DRCS of y (serial 1002) is not there; z is not marked and is at
    // its node-ID already; a DRVI the description does not know waits without a node-ID.
    let network = example_marked(&["x_axis", "y_axis"]);
    let n = net(vec![
        drive(DeviceKind::Drvi, 255, 1001, &dir),
        drive(DeviceKind::Akd, 4, 1003, &dir),
        drive(DeviceKind::Drvi, 255, 77, &dir),
    ]);
    pass(Duration::from_millis(20)).await;
    let start = tokio::time::Instant::now();
    let outcome = boot::boot_network(&n.bus, &network, &BootOptions::default()).await;
    let took = start.elapsed();
    let lss = outcome.lss.expect("an LSS step");
    assert_eq!(lss.assigned.iter().map(|a| (a.0.serial, a.1)).collect::<Vec<_>>(), [(1001, 2)]);
    assert_eq!(lss.unknown.iter().map(|i| i.serial).collect::<Vec<_>>(), [77], "reported");
    let [x, y, z] = &outcome.nodes[..] else { panic!("{:?}", outcome.nodes) };
    assert!(x.result.is_ok() && x.started, "{x:?}");
    assert!(z.result.is_ok() && z.started, "{z:?}");
    let e = y.result.as_ref().unwrap_err();
    assert!(matches!(e, boot::BootError::Lss { node: 3, serial: 1002, .. }), "{e:?}");
    let text = e.to_string();
    assert!(
        text.starts_with("node 3 (y_axis): giving the device of serial number 1002 its node-ID over LSS failed: "),
        "{text}"
    );
    assert!(
        text.contains("LSS switch state selective (") && text.contains("serial 000003EAh): no answer within"),
        "{text}"
    );
    assert!(!y.started);
    let sim = n.sim.lock().unwrap();
    assert_eq!(sim.node(0).active_node_id().map(|i| i.get()), Some(2));
    assert_eq!(sim.node(1).active_node_id().map(|i| i.get()), Some(4));
    assert_eq!(sim.node(2).active_node_id(), None, "the unknown device is left alone");
    drop(sim);
    // At once: one switch-selective timeout for the missing device, one fastscan of the
    // unknown one, the boot of the others; no wait runs to a long timeout.
    assert!(took < Duration::from_secs(3), "took {took:?}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn lss_keys_are_read_and_checked() {
    let text = std::fs::read_to_string(repo().join("networks/example.toml")).unwrap();
    let with = |extra: &str| text.replacen("node_id = 2\n", &format!("node_id = 2\n{extra}"), 1);
    let n = Network::from_description_text(
        "x.toml",
        &repo().join("networks"),
        &with("serial = 5\nlss = true\nlss_store = false\n"),
    )
    .unwrap();
    assert!(n.nodes[0].lss && !n.nodes[0].lss_store && n.nodes[0].serial == Some(5));
    assert!(!n.nodes[1].lss && n.nodes[1].lss_store, "not marked by default");
    let e = Network::from_description_text("x.toml", &repo().join("networks"), &with("lss = true\n")).unwrap_err();
    assert!(e.to_string().contains("node `x_axis`: `lss = true` needs the device's serial number"), "{e}");
    assert!(e.to_string().contains("add `serial = N`"), "{e}");
    let e =
        Network::from_description_text("x.toml", &repo().join("networks"), &with("lss_store = false\nlss = \"yes\"\n"))
            .unwrap_err()
            .to_string();
    assert!(e.contains("`lss_store` without `lss = true`") && e.contains("`lss`"), "{e}");
}

#[tokio::test(start_paused = true)]
async fn boot_moves_a_marked_device_found_at_another_node_id() {
    let dir = state_dir("boot-lss-moved");
    // x's DRVI answers at node 9 (someone set it by hand); the description wants node 2.
    let network = example_marked(&["x_axis"]);
    let n = net(vec![
        drive(DeviceKind::Drvi, 9, 1001, &dir),
        drive(DeviceKind::Drcs, 3, 1002, &dir),
        drive(DeviceKind::Akd, 4, 1003, &dir),
    ]);
    pass(Duration::from_millis(20)).await;
    let outcome = boot::boot_network(&n.bus, &network, &BootOptions::default()).await;
    let lss = outcome.lss.expect("an LSS step");
    assert_eq!(lss.assigned.iter().map(|a| (a.0.serial, a.1, a.2)).collect::<Vec<_>>(), [(1001, 2, Some(9))]);
    assert!(outcome.nodes.iter().all(|r| r.result.is_ok() && r.started), "{:?}", outcome.nodes);
    // Reset at its old node-ID: it runs at node 2 now, not at its next power cycle.
    assert_eq!(active_ids(&n), [Some(2), Some(3), Some(4)]);
    let _ = std::fs::remove_dir_all(&dir);
}
