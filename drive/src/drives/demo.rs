//! The main job end to end, in process and on the virtual clock: a simulated DRVI on an
//! in-memory bus, driven by the project's master, `od-master` (on a [`VirtualBus`]), with real
//! CANopen frames (SDO, NMT, RPDO, TPDO) through the node runner: boot-up, PDO mapping, NMT start, the CiA 402 state machine to
//! Operation enabled, homing, an absolute profile-position move given in physical units
//! (converted with the generated `units` module), a readable log, and the trace as CSV and SVG.
//!
//! `drive-sim demo [--device drvi] [--plot demo.svg] [--trace demo.csv]` runs it; so does
//! [`run`]. The same inputs always give the same frames at the same virtual times.

use std::fmt::Write as _;
use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

use od_master::{Axis, Error as MasterError, Node as MasterNode, PdoField, PdoMapping, PdoValue, Tpdo};
use od_runtime::od::DataType;
use od_runtime::pdo::{Direction, MapEntry};
use tokio::sync::mpsc;

use generated::drvi::Dictionary;
use generated::drvi::units::{Dimension, Quantity, Unit, Units};
use od_runtime::Micros;
use od_runtime::cia402::State;
use od_runtime::od::ObjectDictionary;

use super::DeviceApps;
use crate::node::{DeviceKind, NodeConfig, Sim, VirtualBus};
use crate::trace::{PlotOptions, Quantity as PlotQuantity, Trace};

/// What the demo does and where it writes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DemoOptions {
    /// The device (only the DRVI has a demo so far).
    pub device: DeviceKind,
    /// Its node id.
    pub node_id: u8,
    /// Where to write the SVG plot.
    pub plot: Option<PathBuf>,
    /// Where to write the CSV trace.
    pub trace: Option<PathBuf>,
    /// The absolute target of the move, degrees.
    pub target_deg: i64,
}

impl Default for DemoOptions {
    fn default() -> Self {
        Self { device: DeviceKind::Drvi, node_id: 2, plot: None, trace: None, target_deg: 720 }
    }
}

/// What the demo measured.
#[derive(Clone, Debug, PartialEq)]
pub struct DemoReport {
    /// Virtual time at the end, µs.
    pub virtual_us: Micros,
    /// Wall-clock time it took, seconds.
    pub wall_s: f64,
    /// Frames the master sent (the frames on the bus less those it received).
    pub frames_sent: u64,
    /// Frames the master received.
    pub frames_received: u64,
    /// The position after homing, degrees.
    pub homed_at_deg: f64,
    /// The final position (6064h through TPDO2), degrees.
    pub final_deg: f64,
    /// The trace recorded by the drive.
    pub trace: Trace,
}

/// A demo step failed.
#[derive(Debug, thiserror::Error)]
pub enum DemoError {
    /// The device has no demo.
    #[error("no demo for {0} yet (try --device drvi)")]
    Unsupported(DeviceKind),
    /// The node could not be built.
    #[error("{0}")]
    Setup(String),
    /// A call of the master (an SDO transfer, a PDO, NMT) failed.
    #[error("{what}: {error}")]
    Sdo {
        /// The step.
        what: String,
        /// The failure, as od-master reports it.
        error: MasterError,
    },
    /// The drive did not get where it should within the time allowed.
    #[error("{0}")]
    Timeout(String),
    /// Writing the log or the files failed.
    #[error("{0}")]
    Io(#[from] std::io::Error),
}

struct Demo<'a> {
    m: VirtualBus,
    node: MasterNode,
    /// TPDO1 (statusword) and TPDO2 (position, velocity), decoded by od-master.
    tpdo1: mpsc::Receiver<Tpdo>,
    tpdo2: mpsc::Receiver<Tpdo>,
    /// RPDO1: the controlword.
    rpdo1: PdoMapping,
    id: u8,
    out: &'a mut dyn Write,
    units: Units,
    statusword: u16,
    position: i32,
    velocity: i32,
}

fn sdo<T>(what: &str, r: Result<T, MasterError>) -> Result<T, DemoError> {
    r.map_err(|error| DemoError::Sdo { what: what.to_owned(), error })
}

fn state_name(sw: u16) -> &'static str {
    State::from_statusword(sw).map_or("?", State::name)
}

