//! The DRVI through `drive-sim` as a process: a master lost by node guarding over the TCP hub
//! (remote frames, which python-can's socketcand interface cannot send), `run --trace --plot`,
//! and the `demo` subcommand (the main job).

use std::io::{BufRead, BufReader, Read};
use std::net::SocketAddr;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use drive::trace::Trace;
use drive::transport::{CanFrame, Endpoint, SocketcandClient};

const WAIT: Duration = Duration::from_secs(10);

struct DriveSim {
    child: Child,
    addr: SocketAddr,
}

impl DriveSim {
    fn start(args: &[&str]) -> Self {
        let mut child = Command::new(env!("CARGO_BIN_EXE_drive-sim"))
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("start drive-sim");
        let mut line = String::new();
        BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).expect("read the first line");
        let addr = line.trim().strip_prefix("listening on ").unwrap_or_else(|| panic!("first line {line:?}"));
        Self { addr: addr.parse().unwrap(), child }
    }

    /// SIGTERM, then waits (bounded); returns whether it exited with 0 and its stderr.
    fn stop(mut self) -> (bool, String) {
        let pid = libc::pid_t::try_from(self.child.id()).unwrap();
        // SAFETY: sending a signal to our own child process.
        assert_eq!(unsafe { libc::kill(pid, libc::SIGTERM) }, 0);
        let deadline = Instant::now() + WAIT;
        let status = loop {
            if let Some(status) = self.child.try_wait().unwrap() {
                break status;
            }
            assert!(Instant::now() < deadline, "drive-sim did not stop");
            std::thread::sleep(Duration::from_millis(10));
        };
        let mut text = String::new();
        if let Some(mut e) = self.child.stderr.take() {
            e.read_to_string(&mut text).unwrap();
        }
        (status.success(), text)
    }
}

