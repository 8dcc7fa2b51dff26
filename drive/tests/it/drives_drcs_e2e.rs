//! The DRCS end to end in Rust: `drive-sim run --device drcs --node-id 3` on its TCP hub, a
//! master on the socketcand protocol (the transport's own client), and positions converted
//! with the generated units module (`generated::drcs::units`) for the feed converter 2001h the
//! drive reports: homing 17, an absolute and a relative move in millimetres, the unit changed
//! to micrometres and to inches (chapter 4, 3.6.1); and `--trace`/`--plot` recording the DRCS.

use std::path::Path;
use std::time::{Duration, Instant};

use generated::drcs::Dictionary;
use generated::drcs::units::{Dimension, Quantity, Ratio, Unit, Units};
use od_bus::CanFrame;

use crate::drive_sim::DriveSim;

const ID: u8 = 3;
const WAIT: Duration = Duration::from_secs(5);

/// A DRCS as node 3 on a hub of its own, with `extra` arguments.
fn start_drcs(extra: &[&str]) -> DriveSim {
    let mut args = vec!["run", "--device", "drcs", "--node-id", "3", "--listen", "127.0.0.1:0"];
    args.extend_from_slice(extra);
    DriveSim::start(&args)
}

/// od-master (its blocking facade) on the hub, talking to node 3.
struct Master {
    bus: od_master::blocking::Bus,
    node: od_master::blocking::Node,
}

impl Master {
    fn connect(sim: &DriveSim) -> Self {
        let (bus, node) = crate::support::on_hub(sim.addr, ID, WAIT);
        Self { bus, node }
    }

    fn write(&mut self, index: u16, sub: u8, value: i64, len: usize) {
        let data = &value.to_le_bytes()[..len];
        self.node.write_bytes(index, sub, data).unwrap_or_else(|e| panic!("download {index:04X}h/{sub}: {e}"));
    }

    /// The value, sign-extended when it has 4 bytes.
    fn read(&mut self, index: u16, sub: u8) -> i64 {
        let d = self.node.read_bytes(index, sub).unwrap_or_else(|e| panic!("upload {index:04X}h/{sub}: {e}"));
        let n = d.len();
        assert!((1..=4).contains(&n), "upload {index:04X}h/{sub}: {d:02X?}");
        let mut b = if d[n - 1] & 0x80 != 0 && n == 4 { [0xFF; 8] } else { [0; 8] };
        b[..n].copy_from_slice(&d);
        i64::from_le_bytes(b)
    }

    fn wait_statusword(&mut self, mask: u16, value: u16, timeout: Duration) -> u16 {
        let deadline = Instant::now() + timeout;
        loop {
            let sw = self.read(0x6041, 0) as u16;
            if sw & mask == value {
                return sw;
            }
            assert!(Instant::now() < deadline, "statusword {sw:04X}h: {mask:04X}h never became {value:04X}h");
            std::thread::sleep(Duration::from_millis(10));
        }
    }

    /// The generated units for the 2001h the drive holds now.
    fn units(&mut self) -> Units {
        let mut od = Dictionary::new(ID);
        od.set_feed_converter_numerator(self.read(0x2001, 1) as u32).unwrap();
        od.set_feed_converter_denominator(self.read(0x2001, 2) as u32).unwrap();
        Units::from_dictionary(&od).unwrap()
    }

    fn position(&mut self) -> Quantity {
        let raw = self.read(0x6064, 0);
        self.units().to_physical(Dimension::Position, raw).unwrap()
    }

    fn move_mm(&mut self, target: Quantity, relative: bool) {
        let raw = self.units().to_raw(Dimension::Position, target).unwrap();
        self.write(0x607A, 0, raw, 4);
        self.write(0x6040, 0, if relative { 0x5F } else { 0x1F }, 2);
        self.write(0x6040, 0, 0x0F, 2);
        std::thread::sleep(Duration::from_millis(20));
        self.wait_statusword(0x1400, 0x0400, Duration::from_secs(10));
    }