impl Demo<'_> {
    fn t(&self) -> f64 {
        self.m.now() as f64 * 1e-6
    }

    fn log(&mut self, text: &str) -> Result<(), DemoError> {
        let frames = self.m.frames_on_bus();
        writeln!(self.out, "[{:>7.3} s] {:>5} frames  {text}", self.t(), frames)?;
        Ok(())
    }

    fn raw(&self, d: Dimension, value: i64, unit: Unit) -> Result<i64, DemoError> {
        self.units
            .to_raw(d, Quantity::int(value, unit))
            .map_err(|e| DemoError::Setup(format!("{value} {}: {e:?}", unit.symbol())))
    }

    fn physical(&self, d: Dimension, raw: i64) -> f64 {
        self.units.to_physical(d, raw).map_or(f64::NAN, Quantity::to_f64)
    }

    /// Takes the TPDOs received so far: TPDO1 = statusword, TPDO2 = position + velocity.
    fn pdos(&mut self) {
        self.m.take_seen();
        while let Ok(t) = self.tpdo1.try_recv() {
            if let [PdoValue::Unsigned(sw)] = t.values[..] {
                self.statusword = sw as u16;
            }
        }
        while let Ok(t) = self.tpdo2.try_recv() {
            if let [PdoValue::Signed(p), PdoValue::Signed(v)] = t.values[..] {
                self.position = p as i32;
                self.velocity = v as i32;
            }
        }
    }

    /// The controlword by RPDO1.
    fn controlword(&mut self, cw: u16) -> Result<(), DemoError> {
        let (bus, cob_id) = (self.m.bus().clone(), 0x200 + u16::from(self.id));
        let mapping = self.rpdo1;
        let sent =
            self.m.run(async move { bus.send_pdo(cob_id, &mapping, &[PdoValue::Unsigned(u64::from(cw))]).await });
        sdo("RPDO1", sent)?;
        self.m.advance(1000);
        self.pdos();
        Ok(())
    }

    /// Waits (watching the TPDOs) until `statusword & mask == value`.
    fn wait_sw(&mut self, mask: u16, value: u16, timeout_s: f64, what: &str) -> Result<(), DemoError> {
        let end = self.m.now() + (timeout_s * 1e6) as Micros;
        loop {
            self.pdos();
            if self.statusword & mask == value {
                return Ok(());
            }
            if self.m.now() >= end {
                return Err(DemoError::Timeout(format!(
                    "{what}: statusword {:#06X} after {timeout_s} s",
                    self.statusword
                )));
            }
            self.m.advance(1000);
        }
    }

    fn go_to_state(&mut self, cw: u16, want: State) -> Result<(), DemoError> {
        self.controlword(cw)?;
        self.wait_sw(0x6F, want.statusword_bits() & 0x6F, 1.0, state_name(want.statusword_bits()))?;
        let sw = self.statusword;
        self.log(&format!("controlword {cw:#06X} (RPDO1) -> statusword {sw:#06X} (TPDO1): {}", state_name(sw)))
    }

    /// Runs one SDO call of the master on the drive.
    fn call<T>(
        &mut self,
        what: &str,
        f: impl AsyncFnOnce(MasterNode) -> Result<T, MasterError>,
    ) -> Result<T, DemoError> {
        let node = self.node.clone();
        let r = self.m.run(f(node));
        sdo(what, r)
    }

    fn read_bytes(&mut self, what: &str, index: u16, sub: u8) -> Result<Vec<u8>, DemoError> {
        self.call(what, async |n| n.read_bytes(index, sub).await)
    }

    fn read_u32(&mut self, what: &str, index: u16, sub: u8) -> Result<u32, DemoError> {
        self.call(what, async |n| n.read::<u32>(index, sub).await)
    }

    fn write_bytes(&mut self, what: &str, index: u16, sub: u8, data: &[u8]) -> Result<(), DemoError> {
        self.call(what, async |n| n.write_bytes(index, sub, data).await)
    }

    fn set_mode(&mut self, mode: i8) -> Result<(), DemoError> {
        self.call("6060h", async |n| Axis::new(n).set_mode(mode).await)
    }

    fn deg(&self) -> f64 {
        self.physical(Dimension::Position, i64::from(self.position))
    }

    fn rpm(&self) -> f64 {
        self.physical(Dimension::Velocity, i64::from(self.velocity))
    }
}

