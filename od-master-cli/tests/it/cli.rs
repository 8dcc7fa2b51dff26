//! The `od-master` program end to end: its commands against simulated drives on a socketcand
//! hub over TCP (the hub and device loop `drive-sim hub` and `drive-sim run` run, in this
//! process), their text and `--json` output, and the exit codes 0, 1 and 2.

use std::net::SocketAddr;
use std::process::{Command, Output, Stdio};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use drive::node::{DeviceKind, MonotonicClock, run};
use od_bus::{Hub, HubConfig};
use serde_json::Value;

const DRVI_EDS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../devices/camozzi-drvi.eds");

fn node(kind: DeviceKind, id: u8) -> Box<dyn drive::node::AnyNode> {
    kind.build(&drive::node::NodeConfig { node_id: Some(id), ..Default::default() }, &drive::drives::DeviceApps::new())
        .expect("a simulated node")
}

/// A hub on a port the OS picks, with drives running on it in real time.
pub(crate) struct Rig {
    hub: Hub,
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<()>>,
}

impl Rig {
    pub(crate) fn start(nodes: &[(DeviceKind, u8)]) -> Self {
        let hub = Hub::bind("127.0.0.1:0", HubConfig::default().quiet()).expect("bind the hub");
        let stop = Arc::new(AtomicBool::new(false));
        let threads = nodes
            .iter()
            .map(|&(kind, id)| {
                let mut ep = hub.attach("can0").unwrap();
                let stop = Arc::clone(&stop);
                let mut n = node(kind, id);
                std::thread::spawn(move || {
                    let _ = run(&mut *n, &mut ep, &MonotonicClock::new(), &stop);
                })
            })
            .collect();
        Self { hub, stop, threads }
    }

    fn bus(&self) -> String {
        let addr: SocketAddr = self.hub.local_addr();
        format!("socketcand://{addr}/can0")
    }

    /// Runs `od-master --bus <this hub> args...`.
    pub(crate) fn cli(&self, args: &[&str]) -> Out {
        let mut all = vec!["--bus".to_owned(), self.bus()];
        all.extend(args.iter().map(|a| (*a).to_owned()));
        cli(&all)
    }
}

impl Drop for Rig {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        self.hub.stop();
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

pub(crate) struct Out {
    pub(crate) code: i32,
    pub(crate) stdout: String,
    pub(crate) stderr: String,
}

impl Out {
    pub(crate) fn json_lines(&self) -> Vec<Value> {
        self.stdout
            .lines()
            .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("not a JSON line: {l}: {e}")))
            .collect()
    }
}

pub(crate) fn cli<S: AsRef<std::ffi::OsStr>>(args: &[S]) -> Out {
    let o: Output = Command::new(env!("CARGO_BIN_EXE_od-master")).args(args).stdin(Stdio::null()).output().unwrap();
    Out {
        code: o.status.code().unwrap_or(-1),
        stdout: String::from_utf8_lossy(&o.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&o.stderr).into_owned(),
    }
}

#[test]
fn cli_reads_as_the_type_says_in_text_and_json() {
    let rig = Rig::start(&[(DeviceKind::Drvi, 5)]);
    // A string as text, without an EDS (1008h is a VISIBLE_STRING in every device).
    let out = rig.cli(&["read", "5", "1008h"]);
    assert_eq!((out.code, out.stdout.as_str()), (0, "DRVI\n"), "{}", out.stderr);
    // JSON, the option after the subcommand: node, index, subindex, value.
    let out = rig.cli(&["read", "5", "0x1018:1", "--json"]);
    assert_eq!(out.code, 0, "{}", out.stderr);
    let [v] = &out.json_lines()[..] else { panic!("{}", out.stdout) };
    assert_eq!((&v["node"], &v["index"], &v["subindex"]), (&5.into(), &0x1018.into(), &1.into()));
    assert_eq!(v["value"], 0x97);
    // Named as the generated code names it, with the EDS; the same entry by index.
    let by_name = rig.cli(&["--json", "--eds", DRVI_EDS, "read", "5", "identity_object.vendor_id"]);
    assert_eq!(
        by_name.json_lines(),
        out.json_lines()
            .into_iter()
            .map(|mut v| {
                v["name"] = "identity_object.vendor_id".into();
                v
            })
            .collect::<Vec<_>>()
    );
    // COB-IDs in hex.
    let out = rig.cli(&["--eds", DRVI_EDS, "read", "5", "1800h:1"]);
    assert!(out.stdout.trim().starts_with("0x"), "{}", out.stdout);
}