    fn enable_and_home_17(&mut self) {
        for cw in [0x06, 0x07, 0x0F] {
            self.write(0x6040, 0, cw, 2);
        }
        self.wait_statusword(0x6F, 0x27, WAIT);
        self.write(0x6060, 0, 6, 1);
        self.write(0x6098, 0, 17, 1);
        self.write(0x6083, 0, 400, 4);
        self.write(0x6084, 0, 400, 4);
        self.write(0x6099, 1, 150, 4);
        self.write(0x6099, 2, 30, 4);
        self.write(0x6040, 0, 0x1F, 2);
        self.wait_statusword(0x3400, 0x1400, Duration::from_secs(10));
        self.write(0x6040, 0, 0x0F, 2);
        self.write(0x6060, 0, 1, 1);
    }
}

fn mm(n: i128, d: i128) -> Quantity {
    Quantity::new(Ratio::new(n, d).unwrap(), Unit::Millimeter)
}

#[test]
fn moves_in_millimetres_through_the_generated_units_over_the_hub() {
    let sim = start_drcs(&[]);
    let mut m = Master::connect(&sim);
    m.enable_and_home_17();
    assert_eq!(m.units().unit(Dimension::Position), Some(Unit::Millimeter));
    m.write(0x6081, 0, 200, 4);
    m.write(0x6083, 0, 1000, 4);
    m.write(0x6084, 0, 1000, 4);
    m.move_mm(mm(300, 1), false);
    assert_eq!(m.position(), mm(300, 1));
    m.move_mm(mm(-120, 1), true);
    assert_eq!(m.position(), mm(180, 1));
    // Micrometres (2001h = 1000/1): fractions of a millimetre become reachable.
    m.write(0x2001, 1, 1000, 4);
    m.write(0x2001, 2, 1, 4);
    m.write(0x6081, 0, 200_000, 4);
    m.write(0x6083, 0, 1_000_000, 4);
    m.write(0x6084, 0, 1_000_000, 4);
    assert_eq!(m.position(), mm(180, 1));
    m.move_mm(mm(123_456, 1000), false);
    assert_eq!(m.read(0x6064, 0), 123_456);
    m.move_mm(mm(-3_456, 1000), true);
    assert_eq!(m.position(), mm(120, 1));
    // Inches by the formula (10/254): 120 mm = 4.72 in reads as 5 in = 127 mm.
    m.write(0x2001, 1, 10, 4);
    m.write(0x2001, 2, 254, 4);
    assert_eq!(m.read(0x6064, 0), 5);
    assert_eq!(m.position(), mm(127, 1));
    assert_eq!(m.read(0x607D, 2), 39, "1000 mm full scale");
    m.write(0x6081, 0, 8, 4);
    m.write(0x6083, 0, 40, 4);
    m.write(0x6084, 0, 40, 4);
    m.move_mm(mm(254, 1), false); // 10 in
    assert_eq!(m.read(0x6064, 0), 10);
    assert_eq!(m.position(), mm(254, 1));
    assert_eq!(m.read(0x1001, 0), 0, "no error on the way");
}