/// Runs the demo, writing the log to `out`.
pub fn run(options: &DemoOptions, out: &mut dyn Write) -> Result<DemoReport, DemoError> {
    if options.device != DeviceKind::Drvi {
        return Err(DemoError::Unsupported(options.device));
    }
    let wall = Instant::now();
    let id = options.node_id;
    let apps = DeviceApps::with_trace(2000);
    // The demo homes on the proximity: the DRVI on an actuator, not the bare motor it starts
    // with.
    apps.set_machine(super::machine::preset(DeviceKind::Drvi, "drvi-actuator"));
    let mut sim = Sim::new();
    let node = DeviceKind::Drvi
        .build(&NodeConfig { node_id: Some(id), ..NodeConfig::default() }, &apps)
        .map_err(|e| DemoError::Setup(e.to_string()))?;
    sim.add(node);
    let mut m = VirtualBus::new(sim, od_master::Config::default())?;
    m.advance(1000);
    let bootup = m.take_id(0x700 + u32::from(id));
    let node = sdo("node id", m.bus().node(id))?;
    let field =
        |index: u16, bits: u8, data_type: DataType| PdoField { entry: MapEntry { index, sub: 0, bits }, data_type };
    let mapping = |dir: Direction, fields: &[PdoField]| {
        PdoMapping::from_fields(dir, fields).map_err(|e| DemoError::Setup(format!("PDO mapping: {e:?}")))
    };
    let tpdo1_map = mapping(Direction::Transmit, &[field(0x6041, 16, DataType::Unsigned16)])?;
    let tpdo2_map = mapping(
        Direction::Transmit,
        &[field(0x6064, 32, DataType::Integer32), field(0x606C, 32, DataType::Integer32)],
    )?;
    let rpdo1 = mapping(Direction::Receive, &[field(0x6040, 16, DataType::Unsigned16)])?;
    let bus = m.bus().clone();
    let (cob1, cob2) = (0x180 + u16::from(id), 0x280 + u16::from(id));
    let tpdo1 = sdo("TPDO1", m.run(bus.tpdo(cob1, tpdo1_map, 1024)))?;
    let tpdo2 = sdo("TPDO2", m.run(bus.tpdo(cob2, tpdo2_map, 1024)))?;
    let mut d = Demo {
        m,
        node,
        tpdo1,
        tpdo2,
        rpdo1,
        id,
        out,
        units: Units::from_dictionary(&Dictionary::new(id)).map_err(|e| DemoError::Setup(format!("{e:?}")))?,
        statusword: 0,
        position: 0,
        velocity: 0,
    };
    writeln!(d.out, "drive-sim demo: a simulated Camozzi DRVI (node {id}) on an in-memory CAN bus, virtual clock")?;
    d.log(&format!("boot-up message 0x{:03X} {:02X?}", 0x700 + u32::from(id), bootup.first().map(|s| s.frame.data())))?;

    // Who is there (segmented upload for the name).
    let name = d.read_bytes("1008h", 0x1008, 0)?;
    let vendor = d.read_u32("1018h sub 1", 0x1018, 1)?;
    let device_type = d.read_u32("1000h", 0x1000, 0)?;
    d.log(&format!(
        "SDO: device name \"{}\", vendor id {vendor:#X}, device type {device_type:#010X} (CiA 402)",
        String::from_utf8_lossy(&name)
    ))?;

    // The master's copy of the unit configuration: 2014h, 2001h, 6091h and 6092h as the drive
    // has them.
    let mut mirror = Dictionary::new(id);
    for (index, sub) in [(0x2014u16, 0u8), (0x2001, 1), (0x2001, 2), (0x6091, 1), (0x6091, 2), (0x6092, 1), (0x6092, 2)]
    {
        let v = d.read_bytes("unit configuration", index, sub)?;
        let _ = mirror.write(index, sub, &v);
    }
    d.units = Units::from_dictionary(&mirror).map_err(|e| DemoError::Setup(format!("units: {e:?}")))?;
    d.log(&format!(
        "units ({}): position {}, velocity {}, acceleration {} per raw unit x{} / x{} / x{}",
        d.units.system().name(),
        d.units.unit(Dimension::Position).map_or("?", Unit::symbol),
        d.units.unit(Dimension::Velocity).map_or("?", Unit::symbol),
        d.units.unit(Dimension::Acceleration).map_or("?", Unit::symbol),
        d.units.factor(Dimension::Position).map_or(f64::NAN, |r| r.to_f64()),
        d.units.factor(Dimension::Velocity).map_or(f64::NAN, |r| r.to_f64()),
        d.units.factor(Dimension::Acceleration).map_or(f64::NAN, |r| r.to_f64()),
    ))?;

    // TPDO2: position and velocity every 50 ms (the CiA 301 remapping sequence).
    let cob2 = 0x280 + u32::from(id);
    let steps: [(&str, u16, u8, Vec<u8>); 8] = [
        ("disable TPDO2", 0x1801, 1, (cob2 | 0x8000_0000).to_le_bytes().to_vec()),
        ("clear its mapping", 0x1A01, 0, vec![0]),
        ("map 6064h", 0x1A01, 1, 0x6064_0020u32.to_le_bytes().to_vec()),
        ("map 606Ch", 0x1A01, 2, 0x606C_0020u32.to_le_bytes().to_vec()),
        ("two entries", 0x1A01, 0, vec![2]),
        ("inhibit time 50 ms", 0x1801, 3, 500u16.to_le_bytes().to_vec()),
        ("event timer 50 ms", 0x1801, 5, 50u16.to_le_bytes().to_vec()),
        ("enable TPDO2", 0x1801, 1, cob2.to_le_bytes().to_vec()),
    ];
    for (what, index, sub, data) in steps {
        d.write_bytes(what, index, sub, &data)?;
    }
    d.log(&format!("TPDO2 0x{cob2:03X} mapped to 6064h + 606Ch, at most and at least every 50 ms; TPDO1 0x{:03X} = 6041h; RPDO1 0x{:03X} = 6040h", 0x180 + u32::from(id), 0x200 + u32::from(id)))?;

    d.call("NMT start", async |n| n.start().await)?;
    d.m.advance(2000);
    d.pdos();
    d.log(&format!("NMT start -> operational; statusword {:#06X}: {}", d.statusword, state_name(d.statusword)))?;

    d.go_to_state(0x06, State::ReadyToSwitchOn)?;
    d.go_to_state(0x07, State::SwitchedOn)?;
    d.go_to_state(0x0F, State::OperationEnabled)?;

    // Homing 18: the home proximity in the positive direction, offset 0.
    let fast = d.raw(Dimension::Velocity, 30, Unit::Rpm)?;
    let slow = d.raw(Dimension::Velocity, 5, Unit::Rpm)?;
    let acc = d.raw(Dimension::Acceleration, 200, Unit::RpmPerSecond)?;
    d.write_bytes("6098h", 0x6098, 0, &[18])?;
    d.write_bytes("6099h sub 1", 0x6099, 1, &(fast as u32).to_le_bytes())?;
    d.write_bytes("6099h sub 2", 0x6099, 2, &(slow as u32).to_le_bytes())?;
    d.write_bytes("609Ah", 0x609A, 0, &(acc as u32).to_le_bytes())?;
    d.write_bytes("607Ch", 0x607C, 0, &0i32.to_le_bytes())?;
    d.set_mode(6)?;
    d.log(&format!(
        "homing: method 18 (proximity, positive), 30 rpm search = {fast}, 5 rpm out = {slow}, 200 rpm/s = {acc} raw"
    ))?;
    d.controlword(0x1F)?;
    d.log("controlword 0x001F: homing started")?;
    let start = d.m.now();
    let mut next_log = start;
    loop {
        d.pdos();
        if d.statusword & 0x3400 == 0x1400 {
            break;
        }
        if d.statusword & 0x2000 != 0 {
            return Err(DemoError::Timeout(format!("homing error, statusword {:#06X}", d.statusword)));
        }
        if d.m.now() >= start + 30_000_000 {
            return Err(DemoError::Timeout("homing did not complete in 30 s".into()));
        }
        if d.m.now() >= next_log {
            next_log += 500_000;
            let (p, v) = (d.deg(), d.rpm());
            d.log(&format!("  homing: position {p:>8.2} deg, velocity {v:>7.2} rpm"))?;
        }
        d.m.advance(1000);
    }
    d.controlword(0x0F)?;
    let homed = d.read_bytes("2004h", 0x2004, 0)?.iter().rev().fold(0u64, |v, b| v << 8 | u64::from(*b));
    let p = d.call("6064h", async |n| n.read::<i32>(0x6064, 0).await)?;
    let homed_at_deg = d.physical(Dimension::Position, i64::from(p));
    d.log(&format!(
        "homing completed (statusword {:#06X}, 2004h = {homed}): position {homed_at_deg:.2} deg",
        d.statusword
    ))?;
    // One TPDO2 period (50 ms), so the position the master holds is the one after the homing.
    d.m.advance(60_000);
    d.pdos();

    // Profile position: absolute target in degrees, 60 rpm, 60 rpm/s (the manual's Figure 4.2).
    let target = d.raw(Dimension::Position, options.target_deg, Unit::Degree)?;
    let v = d.raw(Dimension::Velocity, 60, Unit::Rpm)?;
    let a = d.raw(Dimension::Acceleration, 60, Unit::RpmPerSecond)?;
    d.set_mode(1)?;
    d.write_bytes("6081h", 0x6081, 0, &(v as u32).to_le_bytes())?;
    d.write_bytes("6083h", 0x6083, 0, &(a as u32).to_le_bytes())?;
    d.write_bytes("6084h", 0x6084, 0, &(a as u32).to_le_bytes())?;
    d.write_bytes("607Ah", 0x607A, 0, &(target as i32).to_le_bytes())?;
    d.log(&format!(
        "profile position: target {} deg = {target} raw, 60 rpm = {v}, 60 rpm/s = {a} raw",
        options.target_deg
    ))?;
    d.controlword(0x1F)?;
    d.wait_sw(0x1000, 0x1000, 1.0, "set-point acknowledge")?;
    d.log(&format!("new set-point (bit 4): acknowledged, statusword {:#06X}", d.statusword))?;
    d.controlword(0x0F)?;
    let start = d.m.now();
    let mut next_log = start;
    loop {
        d.pdos();
        if d.statusword & 0x0400 != 0 && d.m.now() > start + 10_000 {
            break;
        }
        if d.m.now() >= start + 60_000_000 {
            return Err(DemoError::Timeout("the move did not end in 60 s".into()));
        }
        if d.m.now() >= next_log {
            next_log += 500_000;
            let (p, v) = (d.deg(), d.rpm());
            d.log(&format!("  moving: position {p:>8.2} deg, velocity {v:>7.2} rpm"))?;
        }
        d.m.advance(1000);
    }
    d.m.advance(100_000);
    d.pdos();
    let final_deg = d.deg();
    let duration = (d.m.now() - start) as f64 * 1e-6;
    d.log(&format!(
        "target reached (statusword {:#06X}): position {final_deg:.2} deg (TPDO2), move took about {duration:.2} s",
        d.statusword
    ))?;
    d.go_to_state(0x06, State::ReadyToSwitchOn)?;

    let trace = apps.traces().first().and_then(|(_, t)| t.lock().ok().map(|t| t.clone())).unwrap_or_default();
    let report = DemoReport {
        virtual_us: d.m.now(),
        wall_s: wall.elapsed().as_secs_f64(),
        frames_sent: d.m.frames_on_bus() - d.m.frames_received(),
        frames_received: d.m.frames_received(),
        homed_at_deg,
        final_deg,
        trace,
    };
    let mut summary = String::new();
    let _ = write!(
        summary,
        "done: {:.3} s of virtual time in {:.3} s of wall time; {} frames sent by the master, {} received; {} trace samples",
        report.virtual_us as f64 * 1e-6,
        report.wall_s,
        report.frames_sent,
        report.frames_received,
        report.trace.samples().len()
    );
    writeln!(d.out, "{summary}")?;
    if let Some(path) = &options.trace {
        write_file(path, &report.trace.to_csv())?;
        writeln!(d.out, "trace: {}", path.display())?;
    }
    if let Some(path) = &options.plot {
        let title = format!(
            "Camozzi DRVI: homing (method 18), then an absolute move to {} deg at 60 rpm, 60 rpm/s",
            options.target_deg
        );
        write_file(path, &report.trace.to_svg(&plot_options(&d.units, &title)))?;
        writeln!(d.out, "plot: {}", path.display())?;
    }
    Ok(report)
}

