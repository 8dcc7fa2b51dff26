//! The AKD end to end in Rust: `drive-sim run --device akd --node-id 4` on its TCP hub, a master
//! on the socketcand protocol (the transport's own client): moves in degrees through the
//! factor group read back from the drive into the generated units module
//! (`generated::akd::units`), 1010h saves that survive SIGKILL at any moment, and
//! `--trace`/`--plot` recording the AKD.

use std::io::{BufRead, BufReader};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use generated::akd::Dictionary;
use generated::akd::units::{Dimension, Quantity, System, Unit, Units};
use od_bus::CanFrame;

const ID: u8 = 4;
const WAIT: Duration = Duration::from_secs(5);
const SAVE: i64 = 0x6576_6173;

/// A running `drive-sim run --device akd`; killed (SIGKILL) when dropped.
struct Sim {
    child: Child,
    addr: SocketAddr,
}

impl Sim {
    fn start(extra: &[&str]) -> Self {
        let mut child = Command::new(env!("CARGO_BIN_EXE_drive-sim"))
            .args(["run", "--device", "akd", "--node-id", "4", "--listen", "127.0.0.1:0"])
            .args(extra)
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .expect("drive-sim starts");
        let mut line = String::new();
        BufReader::new(child.stdout.take().expect("stdout")).read_line(&mut line).expect("first line");
        let addr = line.trim().strip_prefix("listening on ").unwrap_or_else(|| panic!("first line {line:?}"));
        Self { addr: addr.parse().expect("address"), child }
    }