#[test]
fn cli_writes_by_the_eds_type_or_a_typed_value_and_checks_the_range() {
    let rig = Rig::start(&[(DeviceKind::Drvi, 5)]);
    let out = rig.cli(&["--eds", DRVI_EDS, "write", "5", "6083h", "1234"]);
    assert_eq!(out.code, 0, "{}", out.stderr);
    assert_eq!(rig.cli(&["--eds", DRVI_EDS, "read", "5", "6083h"]).stdout, "1234\n");
    let out = rig.cli(&["write", "5", "0x6083", "u32:999"]);
    assert_eq!(out.code, 0, "{}", out.stderr);
    assert_eq!(rig.cli(&["read", "5", "6083h"]).stdout, "999\n");
    // Out of the type's range, untyped without an EDS, unknown name: bad usage, nothing sent.
    let out = rig.cli(&["--eds", DRVI_EDS, "write", "5", "6083h", "-1"]);
    assert_eq!(out.code, 2);
    assert!(out.stderr.contains("outside the range of UNSIGNED32"), "{}", out.stderr);
    assert_eq!(rig.cli(&["write", "5", "6083h", "7"]).code, 2);
    let out = rig.cli(&["--eds", DRVI_EDS, "read", "5", "statusward"]);
    assert_eq!(out.code, 2);
    assert!(out.stderr.contains("closest: statusword"), "{}", out.stderr);
    assert_eq!(rig.cli(&["read", "5", "6083h"]).stdout, "999\n");
    // Each SDO mode, both ways, against the od-runtime server.
    for (mode, value) in [("normal", 11u32), ("segmented", 22), ("block", 33)] {
        let out = rig.cli(&["--sdo-mode", mode, "write", "5", "6083h", &format!("u32:{value}")]);
        assert_eq!(out.code, 0, "{mode}: {}", out.stderr);
        let out = rig.cli(&["--sdo-mode", mode, "read", "5", "6083h"]);
        assert_eq!(out.stdout, format!("{value}\n"), "{mode}: {}", out.stderr);
        assert_eq!(rig.cli(&["--sdo-mode", mode, "read", "5", "1008h"]).stdout, "DRVI\n", "{mode}");
    }
}

#[test]
fn cli_exit_codes_say_abort_or_timeout_and_bad_usage() {
    let rig = Rig::start(&[(DeviceKind::Drvi, 5)]);
    // The server's abort: one line naming the node, the object and the abort.
    let out = rig.cli(&["read", "5", "2fffh"]);
    assert_eq!(out.code, 1);
    assert_eq!(out.stderr.lines().count(), 1, "{}", out.stderr);
    assert!(out.stderr.contains("node 5") && out.stderr.contains("2FFFh"), "{}", out.stderr);
    assert!(out.stderr.contains("object does not exist"), "{}", out.stderr);
    // No node 9: a timeout.
    let out = rig.cli(&["--timeout", "100", "read", "9", "1000h"]);
    assert_eq!(out.code, 1);
    assert!(out.stderr.contains("node 9") && out.stderr.contains("1000h"), "{}", out.stderr);
    // Bad usage.
    for args in [&["read", "5"][..], &["read", "0", "1000h"], &["read", "5", "nonsense"], &["nmt", "jump", "5"]] {
        let out = rig.cli(args);
        assert_eq!(out.code, 2, "{args:?}: {}", out.stderr);
    }
    // No bus given; a bus that cannot be opened (a port nobody listens on).
    assert_eq!(cli(&["read", "5", "1000h"]).code, 2);
    let dead = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap();
    let out = cli(&["--bus", &format!("socketcand://{dead}/can0"), "read", "5", "1000h"]);
    assert_eq!(out.code, 2, "{}", out.stderr);
}

#[test]
fn cli_scan_lists_the_nodes_that_answer_with_identity_and_name() {
    let rig = Rig::start(&[(DeviceKind::Drvi, 5), (DeviceKind::Akd, 7)]);
    let out = rig.cli(&["--json", "scan", "--last", "10"]);
    assert_eq!(out.code, 0, "{}", out.stderr);
    let lines = out.json_lines();
    let nodes: Vec<_> = lines.iter().map(|v| v["node"].as_u64().unwrap()).collect();
    assert_eq!(nodes, [5, 7]);
    assert_eq!(lines[0]["name"], "DRVI");
    assert_eq!(lines[0]["vendor_id"], 0x97);
    let text = rig.cli(&["scan", "--last", "10"]);
    assert_eq!(text.stdout.lines().count(), 2, "{}", text.stdout);
    assert!(text.stdout.contains("DRVI"), "{}", text.stdout);
}

