//! `drive-sim hub` as a process: it reports its port, relays between clients, and stops
//! cleanly on SIGTERM and SIGINT; `dump` and `send` reach it as clients.

use std::io::{BufRead, BufReader};
use std::net::SocketAddr;
use std::process::{Child, Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use od_bus::{CanFrame, Endpoint, SocketcandClient};

const WAIT: Duration = Duration::from_secs(10);

struct HubProcess {
    child: Child,
    addr: SocketAddr,
}

impl HubProcess {
    fn start() -> Self {
        let mut child = Command::new(env!("CARGO_BIN_EXE_drive-sim"))
            .args(["hub", "--listen", "127.0.0.1:0"])
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("start drive-sim");
        let stdout = child.stdout.take().unwrap();
        let mut line = String::new();
        BufReader::new(stdout).read_line(&mut line).expect("read the listening line");
        let addr =
            line.trim().strip_prefix("listening on ").unwrap_or_else(|| panic!("unexpected first line {line:?}"));
        Self { addr: addr.parse().unwrap(), child }
    }

    fn signal(&mut self, signal: libc::c_int) -> ExitStatus {
        let pid = libc::pid_t::try_from(self.child.id()).unwrap();
        // SAFETY: sending a signal to our own child process.
        assert_eq!(unsafe { libc::kill(pid, signal) }, 0);
        let deadline = Instant::now() + WAIT;
        loop {
            if let Some(status) = self.child.try_wait().unwrap() {
                return status;
            }
            assert!(Instant::now() < deadline, "drive-sim did not stop on signal {signal}");
            std::thread::sleep(Duration::from_millis(10));
        }
    }
}

impl Drop for HubProcess {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

#[test]
fn the_hub_process_relays_and_stops_on_sigterm() {
    let mut hub = HubProcess::start();
    let mut a = SocketcandClient::connect(hub.addr, "can0").unwrap();
    let mut b = SocketcandClient::connect(hub.addr, "can0").unwrap();
    let frame = CanFrame::standard(0x601, &[0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]).unwrap();
    a.send(frame).unwrap();
    assert_eq!(b.recv_timeout(WAIT).unwrap(), Some(frame));
    let ext = CanFrame::extended(0x18DA_F110, &[0x02, 0x10, 0x03]).unwrap();
    b.send(ext).unwrap();
    assert_eq!(a.recv_timeout(WAIT).unwrap(), Some(ext));

    let status = hub.signal(libc::SIGTERM);
    assert!(status.success(), "{status}");
    assert!(a.recv_timeout(WAIT).is_err(), "clients see the hub go away");
}

#[test]
fn the_hub_process_stops_on_sigint() {
    let mut hub = HubProcess::start();
    let _client = SocketcandClient::connect(hub.addr, "can0").unwrap();
    let status = hub.signal(libc::SIGINT);
    assert!(status.success(), "{status}");
}

#[test]
fn dump_and_send_are_clients_of_the_hub() {
    let hub = HubProcess::start();
    let bus = format!("socketcand://{}/vcan3", hub.addr);
    // The form drive-sim took first, still accepted.
    let alias = format!("tcp://{}/vcan3", hub.addr);
    let mut dump = Command::new(env!("CARGO_BIN_EXE_drive-sim"))
        .args(["dump", "--bus", &bus, "--count", "3", "--timeout", "10"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // dump says on stderr when it is on the bus; frames sent before that would be missed.
    let mut line = String::new();
    BufReader::new(dump.stderr.take().unwrap()).read_line(&mut line).unwrap();
    assert_eq!(line.trim(), format!("dump: on {bus}"));
    let mut probe = SocketcandClient::connect(hub.addr, "vcan3").unwrap();
    let sent = Command::new(env!("CARGO_BIN_EXE_drive-sim"))
        .args(["send", "--bus", &alias, "000#0100", "080#", "1ABCDEF0#R2"])
        .status()
        .unwrap();
    assert!(sent.success());
    let output = dump.wait_with_output().unwrap();
    assert!(output.status.success());
    assert_eq!(String::from_utf8(output.stdout).unwrap(), "000#0100\n080#\n1ABCDEF0#R2\n");
    // The probe saw them too.
    let got: Vec<String> = (0..3).map(|_| probe.recv_timeout(WAIT).unwrap().unwrap().to_string()).collect();
    assert_eq!(got, ["000#0100", "080#", "1ABCDEF0#R2"]);

    let bad = Command::new(env!("CARGO_BIN_EXE_drive-sim"))
        .args(["send", "--bus", &bus, "601#0"])
        .stderr(Stdio::piped())
        .output()
        .unwrap();
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("odd number of data hex digits"));
}

#[test]
fn dump_reports_the_frames_the_hub_dropped_because_it_read_too_slowly() {
    use std::io::Read;
    let mut hub = Command::new(env!("CARGO_BIN_EXE_drive-sim"))
        .args(["hub", "--listen", "127.0.0.1:0", "--quiet", "--queue", "16", "--max-rate", "0"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(hub.stdout.take().unwrap()).read_line(&mut line).unwrap();
    let address = line.trim().strip_prefix("listening on ").unwrap().to_owned();
    // dump's stdout is not read for now: it blocks writing, stops reading its socket, and the
    // hub's queue for it overflows.
    let mut dump = Command::new(env!("CARGO_BIN_EXE_drive-sim"))
        .args(["dump", "--bus", &format!("tcp://{address}/can0"), "--timeout", "20"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut sender = SocketcandClient::connect(address.as_str(), "can0").unwrap();
    // Wait until dump has joined: it prints a probe frame. A fixed sleep was not enough on a
    // loaded machine (dump joined after the flood, so nothing was lost and the test failed).
    // The reader thread reads the probe's line, then waits for `go` before reading the rest.
    let mut out = BufReader::new(dump.stdout.take().unwrap());
    let (joined_tx, joined) = std::sync::mpsc::channel();
    let (go, go_rx) = std::sync::mpsc::channel::<()>();
    let reader = std::thread::spawn(move || {
        let mut first = String::new();
        let _ = out.read_line(&mut first);
        let _ = joined_tx.send(());
        let _ = go_rx.recv();
        let mut text = String::new();
        let _ = out.read_to_string(&mut text);
        1 + text.lines().count()
    });
    let probe = CanFrame::standard(0x7FE, &[]).unwrap();
    let mut probes = 0u64;
    let join_deadline = Instant::now() + Duration::from_secs(20);
    loop {
        sender.send(probe).unwrap();
        probes += 1;
        if joined.recv_timeout(Duration::from_millis(100)).is_ok() {
            break;
        }
        assert!(Instant::now() < join_deadline, "dump printed no frame within 20 s");
    }
    let frame = CanFrame::standard(0x181, &[1, 2, 3, 4, 5, 6, 7, 8]).unwrap();
    for _ in 0..300_000 {
        sender.send(frame).unwrap();
    }
    sender.echo(Duration::from_secs(30)).unwrap();
    // Now read: dump catches up and is told what it missed.
    go.send(()).unwrap();
    // The hub says what it dropped with the next frames it writes, at most once per report
    // interval, and dump prints it once it has read that far: send a frame every 200 ms until
    // dump's stderr says so (20 s at most), rather than guess how long that takes.
    let mut stderr = BufReader::new(dump.stderr.take().unwrap());
    let (said_tx, said) = std::sync::mpsc::channel();
    let log_reader = std::thread::spawn(move || {
        let mut log = String::new();
        let mut line = String::new();
        while stderr.read_line(&mut line).is_ok_and(|n| n > 0) {
            if line.contains("frames lost") {
                let _ = said_tx.send(());
            }
            log.push_str(&line);
            line.clear();
        }
        log
    });
    let nudge = CanFrame::standard(0x7FF, &[]).unwrap();
    let report_deadline = Instant::now() + Duration::from_secs(20);
    loop {
        sender.send(nudge).unwrap();
        probes += 1;
        if said.recv_timeout(Duration::from_millis(200)).is_ok() || Instant::now() >= report_deadline {
            break;
        }
    }
    let deadline = Instant::now() + Duration::from_secs(30);
    let _ = unsafe { libc::kill(libc::pid_t::try_from(dump.id()).unwrap(), libc::SIGTERM) };
    while dump.try_wait().unwrap().is_none() {
        assert!(Instant::now() < deadline, "dump did not stop");
        std::thread::sleep(Duration::from_millis(10));
    }
    let log = log_reader.join().unwrap();
    let printed = reader.join().unwrap();
    let _ = hub.kill();
    let _ = hub.wait();
    assert!(log.contains("frames lost") && log.contains("reads more slowly than the bus runs"), "{log}");
    let lost: u64 = log
        .lines()
        .filter_map(|l| {
            l.split_once(" in all)").and_then(|(head, _)| head.rsplit_once('(')).map(|(_, n)| n.parse().unwrap())
        })
        .max()
        .unwrap();
    assert!(lost > 0 && printed as u64 + lost <= 300_002 + probes, "printed {printed}, lost {lost}");
}

#[test]
fn a_bus_drive_sim_cannot_share_is_refused_naming_the_forms() {
    for (bus, says) in [
        ("mem://line", "an in-memory bus lives inside one process"),
        ("udp://127.0.0.1:1/can0", "unknown scheme"),
        ("socketcand://127.0.0.1/can0", "no port"),
    ] {
        for command in [
            &["dump", "--bus", bus][..],
            &["send", "--bus", bus, "080#"],
            &["run", "--device", "drvi", "--node-id", "2", "--bus", bus],
        ] {
            let out = Command::new(env!("CARGO_BIN_EXE_drive-sim")).args(command).output().unwrap();
            assert!(!out.status.success(), "{command:?}");
            let stderr = String::from_utf8_lossy(&out.stderr);
            assert!(
                stderr.contains(says) && stderr.contains("socketcand://HOST:PORT/CHANNEL"),
                "{command:?}: {stderr}"
            );
        }
    }
}

#[test]
fn hub_and_run_help_document_the_limits_and_the_bitrate() {
    for command in ["hub", "run"] {
        let out = Command::new(env!("CARGO_BIN_EXE_drive-sim")).args([command, "--help"]).output().unwrap();
        assert!(out.status.success());
        let help = String::from_utf8(out.stdout).unwrap();
        for option in ["--max-clients", "--handshake-timeout-ms", "--max-rate", "--bitrate", "Hub limits"] {
            assert!(help.contains(option), "{command} --help lacks {option}:\n{help}");
        }
        assert!(help.contains("[default: 1024]") && help.contains("longest"), "{help}");
    }
}

/// `drive-sim run --bus` with several devices joins the bus once for all of them by default,
/// and once per device with `--connection-per-device`; either way each device answers its own
/// SDO requests, also when they come at once.
#[test]
fn run_joins_once_for_its_devices_or_once_each_when_asked() {
    for (per_device, connections) in [(false, 1), (true, 3)] {
        let hub = od_bus::Hub::bind("127.0.0.1:0", od_bus::HubConfig::default().quiet()).unwrap();
        let bus = format!("socketcand://{}/can0", hub.local_addr());
        let mut args = vec!["run", "--bus", &bus, "--device", "drvi", "--node-id", "1"];
        args.extend(["--device", "drcs", "--node-id", "2", "--device", "akd", "--node-id", "3"]);
        if per_device {
            args.push("--connection-per-device");
        }
        let mut child = Command::new(env!("CARGO_BIN_EXE_drive-sim"))
            .args(&args)
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("start drive-sim");
        let mut line = String::new();
        BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).unwrap();
        assert_eq!(line.trim(), format!("running on {bus}"));
        let mut master = hub.attach("can0").unwrap();
        let deadline = Instant::now() + WAIT;
        while hub.client_count() < connections {
            assert!(Instant::now() < deadline, "{} connections", hub.client_count());
            std::thread::sleep(Duration::from_millis(5));
        }
        for id in 1..=3u32 {
            master.send(CanFrame::standard(0x600 + id, &[0x40, 0x00, 0x10, 0x00, 0, 0, 0, 0]).unwrap()).unwrap();
        }
        let mut answered = Vec::new();
        while answered.len() < 3 {
            let frame = master.recv_timeout(WAIT).unwrap().expect("every drive answers");
            if frame.id() & !0x7F == 0x580 {
                assert_eq!(frame.data()[0], 0x43, "{frame:?}");
                answered.push(frame.id());
            }
        }
        answered.sort();
        assert_eq!(answered, [0x581, 0x582, 0x583]);
        assert_eq!(hub.client_count(), connections, "--connection-per-device {per_device}");
        let _ = child.kill();
        let _ = child.wait();
    }
}

/// `drive-sim hub` says where it listens once, on stdout (its log on stderr does not repeat it).
#[test]
fn hub_prints_its_address_once() {
    use std::io::Read;
    let mut hub = Command::new(env!("CARGO_BIN_EXE_drive-sim"))
        .args(["hub", "--listen", "127.0.0.1:0"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(hub.stdout.take().unwrap()).read_line(&mut line).unwrap();
    assert!(line.starts_with("listening on 127.0.0.1:"), "{line:?}");
    hub.kill().unwrap();
    hub.wait().unwrap();
    let mut log = String::new();
    hub.stderr.take().unwrap().read_to_string(&mut log).unwrap();
    assert!(!log.contains("listening"), "{log}");
}
