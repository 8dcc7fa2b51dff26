//! `od-master run` end to end: networks/example.toml supervised on simulated drives behind a
//! TCP hub, in real time; a drive power-cycled in place and a drive process "killed" and
//! started again, both configured again; Ctrl-C (SIGINT) ends it with 0; a mandatory wrong
//! device ends it with 1.

use std::io::{BufRead, BufReader};
use std::net::SocketAddr;
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use drive::node::{DeviceKind, Fault, FaultHandle, Faulty, MonotonicClock, run};
use od_bus::{Hub, HubConfig};
use serde_json::Value;

const EXAMPLE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../networks/example.toml");

/// One drive on the hub, in a thread of its own (as a process of its own would be).
struct Drive {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
    faults: FaultHandle,
}

impl Drive {
    fn start(hub: &Hub, kind: DeviceKind, id: u8) -> Self {
        let node = kind
            .build(
                &drive::node::NodeConfig { node_id: Some(id), ..Default::default() },
                &drive::drives::DeviceApps::new(),
            )
            .expect("a simulated node");
        let (mut node, faults) = Faulty::new(node);
        let mut ep = hub.attach("can0").unwrap();
        let stop = Arc::new(AtomicBool::new(false));
        let s = Arc::clone(&stop);
        let thread = std::thread::spawn(move || {
            let _ = run(&mut node, &mut ep, &MonotonicClock::new(), &s);
        });
        Self { stop, thread: Some(thread), faults }
    }

    /// Gone at once, as a process killed with SIGKILL: no frame more.
    fn kill(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for Drive {
    fn drop(&mut self) {
        self.kill();
    }
}

/// `od-master --bus HUB run FILE --json` with its lines read as they come.
struct Supervising {
    child: Child,
    lines: mpsc::Receiver<Value>,
}

impl Supervising {
    fn start(hub: &Hub, file: &str) -> Self {
        let addr: SocketAddr = hub.local_addr();
        let mut child = Command::new(env!("CARGO_BIN_EXE_od-master"))
            .args(["--bus", &format!("socketcand://{addr}/can0"), "run", file, "--json"])
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let stdout = child.stdout.take().unwrap();
        let (tx, lines) = mpsc::channel();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                let v: Value = serde_json::from_str(&line).unwrap_or_else(|e| panic!("not a JSON line: {line}: {e}"));
                if tx.send(v).is_err() {
                    return;
                }
            }
        });
        Self { child, lines }
    }

    /// The next line with `event` (and `node`, if given), within `within`; the lines before.
    fn expect(&self, event: &str, node: Option<u64>, within: Duration) -> (Value, Vec<Value>) {
        let end = Instant::now() + within;
        let mut before = Vec::new();
        loop {
            let left = end.saturating_duration_since(Instant::now());
            match self.lines.recv_timeout(left) {
                Ok(v) if v["event"] == event && node.is_none_or(|n| v["node"] == n) => return (v, before),
                Ok(v) => before.push(v),
                Err(_) => panic!("no `{event}` line for node {node:?} within {within:?}; before: {before:#?}"),
            }
        }
    }

    /// SIGINT (Ctrl-C), then its exit code and standard error.
    fn interrupt(self) -> (i32, String) {
        let _ = Command::new("kill").args(["-INT", &self.child.id().to_string()]).status();
        self.finish()
    }

    fn finish(mut self) -> (i32, String) {
        let status = self.child.wait().unwrap();
        let mut err = String::new();
        if let Some(mut e) = self.child.stderr.take() {
            let _ = std::io::Read::read_to_string(&mut e, &mut err);
        }
        (status.code().unwrap_or(-1), err)
    }
}

#[test]
fn run_configures_a_power_cycled_drive_and_a_restarted_one_again_and_ends_on_ctrl_c() {
    let hub = Hub::bind("127.0.0.1:0", HubConfig::default().quiet()).expect("bind the hub");
    let mut drives: Vec<Drive> = [(DeviceKind::Drvi, 2), (DeviceKind::Drcs, 3), (DeviceKind::Akd, 4)]
        .iter()
        .map(|&(kind, id)| Drive::start(&hub, kind, id))
        .collect();
    let sup = Supervising::start(&hub, EXAMPLE);
    for n in [2, 3, 4] {
        let (line, _) = sup.expect("booted", Some(n), Duration::from_secs(10));
        assert!(line["writes"].as_u64().unwrap() >= 28, "{line}");
    }
    // In place: the DRCS's power cycled.
    drives[1].faults.inject(Fault::PowerCycle { off: 5_000 });
    sup.expect("rebooted", Some(3), Duration::from_secs(5));
    let (done, between) = sup.expect("reconfigured", Some(3), Duration::from_secs(5));
    assert_eq!(done["writes"], 28, "{done}");
    assert!(done["elapsed_ms"].as_f64().unwrap() > 0.0, "{done}");
    assert!(between.is_empty(), "{between:#?}");
    // The AKD's "process" killed and started again: a fresh device with its defaults.
    drives[2].kill();
    drives[2] = Drive::start(&hub, DeviceKind::Akd, 4);
    sup.expect("rebooted", Some(4), Duration::from_secs(5));
    let (done, _) = sup.expect("reconfigured", Some(4), Duration::from_secs(5));
    assert_eq!(done["writes"], 28, "{done}");
    let (code, err) = sup.interrupt();
    assert_eq!(code, 0, "{err}");
    hub.stop();
}

#[test]
fn run_ends_with_1_when_a_mandatory_node_cannot_boot() {
    let hub = Hub::bind("127.0.0.1:0", HubConfig::default().quiet()).expect("bind the hub");
    // A DRCS where the DRVI (x_axis, mandatory) should be.
    let _drives: Vec<Drive> = [(DeviceKind::Drcs, 2), (DeviceKind::Drcs, 3), (DeviceKind::Akd, 4)]
        .iter()
        .map(|&(kind, id)| Drive::start(&hub, kind, id))
        .collect();
    let devices = concat!(env!("CARGO_MANIFEST_DIR"), "/../devices/");
    let text = std::fs::read_to_string(EXAMPLE).unwrap().replace("../devices/", devices)
        + "\n[network.supervision]\non_mandatory_failure = \"stop_all\"\n[nodes.x_axis.supervision]\nmandatory = true\n";
    let dir = std::env::temp_dir().join(format!("od-master-run-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("network.toml");
    std::fs::write(&file, text).unwrap();
    let sup = Supervising::start(&hub, file.to_str().unwrap());
    let (failed, _) = sup.expect("boot_failed", Some(2), Duration::from_secs(10));
    assert_eq!((&failed["index"], &failed["subindex"], &failed["reason"]), (&4096.into(), &0.into(), &"C".into()));
    assert!(failed["message"].as_str().unwrap().contains("is 0xFF7C0192"), "{failed}");
    sup.expect("acted", Some(2), Duration::from_secs(5));
    sup.expect("mandatory_failed", Some(2), Duration::from_secs(5));
    let (code, err) = sup.finish();
    assert_eq!(code, 1, "{err}");
    assert!(err.contains("x_axis"), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
    hub.stop();
}
