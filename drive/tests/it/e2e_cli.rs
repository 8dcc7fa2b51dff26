//! `drive-sim run` as a process: devices on their own hub or joining one, several devices per
//! process, clean stops on signals, a failure when the bus goes away, and the errors a user
//! can make on the command line.

use std::io::{BufRead, BufReader, Read};
use std::process::{Child, ChildStderr, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use od_bus::{CanFrame, Endpoint, SocketcandClient};

const WAIT: Duration = Duration::from_secs(10);

struct Process {
    child: Child,
    /// The rest of the first stdout line after the expected prefix.
    ready: String,
    stderr: Option<ChildStderr>,
}

impl Process {
    fn start(args: &[&str], prefix: &str) -> Self {
        let mut child = Command::new(env!("CARGO_BIN_EXE_drive-sim"))
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("start drive-sim");
        let mut line = String::new();
        BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).expect("read the first line");
        let stderr = child.stderr.take();
        let ready = line.trim().strip_prefix(prefix).unwrap_or_else(|| panic!("first line {line:?}")).to_owned();
        Self { child, ready, stderr }
    }

    fn signal(&mut self, signal: libc::c_int) {
        let pid = libc::pid_t::try_from(self.child.id()).unwrap();
        // SAFETY: sending a signal to our own child process.
        assert_eq!(unsafe { libc::kill(pid, signal) }, 0);
    }

    /// Waits (bounded) for the process to end; returns its status and standard error.
    fn wait(&mut self) -> (ExitStatus, String) {
        let deadline = Instant::now() + WAIT;
        let status = loop {
            if let Some(status) = self.child.try_wait().unwrap() {
                break status;
            }
            assert!(Instant::now() < deadline, "drive-sim did not stop");
            std::thread::sleep(Duration::from_millis(10));
        };
        let mut text = String::new();
        if let Some(mut e) = self.stderr.take() {
            e.read_to_string(&mut text).unwrap();
        }
        (status, text)
    }
}