/// Plot labels and scales for the DRVI's active unit system.
pub fn plot_options(units: &Units, title: &str) -> PlotOptions {
    let q = |label: &str, d: Dimension| PlotQuantity {
        label: label.to_owned(),
        unit: units.unit(d).map_or("raw", Unit::symbol).to_owned(),
        scale: units.factor(d).map_or(1.0, |r| r.to_f64()),
    };
    PlotOptions {
        title: title.to_owned(),
        position: q("Position", Dimension::Position),
        velocity: q("Velocity", Dimension::Velocity),
        torque: q("Current", Dimension::Torque),
        ..PlotOptions::default()
    }
}

fn write_file(path: &std::path::Path, text: &str) -> Result<(), DemoError> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir)?;
    }
    std::fs::write(path, text)?;
    Ok(())
}

/// Plot labels and scales for a node of `kind` as its dictionary is configured now (physical
/// units where the device's generated `units` module gives them, raw values otherwise).
pub fn plot_options_for(kind: DeviceKind, node: &dyn crate::node::AnyNode, title: &str) -> PlotOptions {
    type DrviNode = crate::node::Node<Dictionary, Box<dyn crate::node::DriveApp<Dictionary> + Send>>;
    match kind {
        DeviceKind::Drvi => match node.as_any().downcast_ref::<DrviNode>().map(|n| Units::from_dictionary(n.od())) {
            Some(Ok(units)) => plot_options(&units, title),
            _ => PlotOptions { title: title.to_owned(), ..PlotOptions::default() },
        },
        _ => PlotOptions { title: title.to_owned(), ..PlotOptions::default() },
    }
}