#[test]
fn cli_nmt_commands_show_in_the_monitor_decoded() {
    let rig = Rig::start(&[(DeviceKind::Drvi, 5)]);
    let bus = rig.bus();
    let drvi = format!("5={DRVI_EDS}");
    let monitor = Command::new(env!("CARGO_BIN_EXE_od-master"))
        .args(["--bus", &bus, "--eds", &drvi, "monitor", "--json", "--count", "6"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // The monitor connects at its own pace: repeat the commands until it has seen enough.
    let deadline = Instant::now() + Duration::from_secs(20);
    let pid = monitor.id();
    let alive = || std::path::Path::new(&format!("/proc/{pid}/stat")).exists() && !zombie(pid);
    while alive() {
        assert!(Instant::now() < deadline, "the monitor did not see 6 frames");
        assert_eq!(rig.cli(&["nmt", "start", "5"]).code, 0);
        assert_eq!(rig.cli(&["nmt", "preop", "all"]).code, 0);
    }
    let out = monitor.wait_with_output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let lines: Vec<Value> =
        String::from_utf8_lossy(&out.stdout).lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(lines.len(), 6);
    let kinds: Vec<&str> = lines.iter().map(|v| v["kind"].as_str().unwrap()).collect();
    assert!(lines.iter().any(|v| v["kind"] == "nmt" && v["command"] == "start" && v["node"] == 5), "{lines:?}");
    assert!(lines.iter().any(|v| v["kind"] == "nmt" && v["command"] == "enter pre-operational"), "{lines:?}");
    // In Operational the DRVI sends its TPDO1 (the statusword), decoded by the EDS mapping.
    if kinds.contains(&"pdo") {
        let pdo = lines.iter().find(|v| v["kind"] == "pdo").unwrap();
        assert!(pdo["fields"]["statusword"].is_u64(), "{pdo}");
    }
    // The other commands, to a node and to all.
    for args in [["nmt", "stop", "5"], ["nmt", "reset-comm", "all"], ["nmt", "reset", "5"]] {
        assert_eq!(rig.cli(&args).code, 0, "{args:?}");
    }
    // A duration ends it too, with nothing seen on a quiet bus.
    let out = rig.cli(&["monitor", "--duration", "0.2"]);
    assert_eq!(out.code, 0, "{}", out.stderr);
}

fn zombie(pid: u32) -> bool {
    std::fs::read_to_string(format!("/proc/{pid}/stat")).map_or(true, |s| s.contains(") Z "))
}

#[test]
fn cli_axis_homes_moves_and_runs_at_a_velocity() {
    let rig = Rig::start(&[(DeviceKind::Drvi, 5)]);
    let out = rig.cli(&["axis", "5", "home", "--method", "37"]);
    assert_eq!(out.code, 0, "{}", out.stderr);
    assert!(out.stdout.contains("position 0"), "{}", out.stdout);
    let out = rig.cli(&["axis", "5", "move", "--to", "3600", "--velocity", "36000", "--acceleration", "36000"]);
    assert_eq!((out.code, out.stdout.as_str()), (0, "position 3600\n"), "{}", out.stderr);
    assert_eq!(rig.cli(&["read", "5", "6064h"]).stdout, "3600\n");
    assert_eq!(rig.cli(&["axis", "5", "velocity", "-100"]).code, 0);
    assert_eq!(rig.cli(&["read", "5", "60FFh"]).stdout, (-100i32 as u32).to_string() + "\n");
    assert_eq!(rig.cli(&["axis", "5", "enable"]).code, 0);
    // In the unit of the DRVI's sidecar (only motor: hundredths of a degree, of an rpm).
    let out = rig.cli(&["--eds", DRVI_EDS, "axis", "5", "move", "--to", "72deg", "--velocity", "36000"]);
    assert_eq!((out.code, out.stdout.as_str()), (0, "position 7200\n"), "{}", out.stderr);
    assert_eq!(rig.cli(&["--eds", DRVI_EDS, "axis", "5", "velocity", "-1.5rpm"]).code, 0);
    assert_eq!(rig.cli(&["read", "5", "60FFh"]).stdout, (-150i32 as u32).to_string() + "\n");
    let out = rig.cli(&["--eds", DRVI_EDS, "axis", "5", "move", "--to", "3mm"]);
    assert_eq!(out.code, 2);
    assert!(out.stderr.contains("in deg"), "{}", out.stderr);
    assert_eq!(rig.cli(&["axis", "5", "move", "--to", "3deg"]).code, 2);
    // A homing method the DRVI does not have: the drive's abort, exit code 1.
    let out = rig.cli(&["axis", "5", "home", "--method", "35"]);
    assert_eq!(out.code, 1, "{}", out.stderr);
    assert!(out.stderr.contains("drive 5") && out.stderr.contains("6098h"), "{}", out.stderr);
}