impl Drop for Process {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// od-master on the hub at `addr`, channel `channel`.
fn master(addr: &str, channel: &str) -> od_master::blocking::Bus {
    crate::support::hub_master(addr, channel, WAIT)
}

/// Sub-index 0 of `index` on `node`, read by od-master.
fn upload(bus: &od_master::blocking::Bus, node: u8, index: u16) -> Vec<u8> {
    bus.node(node).unwrap().read_bytes(index, 0).unwrap_or_else(|e| panic!("upload {index:04X}h: {e}"))
}

#[test]
fn a_device_joins_a_hub_with_bus_and_stops_on_sigint() {
    let hub = Process::start(&["hub", "--listen", "127.0.0.1:0", "--quiet"], "listening on ");
    let mut master = SocketcandClient::connect(hub.ready.as_str(), "line1").unwrap();
    let spec = format!("socketcand://{}/line1", hub.ready);
    let mut run = Process::start(&["run", "--device", "akd", "--node-id", "5", "--bus", &spec], "running on ");
    assert_eq!(run.ready, spec);
    // The first thing on the bus is its boot-up.
    let first = master.recv_timeout(WAIT).unwrap().unwrap();
    assert_eq!(first.to_string(), "705#00");
    assert_eq!(upload(&self::master(&hub.ready, "line1"), 5, 0x1008), b"M006");
    run.signal(libc::SIGINT);
    let (status, log) = run.wait();
    assert!(status.success(), "{status}: {log}");
    assert!(log.contains("SIGINT, stopping"), "{log}");
}

/// `value` written to `index`/`sub` of `node` by od-master.
fn download_u32(bus: &od_master::blocking::Bus, node: u8, index: u16, sub: u8, value: u32) {
    bus.node(node).unwrap().write(index, sub, value).unwrap_or_else(|e| panic!("download {index:04X}h: {e}"));
}

#[test]
fn a_device_whose_hub_goes_away_keeps_its_state_and_reconnects() {
    let mut hub = Process::start(&["hub", "--listen", "127.0.0.1:0", "--quiet"], "listening on ");
    let address = hub.ready.clone();
    let spec = format!("tcp://{address}");
    let mut run = Process::start(&["run", "--device", "drcs", "--node-id", "3", "--bus", &spec], "running on ");
    let od = master(&address, "can0");
    download_u32(&od, 3, 0x6083, 0, 4321); // not saved: only the running device has it
    drop(od);
    hub.signal(libc::SIGTERM);
    assert!(hub.wait().0.success());
    std::thread::sleep(Duration::from_millis(300));
    assert!(run.child.try_wait().unwrap().is_none(), "the device runs on without its bus");

    // A hub on the same address: the device comes back by itself, with its state.
    let _hub = Process::start(&["hub", "--listen", &address, "--quiet"], "listening on ");
    let od = master(&address, "can0");
    let short = od_master::SdoOptions { timeout: Duration::from_millis(200), retries: 0, ..Default::default() };
    let drcs = od.node(3).unwrap().with_options(short);
    let deadline = Instant::now() + Duration::from_secs(30);
    let value = loop {
        assert!(Instant::now() < deadline, "the device did not come back");
        if let Ok(v) = drcs.read::<u32>(0x6083, 0) {
            break v;
        }
    };
    assert_eq!(value, 4321);
    run.signal(libc::SIGTERM);
    let (status, log) = run.wait();
    assert!(status.success(), "{status}: {log}");
    assert!(log.contains("drcs node 3") && log.contains("reconnecting"), "{log}");
    assert!(log.contains("reconnected after"), "{log}");
}

#[test]
fn saves_killed_at_random_moments_never_mix_two_saves_nor_lose_a_confirmed_one() {
    let dir = std::env::temp_dir().join(format!("drive-e2e-cli-kill-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let state = dir.to_str().unwrap();
    let args =
        ["run", "--device", "drvi", "--node-id", "2", "--state-dir", state, "--listen", "127.0.0.1:0", "--quiet"];
    let mut confirmed = 0u32; // last save whose response the master got
    let mut written = 0u32; // last generation written and asked to be saved
    let mut seed = 0x2545_F491u32;
    let rounds = 25;
    let mut torn_rounds = 0;
    // The last round only checks what the kill of the one before left.
    for round in 1..=rounds + 1 {
        let mut run = Process::start(&args, "listening on ");
        // od-master for the reads and writes; the save goes on a raw client, whose stream
        // shows whether its answer came before the kill.
        let od = master(&run.ready, "can0");
        let mut bus = SocketcandClient::connect(run.ready.as_str(), "can0").unwrap();
        let acc = u32::from_le_bytes(upload(&od, 2, 0x6083).try_into().unwrap());
        let hb = upload(&od, 2, 0x1017);
        let hb = u32::from(u16::from_le_bytes(hb.try_into().unwrap()));
        // 6083h (application area) = 1000 + g and 1017h (communication area) = 100 + g were
        // saved together: both from one generation g, or nothing saved yet.
        let g = match (acc.checked_sub(1000), hb.checked_sub(100)) {
            (Some(a), Some(h)) if a == h => a,
            _ if acc == 0 && hb == 0 => 0,
            _ => panic!("round {round}: areas from different saves: 6083h={acc} 1017h={hb}"),
        };
        assert!(
            g >= confirmed && g <= written,
            "round {round}: generation {g}, confirmed {confirmed}, written {written}"
        );
        if g < written {
            torn_rounds += 1; // the kill came before the save's rename: the previous save stands
        }
        if round > rounds {
            break;
        }
        written = round;
        download_u32(&od, 2, 0x6083, 0, 1000 + round);
        od.node(2).unwrap().write(0x1017, 0, (100 + round) as u16).expect("1017h");
        bus.send(CanFrame::standard(0x602, &[0x23, 0x10, 0x10, 0x01, b's', b'a', b'v', b'e']).unwrap()).unwrap();
        seed ^= seed << 13;
        seed ^= seed >> 17;
        seed ^= seed << 5;
        std::thread::sleep(Duration::from_micros(u64::from(seed % 4000)));
        run.signal(libc::SIGKILL);
        let _ = run.wait();
        while let Ok(Some(frame)) = bus.recv_timeout(Duration::from_millis(50)) {
            if frame.id() == 0x582 && frame.data()[..4] == [0x60, 0x10, 0x10, 0x01] {
                confirmed = round;
            }
        }
    }
    eprintln!("{rounds} kill rounds: {torn_rounds} killed before the save took effect, none mixed");
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn several_devices_in_one_process_share_its_hub() {
    let mut run = Process::start(
        &[
            "run",
            "--device",
            "drvi",
            "--node-id",
            "2",
            "--device",
            "drcs",
            "--node-id",
            "3",
            "--device",
            "akd",
            "--node-id",
            "4",
            "--listen",
            "127.0.0.1:0",
            "--channel",
            "axes",
        ],
        "listening on ",
    );
    let od = self::master(&run.ready, "axes");
    assert_eq!(upload(&od, 2, 0x1008), b"DRVI");
    assert_eq!(upload(&od, 3, 0x1008), b"DRCS");
    assert_eq!(upload(&od, 4, 0x1008), b"M006");
    // The boot-ups on a raw client that joins now (the transfers above are not in its way).
    let mut master = SocketcandClient::connect(run.ready.as_str(), "axes").unwrap();
    // Reset communication, all nodes: three boot-ups.
    master.send(CanFrame::standard(0, &[0x82, 0]).unwrap()).unwrap();
    let mut ids: Vec<u32> = (0..3).map(|_| master.recv_timeout(WAIT).unwrap().unwrap().id()).collect();
    ids.sort();
    assert_eq!(ids, [0x702, 0x703, 0x704]);
    run.signal(libc::SIGTERM);
    let (status, log) = run.wait();
    assert!(status.success(), "{log}");
    for name in ["drvi node 2 started", "drcs node 3 started", "akd node 4 started", "SIGTERM, stopping"] {
        assert!(log.contains(name), "{log}");
    }
}

fn fails(args: &[&str]) -> (Option<i32>, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_drive-sim")).args(args).stdin(Stdio::null()).output().unwrap();
    (out.status.code(), String::from_utf8_lossy(&out.stderr).into_owned())
}

#[test]
fn command_line_mistakes_are_explained() {
    let listen = ["--listen", "127.0.0.1:0"];
    let cases: &[(&[&str], i32, &str)] = &[
        (&["--node-id", "2", "--device", "drvi"], 1, "--node-id must follow the --device"),
        (&["--device", "drvi", "--node-id", "2", "--node-id", "3"], 1, "device 1 (drvi) has two --node-id"),
        (&["--device", "drvi", "--node-id", "2", "--device", "akd", "--node-id", "2"], 1, "two devices with node id 2"),
        (&["--device", "drvi"], 1, "no node id"),
        (&["--device", "drvi", "--node-id", "0"], 1, "node id 0 is outside 1..=127"),
        (&["--device", "xyz", "--node-id", "2"], 2, "unknown device 'xyz'"),
        (&["--device", "drvi", "--node-id", "2", "--dcf", "/nonexistent/x.dcf"], 1, "/nonexistent/x.dcf"),
    ];
    for (args, code, message) in cases {
        let mut all = vec!["run"];
        all.extend_from_slice(args);
        all.extend_from_slice(&listen);
        let (got, stderr) = fails(&all);
        assert_eq!(got, Some(*code), "{all:?}: {stderr}");
        assert!(stderr.contains(message), "{all:?}: {stderr}");
    }
    // Neither --listen nor --bus.
    let (got, stderr) = fails(&["run", "--device", "drvi", "--node-id", "2"]);
    assert_eq!(got, Some(2), "{stderr}");
    assert!(stderr.contains("--listen") && stderr.contains("--bus"), "{stderr}");
}

#[test]
fn saved_parameters_persist_and_a_corrupt_file_is_reported() {
    let dir = std::env::temp_dir().join(format!("drive-e2e-cli-state-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let state = dir.to_str().unwrap();
    let args = ["run", "--device", "drvi", "--node-id", "2", "--state-dir", state, "--listen", "127.0.0.1:0"];

    let mut first = Process::start(&args, "listening on ");
    let od = master(&first.ready, "can0");
    download_u32(&od, 2, 0x6083, 0, 12345);
    od.node(2).unwrap().write_bytes(0x1010, 1, b"save").expect("1010h save");
    drop(od);
    first.signal(libc::SIGTERM);
    assert!(first.wait().0.success());

    let mut second = Process::start(&args, "listening on ");
    assert_eq!(upload(&master(&second.ready, "can0"), 2, 0x6083), 12345u32.to_le_bytes());
    second.signal(libc::SIGTERM);
    assert!(second.wait().0.success());

    let file = dir.join("drvi-node2.params");
    let mut bytes = std::fs::read(&file).unwrap();
    let middle = bytes.len() / 2;
    bytes[middle] ^= 0xFF;
    std::fs::write(&file, bytes).unwrap();
    let mut third = Process::start(&args, "listening on ");
    assert_eq!(upload(&master(&third.ready, "can0"), 2, 0x6083), [0, 0, 0, 0]);
    third.signal(libc::SIGTERM);
    let (status, log) = third.wait();
    assert!(status.success());
    assert!(log.contains("drvi-node2: warning: ignoring stored parameters, defaults used"), "{log}");
    assert!(log.contains("drvi-node2.params"), "{log}");
    std::fs::remove_dir_all(&dir).unwrap();
}