#[test]
fn drive_sim_traces_and_plots_the_drcs() {
    let dir = std::env::temp_dir().join(format!("drcs-trace-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (csv, svg) = (dir.join("drcs.csv"), dir.join("drcs.svg"));
    let sim =
        start_drcs(&["--trace", csv.to_str().unwrap(), "--plot", svg.to_str().unwrap(), "--trace-interval-ms", "10"]);
    let mut m = Master::connect(&sim);
    m.enable_and_home_17();
    m.write(0x6081, 0, 200, 4);
    m.write(0x6083, 0, 1000, 4);
    m.write(0x6084, 0, 1000, 4);
    m.move_mm(mm(100, 1), false);
    drop(m);
    let _ = sim.stop();
    let text = std::fs::read_to_string(&csv).unwrap();
    let trace = drive::trace::Trace::from_csv(&text).unwrap();
    let samples = trace.samples();
    assert!(samples.iter().any(|s| s.velocity_actual == 200), "cruise at 200 mm/s recorded");
    assert!(samples.iter().any(|s| s.position_actual < -100), "the homing search recorded");
    assert_eq!(samples.last().unwrap().position_actual, 100);
    assert!(std::fs::read_to_string(&svg).unwrap().contains("<svg"));
    remove(&dir);
}

fn remove(dir: &Path) {
    let _ = std::fs::remove_dir_all(dir);
}

/// 1010h under SIGKILL (issue #7, persistence): a drive-sim killed at any moment of a save
/// restarts with either the previous or the new parameter set of each area, never a mix and
/// never a corrupt image (which would fall back to the defaults).
#[test]
fn a_kill_during_save_never_leaves_a_torn_parameter_set() {
    let dir = std::env::temp_dir().join(format!("drcs-kill-{}", std::process::id()));
    remove(&dir);
    let state = dir.to_str().unwrap().to_owned();
    let args = ["--state-dir", state.as_str()];
    // A first complete save: generation 1.
    let sim = start_drcs(&args);
    let mut m = Master::connect(&sim);
    let write_generation = |m: &mut Master, g: i64| {
        m.write(0x2001, 1, g, 4); // manufacturer area
        m.write(0x2001, 2, g + 1, 4);
        m.write(0x6081, 0, g, 4); // application area
        m.write(0x6083, 0, g + 1, 4);
        m.write(0x1017, 0, g, 2); // communication area
        m.write(0x1015, 0, g + 1, 2);
    };
    write_generation(&mut m, 1);
    m.write(0x1010, 1, 0x6576_6173, 4);
    drop(m);
    drop(sim);
    // Per area: the generation on file, and the one the last round tried to save.
    let mut saved = [1i64; 3];
    let mut attempted = 1i64;
    let mut seen_new = 0;
    // Every eighth round waits for the save's confirmation before the kill: then the next
    // start must find the new set (and the test has completed saves however loaded the machine).
    let mut confirmed = false;
    for round in 0..40u64 {
        let sim = start_drcs(&args);
        let mut m = Master::connect(&sim);
        // What the last round left: per area, one whole generation (the old or the new one).
        let found = [
            ("2000h", m.read(0x2001, 1), m.read(0x2001, 2)),
            ("6000h", m.read(0x6081, 0), m.read(0x6083, 0)),
            ("1000h", m.read(0x1017, 0), m.read(0x1015, 0)),
        ];
        for (i, (area, a, b)) in found.into_iter().enumerate() {
            assert_eq!(b, a + 1, "round {round}: torn {area} set ({a}, {b})");
            assert!(
                a == saved[i] || a == attempted,
                "round {round}: {area} generation {a}, expected {} or {attempted}",
                saved[i]
            );
            assert!(!confirmed || a == attempted, "round {round}: {area} lost a confirmed save ({a})");
            if a != saved[i] {
                saved[i] = a;
                seen_new += 1;
            }
        }
        // Write a new generation and kill the process while it saves.
        attempted += 1;
        write_generation(&mut m, attempted);
        confirmed = round % 8 == 7;
        if confirmed {
            m.write(0x1010, 1, 0x6576_6173, 4);
        } else {
            let [lo, hi] = 0x1010u16.to_le_bytes();
            let s = 0x6576_6173u32.to_le_bytes();
            let save = CanFrame::standard(0x600 + u32::from(ID), &[0x23, lo, hi, 1, s[0], s[1], s[2], s[3]]).unwrap();
            m.bus.send(save).unwrap();
            std::thread::sleep(Duration::from_micros(round * 97 % 3000));
        }
        drop(m);
        drop(sim); // SIGKILL
    }
    // Both outcomes happened: kills before, during and after the saves.
    assert!(seen_new > 0, "some saves completed before the kill");
    assert!(seen_new < 3 * 40, "some saves were cut short");
    remove(&dir);
}