    /// SIGTERM (drive-sim then writes its trace and plot) and the exit status.
    fn terminate(mut self) -> bool {
        let pid = self.child.id().to_string();
        assert!(Command::new("kill").args(["-TERM", &pid]).status().unwrap().success());
        let deadline = Instant::now() + WAIT;
        loop {
            if let Some(status) = self.child.try_wait().unwrap() {
                return status.success();
            }
            assert!(Instant::now() < deadline, "drive-sim did not stop after SIGTERM");
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

impl Drop for Sim {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// od-master (its blocking facade) on the hub, talking to the AKD.
struct Master {
    bus: od_master::blocking::Bus,
    node: od_master::blocking::Node,
}

impl Master {
    fn connect(sim: &Sim) -> Self {
        let (bus, node) = crate::support::on_hub(sim.addr, ID, WAIT);
        Self { bus, node }
    }

    /// An SDO request of the test's own, put on the bus as it is; its answer is not awaited.
    fn send(&mut self, request: [u8; 8]) {
        self.bus.send(CanFrame::standard(0x600 + u32::from(ID), &request).unwrap()).unwrap();
    }

    fn write(&mut self, index: u16, sub: u8, value: i64, len: usize) {
        let data = &value.to_le_bytes()[..len];
        self.node.write_bytes(index, sub, data).unwrap_or_else(|e| panic!("download {index:04X}h sub {sub}: {e}"));
    }

    /// A signed value of the entry's length.
    fn read(&mut self, index: u16, sub: u8) -> i64 {
        let d = self.node.read_bytes(index, sub).unwrap_or_else(|e| panic!("upload {index:04X}h sub {sub}: {e}"));
        let n = d.len();
        assert!((1..=4).contains(&n), "upload {index:04X}h sub {sub}: {d:02X?}");
        let mut b = if d[n - 1] & 0x80 != 0 { [0xFF; 8] } else { [0; 8] };
        b[..n].copy_from_slice(&d);
        i64::from_le_bytes(b)
    }

    fn wait_statusword(&mut self, mask: u16, value: u16) -> u16 {
        let deadline = Instant::now() + Duration::from_secs(10);
        loop {
            let sw = self.read(0x6041, 0) as u16;
            if sw & mask == value {
                return sw;
            }
            assert!(Instant::now() < deadline, "statusword {sw:04X}h & {mask:04X}h never {value:04X}h");
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    fn enable(&mut self) {
        for cw in [0x06, 0x07, 0x0F] {
            self.write(0x6040, 0, cw, 2);
        }
        self.wait_statusword(0x6F, 0x27);
    }

    /// The generated conversions for the factor group the drive holds now.
    fn units(&mut self) -> Units {
        let mut od = Dictionary::new(ID);
        od.set_fieldbus_configuration_bits(self.read(0x36E9, 0) as u32).unwrap();
        od.set_position_encoder_resolution_increments(self.read(0x608F, 1) as u32).unwrap();
        od.set_position_encoder_resolution_motor_revolutions(self.read(0x608F, 2) as u32).unwrap();
        od.set_gear_ratio_motor_shaft_revolutions(self.read(0x6091, 1) as u32).unwrap();
        od.set_gear_ratio_driving_shaft_revolutions(self.read(0x6091, 2) as u32).unwrap();
        od.set_feed_constant_feed(self.read(0x6092, 1) as u32).unwrap();
        od.set_feed_constant_shaft_revolutions(self.read(0x6092, 2) as u32).unwrap();
        Units::from_dictionary(&od).unwrap()
    }

    fn move_to(&mut self, target: Quantity, relative: bool) {
        let raw = self.units().to_raw(Dimension::Position, target).unwrap();
        self.write(0x607A, 0, raw, 4);
        self.write(0x6040, 0, if relative { 0x5F } else { 0x1F }, 2);
        self.write(0x6040, 0, 0x0F, 2);
        std::thread::sleep(Duration::from_millis(20));
        self.wait_statusword(0x1400, 0x0400);
    }
}

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("akd-e2e-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn remove(dir: &Path) {
    let _ = std::fs::remove_dir_all(dir);
}

/// 6.5 over the hub: a shaft behind a 10:1 gearbox in degrees (6092h = 360 per shaft turn) with
/// the DS402 factors, positions converted by the generated units module from the factor group
/// the drive reports; 6063h counts 608Fh = 4096 increments per motor turn.
/// On the `free` machine: 2.5 motor turns would reach the limit switch of the default one.
#[test]
fn moves_in_degrees_through_the_generated_units() {
    let sim = Sim::start(&["--machine", "free"]);
    let mut m = Master::connect(&sim);
    m.write(0x36E9, 0, 0x10, 4);
    m.write(0x6092, 1, 360, 4);
    m.write(0x6091, 1, 10, 4);
    m.write(0x608F, 1, 4096, 4);
    m.write(0x6081, 0, 720, 4);
    m.write(0x6083, 0, 36_000, 4);
    m.write(0x6084, 0, 36_000, 4);
    m.write(0x6060, 0, 1, 1);
    m.enable();
    let units = m.units();
    assert_eq!(units.system(), System::Ds402Factors);
    let deg = |v: i64| Quantity::int(v, Unit::UserUnit);
    m.move_to(deg(90), false);
    let at = units.to_physical(Dimension::Position, m.read(0x6064, 0)).unwrap();
    assert_eq!(at, deg(90));
    let increments = units.to_internal(Dimension::Position, m.read(0x6064, 0)).unwrap().round();
    assert_eq!(increments, 10_240, "2.5 motor turns of 4096");
    assert_eq!(i128::from(m.read(0x6063, 0)), increments);
    m.move_to(deg(-30), true);
    assert_eq!(units.to_physical(Dimension::Position, m.read(0x6064, 0)).unwrap(), deg(60));
    assert_eq!(m.read(0x6063, 0), (60 * 10 * 4096 + 180) / 360, "rounded to the nearest increment");
}

/// 1010h under SIGKILL: a drive-sim killed at any moment of a save restarts with the previous
/// or the new parameter set of each area, never a mix, never a corrupt one; the store list
/// leaves the commands (60FFh) out whatever happens.
#[test]
fn a_kill_during_save_never_leaves_a_torn_parameter_set() {
    let dir = temp("kill");
    let state = dir.to_str().unwrap().to_owned();
    let args = ["--state-dir", state.as_str()];
    // Two stored objects per area: DRV.ACC/DRV.DEC (3501h/3522h), MT.V/MT.ACC (6081h/6083h).
    let generation = |m: &mut Master, g: i64| {
        m.write(0x3501, 0, g, 4);
        m.write(0x3522, 0, g + 1, 4);
        m.write(0x6081, 0, g, 4);
        m.write(0x6083, 0, g + 1, 4);
        m.write(0x60FF, 0, g, 4);
    };
    {
        let sim = Sim::start(&args);
        let mut m = Master::connect(&sim);
        generation(&mut m, 1);
        m.write(0x1010, 1, SAVE, 4);
    }
    let mut saved = [1i64; 2];
    let mut attempted = 1i64;
    let mut completed = 0;
    // Every eighth round waits for the save's confirmation before the kill: then the next
    // start must find the new set (and the test has completed saves however loaded the machine).
    let mut confirmed = false;
    for round in 0..30u64 {
        let sim = Sim::start(&args);
        let mut m = Master::connect(&sim);
        let found = [("2000h", m.read(0x3501, 0), m.read(0x3522, 0)), ("6000h", m.read(0x6081, 0), m.read(0x6083, 0))];
        for (i, (area, a, b)) in found.into_iter().enumerate() {
            assert_eq!(b, a + 1, "round {round}: torn {area} set ({a}, {b})");
            assert!(
                a == saved[i] || a == attempted,
                "round {round}: {area} holds {a}, not {} or {attempted}",
                saved[i]
            );
            assert!(!confirmed || a == attempted, "round {round}: {area} lost a confirmed save ({a})");
            if a != saved[i] {
                saved[i] = a;
                completed += 1;
            }
        }
        assert_eq!(m.read(0x60FF, 0), 0, "60FFh is a command, never stored");
        attempted += 1;
        generation(&mut m, attempted);
        confirmed = round % 8 == 7;
        if confirmed {
            m.write(0x1010, 1, SAVE, 4);
        } else {
            let s = (SAVE as u32).to_le_bytes();
            m.send([0x23, 0x10, 0x10, 1, s[0], s[1], s[2], s[3]]);
            std::thread::sleep(Duration::from_micros(round * 131 % 4000));
        }
        drop(m);
        drop(sim); // SIGKILL
    }
    assert!(completed > 0, "some saves completed before the kill");
    assert!(completed < 2 * 30, "some saves were cut short");
    remove(&dir);
}

/// `--trace`/`--plot` record the AKD's motion in its bus units.
#[test]
fn drive_sim_traces_and_plots_the_akd() {
    let dir = temp("trace");
    let (csv, svg) = (dir.join("akd.csv"), dir.join("akd.svg"));
    let sim =
        Sim::start(&["--trace", csv.to_str().unwrap(), "--plot", svg.to_str().unwrap(), "--trace-interval-ms", "1"]);
    let mut m = Master::connect(&sim);
    m.write(0x6092, 1, 10_000, 4); // um
    m.write(0x6060, 0, 3, 1);
    m.enable();
    m.write(0x60FF, 0, 20_000, 4);
    std::thread::sleep(Duration::from_millis(300));
    m.write(0x60FF, 0, 0, 4);
    std::thread::sleep(Duration::from_millis(200));
    drop(m);
    assert!(sim.terminate(), "drive-sim exits cleanly");
    let trace = std::fs::read_to_string(&csv).expect("trace written");
    let header = trace.lines().next().unwrap();
    let column = header.split(',').position(|c| c.starts_with("velocity_actual")).expect("velocity column");
    let peak = trace
        .lines()
        .skip(1)
        .filter_map(|l| l.split(',').nth(column).and_then(|v| v.parse::<i64>().ok()))
        .max()
        .unwrap();
    assert!((19_990..=20_010).contains(&peak), "peak velocity {peak} um/s");
    let plot = std::fs::read_to_string(&svg).expect("plot written");
    assert!(plot.starts_with("<svg") || plot.starts_with("<?xml"), "an SVG");
    remove(&dir);
}
