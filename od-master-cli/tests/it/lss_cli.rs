//! `od-master lss` end to end: three simulated drives that all start as node 1 on a hub over
//! TCP (each with its own serial number), given nodes 2, 3 and 4 by `lss assign` from
//! networks/example.toml with serials (by switch state selective: fastscan sees no device
//! with a node-ID), reset, then booted; inquire, errors. Fastscan itself is tested in virtual
//! time (od-master's tests/it/lss.rs) and against python-canopen (tests/python/test_lss.py).

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;

use drive::node::{DeviceKind, MonotonicClock, NodeConfig, run};
use od_bus::{Hub, HubConfig};

use crate::cli::{Out, cli};

const DRIVES: [(DeviceKind, u32); 3] = [(DeviceKind::Drvi, 1001), (DeviceKind::Drcs, 1002), (DeviceKind::Akd, 1003)];
const DRVI_EDS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../devices/camozzi-drvi.eds");

struct Rig {
    hub: Hub,
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<()>>,
    dir: PathBuf,
}

impl Rig {
    fn start(test: &str) -> Self {
        Self::start_at(test, Some(1))
    }

    /// The three drives at `node_id` (255: without one, as `drive-sim --node-id none`).
    fn start_at(test: &str, node_id: Option<u8>) -> Self {
        let dir = std::env::temp_dir().join(format!("od-master-cli-lss-{test}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let hub = Hub::bind("127.0.0.1:0", HubConfig::default().quiet()).expect("bind the hub");
        let stop = Arc::new(AtomicBool::new(false));
        let threads = DRIVES
            .iter()
            .map(|&(kind, serial)| {
                let config =
                    NodeConfig { node_id, serial: Some(serial), state_dir: Some(dir.clone()), ..Default::default() };
                let mut n = kind.build(&config, &drive::drives::DeviceApps::new()).expect("a simulated drive");
                let mut ep = hub.attach("can0").unwrap();
                let stop = Arc::clone(&stop);
                std::thread::spawn(move || {
                    let _ = run(&mut *n, &mut ep, &MonotonicClock::new(), &stop);
                })
            })
            .collect();
        Self { hub, stop, threads, dir }
    }

    fn cli(&self, args: &[&str]) -> Out {
        let mut all = vec!["--bus".to_owned(), format!("socketcand://{}/can0", self.hub.local_addr())];
        all.extend(args.iter().map(|a| (*a).to_owned()));
        cli(&all)
    }

    /// networks/example.toml with `serial = N` in each node, device paths made absolute.
    fn network(&self) -> PathBuf {
        self.network_with(&[], "example-lss.toml")
    }

    /// [`Rig::network`] with `lss = true` added to each node and the serial numbers of
    /// `serials` (the rig's by default).
    fn network_with(&self, serials: &[u32], file: &str) -> PathBuf {
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let text = std::fs::read_to_string(root.join("networks/example.toml")).unwrap();
        let devices = root.join("devices").canonicalize().unwrap();
        let mut out = String::new();
        let marked = !serials.is_empty();
        let mut serials = serials.iter().copied().chain(DRIVES.iter().map(|d| d.1).skip(serials.len()));
        for line in text.lines() {
            out.push_str(&line.replace("\"../devices", &format!("\"{}", devices.display())));
            out.push('\n');
            if line.starts_with("node_id = ") {
                out.push_str(&format!("serial = {}\n", serials.next().unwrap()));
                if marked {
                    out.push_str("lss = true\n");
                }
            }
        }
        std::fs::create_dir_all(&self.dir).unwrap();
        let path = self.dir.join(file);
        std::fs::write(&path, out).unwrap();
        path
    }
}

impl Drop for Rig {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        self.hub.stop();
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

#[test]
fn lss_assign_inquire_then_boot() {
    let rig = Rig::start("assign");
    let network = rig.network();
    // A long step timeout: the test host may be loaded (answers over the hub took up to 160 ms
    // at a load average of 19 on 2 cores).
    let out = rig.cli(&["lss", "--step-timeout", "300", "assign", network.to_str().unwrap()]);
    assert_eq!(out.code, 0, "{}", out.stderr);
    let lines: Vec<&str> = out.stdout.lines().collect();
    assert_eq!(lines.len(), 3, "{}", out.stdout);
    for (line, node) in lines.iter().zip(["node 2: ", "node 3: ", "node 4: "]) {
        assert!(line.starts_with(node), "{}", out.stdout);
    }

    // The new node-IDs take effect at the next reset.
    assert_eq!(rig.cli(&["nmt", "reset", "all"]).code, 0);
    std::thread::sleep(std::time::Duration::from_millis(300));
    let out = rig.cli(&["--eds", DRVI_EDS, "--json", "lss", "--step-timeout", "300", "inquire", "--serial", "1001"]);
    assert_eq!(out.code, 0, "{}", out.stderr);
    let [v] = &out.json_lines()[..] else { panic!("{}", out.stdout) };
    assert_eq!((v["node"].as_u64(), v["identity"]["vendor"].as_u64()), (Some(2), Some(0x97)));

    let out = rig.cli(&["boot", network.to_str().unwrap()]);
    assert_eq!(out.code, 0, "{}\n{}", out.stdout, out.stderr);

    // Errors: a bit rate outside the table, a device that is not there, an identity not
    // known; each one line and its exit code.
    let out = rig.cli(&["lss", "set-bitrate", "100"]);
    assert_eq!(out.code, 1);
    assert!(
        out.stderr.contains("LSS configure bit timing 100 kbit/s: not a bit rate of the CiA 305 table"),
        "{}",
        out.stderr
    );
    let out = rig.cli(&["--eds", DRVI_EDS, "lss", "set-id", "--serial", "5", "9"]);
    assert_eq!(out.code, 1);
    assert!(out.stderr.contains("serial 00000005h): no answer within "), "{}", out.stderr);
    let out = rig.cli(&["lss", "set-id", "--serial", "5", "9"]);
    assert_eq!(out.code, 2);
    assert!(out.stderr.contains("give --eds FILE or --vendor"), "{}", out.stderr);
}

#[test]
fn boot_gives_three_unconfigured_drives_their_node_ids_then_boots_them() {
    let rig = Rig::start_at("boot", Some(255));
    let network = rig.network_with(&[1001, 1002, 1003], "marked.toml");
    // Loaded test hosts answer late (see above): a step timeout that covers them.
    let started = std::time::Instant::now();
    let out = rig.cli(&["boot", "--lss-step-timeout", "300", network.to_str().unwrap()]);
    let took = started.elapsed();
    assert_eq!(out.code, 0, "{}\n{}", out.stdout, out.stderr);
    let lines: Vec<&str> = out.stdout.lines().collect();
    assert_eq!(
        lines[..3],
        [
            "x_axis (node 2): node-ID given over LSS (serial 1001, had none)",
            "y_axis (node 3): node-ID given over LSS (serial 1002, had none)",
            "z_axis (node 4): node-ID given over LSS (serial 1003, had none)",
        ],
        "{}",
        out.stdout
    );
    for (line, node) in lines[3..].iter().zip(["x_axis (node 2): ", "y_axis (node 3): ", "z_axis (node 4): "]) {
        assert!(line.starts_with(node) && line.ends_with("writes, started"), "{}", out.stdout);
    }
    assert_eq!(lines.len(), 6, "{}", out.stdout);
    eprintln!("boot with LSS over the hub: {took:?}");

    // A marked node whose device is not there (serial 9999): the other two boot, it fails
    // naming the serial and the step, after one step timeout, no hang.
    let missing = rig.network_with(&[1001, 1002, 9999], "missing.toml");
    let started = std::time::Instant::now();
    let out = rig.cli(&["--json", "boot", "--lss-step-timeout", "300", missing.to_str().unwrap()]);
    let took = started.elapsed();
    assert_eq!(out.code, 1, "{}\n{}", out.stdout, out.stderr);
    let v = out.json_lines();
    let z = v.iter().find(|v| v["name"] == "z_axis").unwrap_or_else(|| panic!("{}", out.stdout));
    assert_eq!((z["ok"].as_bool(), z["stage"].as_str()), (Some(false), Some("LSS")), "{}", out.stdout);
    let error = z["error"].as_str().unwrap();
    assert!(error.contains("serial number 9999") && error.contains("LSS switch state selective ("), "{error}");
    assert!(error.contains("serial 0000270Fh): no answer within 300 ms"), "{error}");
    for name in ["x_axis", "y_axis"] {
        let n = v.iter().find(|v| v["name"] == name).unwrap();
        assert_eq!(n["ok"].as_bool(), Some(true), "{}", out.stdout);
    }
    // Process start, connection, one 300 ms step timeout, the boot: no wait ran long.
    assert!(took < std::time::Duration::from_secs(10), "took {took:?}");
}