impl Drop for DriveSim {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn next_with_id(bus: &mut SocketcandClient, id: u32, within: Duration) -> Option<CanFrame> {
    let deadline = Instant::now() + within;
    loop {
        let left = deadline.saturating_duration_since(Instant::now());
        if left.is_zero() {
            return None;
        }
        match bus.recv_timeout(left).unwrap() {
            Some(f) if f.id() == id => return Some(f),
            Some(_) => continue,
            None => return None,
        }
    }
}

fn sdo(bus: &mut SocketcandClient, data: [u8; 8]) -> [u8; 8] {
    bus.send(CanFrame::standard(0x602, &data).unwrap()).unwrap();
    next_with_id(bus, 0x582, WAIT).expect("SDO response").raw_data()
}

fn write(bus: &mut SocketcandClient, index: u16, sub: u8, value: u32, len: u8) {
    let v = value.to_le_bytes();
    let cmd = 0x23 | ((4 - len) << 2);
    let r = sdo(bus, [cmd, index as u8, (index >> 8) as u8, sub, v[0], v[1], v[2], v[3]]);
    assert_eq!(r[0], 0x60, "download {index:04X}sub{sub}: {r:02X?}");
}

fn statusword(bus: &mut SocketcandClient) -> u16 {
    let r = sdo(bus, [0x40, 0x41, 0x60, 0, 0, 0, 0, 0]);
    u16::from_le_bytes([r[4], r[5]])
}

#[test]
fn a_master_lost_by_node_guarding_quick_stops_the_drvi_into_fault() {
    let sim = DriveSim::start(&["run", "--device", "drvi", "--node-id", "2", "--listen", "127.0.0.1:0"]);
    let mut bus = SocketcandClient::connect(sim.addr, "can0").unwrap();
    write(&mut bus, 0x100C, 0, 50, 2); // guard time 50 ms
    write(&mut bus, 0x100D, 0, 3, 1); // life time factor 3
    for cw in [0x06, 0x07, 0x0F] {
        write(&mut bus, 0x6040, 0, cw, 2);
    }
    write(&mut bus, 0x6060, 0, 3, 1); // profile velocity
    write(&mut bus, 0x6083, 0, 600, 4);
    write(&mut bus, 0x6084, 0, 600, 4);
    write(&mut bus, 0x60FF, 0, 3000, 4); // 30 rpm
    for _ in 0..10 {
        bus.send(CanFrame::remote(0x702, false, 1).unwrap()).unwrap();
        assert!(next_with_id(&mut bus, 0x702, WAIT).is_some(), "guarding reply");
        std::thread::sleep(Duration::from_millis(30));
    }
    assert_eq!(statusword(&mut bus) & 0x6F, 0x27, "still operation enabled while guarded");
    let emcy = next_with_id(&mut bus, 0x082, Duration::from_secs(3)).expect("EMCY for the lost master");
    assert_eq!(emcy.data(), [0x30, 0x81, 0x11, 0, 0, 0, 0, 0], "8130h, communication bit");
    // A soft error: a quick stop ramp (30 rpm at 600 rpm/s: 50 ms), then Fault.
    let deadline = Instant::now() + WAIT;
    while statusword(&mut bus) & 0x4F != 0x08 {
        assert!(Instant::now() < deadline, "no Fault");
        std::thread::sleep(Duration::from_millis(10));
    }
    let r = sdo(&mut bus, [0x40, 0x3F, 0x60, 0, 0, 0, 0, 0]);
    assert_eq!(u16::from_le_bytes([r[4], r[5]]), 0x8130, "603Fh");
    let (ok, log) = sim.stop();
    assert!(ok, "{log}");
}

#[test]
fn run_writes_the_trace_and_the_plot_when_stopped() {
    let dir = std::env::temp_dir().join(format!("drvi-run-trace-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let (csv, svg) = (dir.join("t.csv"), dir.join("p.svg"));
    let sim = DriveSim::start(&[
        "run",
        "--device",
        "drvi",
        "--node-id",
        "2",
        "--listen",
        "127.0.0.1:0",
        "--trace",
        csv.to_str().unwrap(),
        "--plot",
        svg.to_str().unwrap(),
        "--trace-interval-ms",
        "1",
    ]);
    let mut bus = SocketcandClient::connect(sim.addr, "can0").unwrap();
    for cw in [0x06, 0x07, 0x0F] {
        write(&mut bus, 0x6040, 0, cw, 2);
    }
    write(&mut bus, 0x6060, 0, 3, 1);
    write(&mut bus, 0x6083, 0, 6000, 4);
    write(&mut bus, 0x60FF, 0, 6000, 4);
    std::thread::sleep(Duration::from_millis(300));
    let (ok, log) = sim.stop();
    assert!(ok, "{log}");
    assert!(log.contains("trace written"), "{log}");
    let trace = Trace::from_csv(&std::fs::read_to_string(&csv).unwrap()).unwrap();
    let top = trace.samples().iter().map(|s| s.velocity_actual).max().unwrap();
    assert_eq!(top, 6000, "reached 60 rpm");
    assert!(trace.samples().iter().any(|s| s.mode == 3 && s.statusword & 0x6F == 0x27));
    let plot = std::fs::read_to_string(&svg).unwrap();
    assert!(plot.starts_with("<svg") && plot.contains("rpm"), "physical units on the plot");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn demo_runs_the_main_job() {
    let dir = std::env::temp_dir().join(format!("drvi-demo-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let (csv, svg) = (dir.join("demo.csv"), dir.join("sub").join("demo.svg"));
    let out = Command::new(env!("CARGO_BIN_EXE_drive-sim"))
        .args(["demo", "--plot", svg.to_str().unwrap(), "--trace", csv.to_str().unwrap()])
        .output()
        .expect("run drive-sim demo");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{text}\n{}", String::from_utf8_lossy(&out.stderr));
    for expected in [
        "device name \"DRVI\"",
        "Operation enabled",
        "homing completed",
        "position 0.00 deg",
        "target reached",
        "position 720.00 deg",
        "plot: ",
    ] {
        assert!(text.contains(expected), "missing {expected:?} in:\n{text}");
    }
    let trace = Trace::from_csv(&std::fs::read_to_string(&csv).unwrap()).unwrap();
    assert_eq!(trace.samples().last().unwrap().position_actual, 72_000);
    assert!(std::fs::read_to_string(&svg).unwrap().contains("deg"));
    // Deterministic: the same run prints the same log (wall time aside).
    let again = Command::new(env!("CARGO_BIN_EXE_drive-sim")).arg("demo").output().unwrap();
    let strip = |s: &str| {
        s.lines()
            .filter(|l| !l.starts_with("done:") && !l.starts_with("plot") && !l.starts_with("trace"))
            .map(str::to_owned)
            .collect::<Vec<_>>()
    };
    assert_eq!(strip(&text), strip(&String::from_utf8_lossy(&again.stdout)));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn demo_refuses_devices_without_one() {
    let out = Command::new(env!("CARGO_BIN_EXE_drive-sim")).args(["demo", "--device", "nope"]).output().unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("unknown device"));
}
