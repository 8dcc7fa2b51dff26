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
        let dir = std::env::temp_dir().join(format!("od-master-cli-lss-{test}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let hub = Hub::bind("127.0.0.1:0", HubConfig::default().quiet()).expect("bind the hub");
        let stop = Arc::new(AtomicBool::new(false));
        let threads = DRIVES
            .iter()
            .map(|&(kind, serial)| {
                let config = NodeConfig {
                    node_id: Some(1),
                    serial: Some(serial),
                    state_dir: Some(dir.clone()),
                    ..Default::default()
                };
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
        let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let text = std::fs::read_to_string(root.join("networks/example.toml")).unwrap();
        let devices = root.join("devices").canonicalize().unwrap();
        let mut out = String::new();
        let mut serials = DRIVES.iter().map(|d| d.1);
        for line in text.lines() {
            out.push_str(&line.replace("\"../devices", &format!("\"{}", devices.display())));
            out.push('\n');
            if line.starts_with("node_id = ") {
                out.push_str(&format!("serial = {}\n", serials.next().unwrap()));
            }
        }
        std::fs::create_dir_all(&self.dir).unwrap();
        let path = self.dir.join("example-lss.toml");
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
