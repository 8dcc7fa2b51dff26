//! `od-master`: a CANopen master on the command line. Scan a bus, read and write objects,
//! send NMT commands, boot a network from its description, watch the traffic in words, and drive a CiA 402 axis.
//!
//! Exit codes: 0 ok, 1 an SDO abort, a timeout or a failed drive operation (one line naming
//! the node and the object), 2 bad usage or a bus that cannot be opened.

mod cli;
mod top;

use std::collections::BTreeMap;
use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Duration;

use clap::{Parser, Subcommand};
use od_master::{Axis, Bus, Config, Homing, Move, NmtCommand, SdoOptions};
use od_sidecar::Dimension;
use serde_json::json;

use cli::decode::decode;
use cli::device::Device;
use cli::object::{Target, resolve};
use cli::value::{encode, encode_typed, show};

/// A CANopen master on the command line.
#[derive(Parser, Debug)]
#[command(name = "od-master", version, about, after_help = AFTER_HELP)]
struct Args {
    /// The bus: socketcand://HOST:PORT/CHANNEL, socketcan://IFACE (Linux), slcan://PORT?bitrate=500000
    /// (a CANable, USBtin or Lawicel serial adapter: /dev/ttyACM0, COM4, /dev/cu.usbmodem...) or
    /// mem://NAME.
    #[arg(long, global = true, value_name = "ADDR")]
    bus: Option<String>,
    /// A device description: FILE for the node the command names, NODE=FILE for one node
    /// (repeatable). Lets objects be named as the generated code names them, values be typed,
    /// and `monitor` decode PDOs and EMCY texts (from the sidecar FILE.toml beside it).
    #[arg(long, global = true, value_name = "[NODE=]FILE")]
    eds: Vec<String>,
    /// One JSON object a line (read, write, scan, monitor, boot, axis).
    #[arg(long, global = true)]
    json: bool,
    /// How long to wait for each SDO answer, in milliseconds.
    #[arg(long, global = true, default_value_t = 1000, value_name = "MS")]
    timeout: u64,
    /// SDO transfer mode for read and write: normal (expedited or segmented), segmented, block
    /// (with a server that has no block transfer, the same transfer runs as a normal one).
    #[arg(long, global = true, default_value = "normal", value_parser = ["normal", "segmented", "block"])]
    sdo_mode: String,
    /// The largest value a read accepts, in bytes.
    #[arg(long, global = true, default_value_t = 1 << 20, value_name = "BYTES")]
    max_len: usize,
    #[command(subcommand)]
    command: Cmd,
}

const AFTER_HELP: &str = "\
Objects: 6041h, 0x6041, 1018h:1, 0x1018:1, or with --eds a name as the generated code gives it
(statusword, identity_object.vendor_id).
Values for write: by the entry's type with --eds (numbers in decimal or 0x hex, strings as text,
DOMAIN and OCTET_STRING as hex); without --eds typed: u8: u16: u32: u64: i8: i16: i32: i64: f32:
f64: bool: str: hex: (u16:1234, i32:-5, str:abc, hex:0102).
Exit codes: 0 ok, 1 an SDO abort or timeout or failed drive operation, 2 bad usage or bus.";

#[derive(Subcommand, Debug)]
enum Cmd {
    /// The nodes that answer, with their identity (1018h) and name (1008h).
    Scan {
        /// The highest node id asked.
        #[arg(long, default_value_t = 127)]
        last: u8,
        /// Times a node's first read (1000h) is asked again after no answer within --timeout:
        /// a node that missed one request on a busy or lossy bus is still found.
        #[arg(long, default_value_t = 1)]
        retries: u8,
    },
    /// Reads an object.
    Read {
        /// Node id (1..=127).
        node: u8,
        /// The object.
        object: String,
    },
    /// Writes an object.
    Write {
        /// Node id (1..=127).
        node: u8,
        /// The object.
        object: String,
        /// The value.
        #[arg(allow_hyphen_values = true)]
        value: String,
    },
    /// Sends an NMT command to a node or all.
    Nmt {
        /// start, stop, preop, reset or reset-comm.
        #[arg(value_parser = ["start", "stop", "preop", "reset", "reset-comm"])]
        command: String,
        /// Node id or `all`.
        node: String,
    },
    /// Prints the frames on the bus in words, until stopped (or after --count frames or
    /// --duration seconds).
    Monitor {
        /// Stop after this many frames.
        #[arg(long)]
        count: Option<u64>,
        /// Stop after this many seconds.
        #[arg(long)]
        duration: Option<f64>,
    },
    /// Boots a network (CiA 302-2): checks each node's identity (1000h, 1018h), writes what
    /// differs from its defaults, maps its PDOs, and starts the nodes.
    Boot {
        /// A network description (networks/*.toml), or one DCF per node.
        #[arg(required = true, value_name = "FILE")]
        files: Vec<PathBuf>,
        /// Print what would be checked and written, without a bus.
        #[arg(long)]
        plan: bool,
        /// Leave the nodes pre-operational.
        #[arg(long)]
        no_start: bool,
        /// Boot the nodes one after another instead of at the same time.
        #[arg(long)]
        sequential: bool,
        /// The LSS step timeout (ms) for the nodes the description marks `lss = true`.
        #[arg(long, value_name = "MS", default_value_t = 20)]
        lss_step_timeout: u64,
    },
    /// Commissioning with LSS (CiA 305): scan, set-id, set-bitrate, store, inquire,
    /// unconfigure-all, assign.
    Lss(cli::lss::LssArgs),
    /// Boots a network, then keeps it running until Ctrl-C: nodes that reboot are configured
    /// again, lost heartbeats handled by each node's policy (the description's
    /// `[nodes.NAME.supervision]`), one line per event. Exit code 1 when a mandatory node
    /// cannot be booted (after its policy ran).
    Run {
        /// A network description (networks/*.toml), or one DCF per node.
        #[arg(required = true, value_name = "FILE")]
        files: Vec<PathBuf>,
        /// The master's DCF: its 1F80h and 1F81h (CiA 302-2) set the supervision.
        #[arg(long, value_name = "DCF")]
        master_dcf: Option<PathBuf>,
    },
    /// A live full-screen view of the network: its nodes (NMT state, heartbeat, last EMCY,
    /// CiA 402 state, mode, position, velocity), its events and its frames in words, an object
    /// browser (o) and plots of any values, several at once (g). q quits.
    Top {
        /// A network description (networks/*.toml) or one DCF per node: its nodes are listed
        /// from the start under their names, with their device files, sidecars and configured
        /// PDOs (--eds NODE=FILE adds nodes or replaces one's file).
        #[arg(value_name = "NETWORK")]
        files: Vec<PathBuf>,
        /// Let the object browser write (each write confirmed); read-only without it.
        #[arg(long)]
        allow_writes: bool,
        /// How often a drive's statusword, mode, position and velocity (when no TPDO carries
        /// them) and the entries picked for a plot are read by SDO, in milliseconds; 0: never
        /// (leaves the SDO channels to another master).
        #[arg(long, default_value_t = 200, value_name = "MS")]
        poll_ms: u64,
    },
    /// Drives a CiA 402 axis.
    Axis {
        /// Node id (1..=127).
        node: u8,
        #[command(subcommand)]
        action: AxisCmd,
    },
}

#[derive(Subcommand, Debug)]
enum AxisCmd {
    /// To Operation enabled.
    Enable,
    /// Homing (with the drive's method, or --method).
    Home {
        /// Homing method (6098h).
        #[arg(long, allow_hyphen_values = true)]
        method: Option<i8>,
    },
    /// Profile position move to a target, waiting until it is reached.
    Move {
        /// Target position: raw units, or with the unit of the drive's sidecar (`90deg`,
        /// `12.5mm`; needs --eds).
        #[arg(long, allow_hyphen_values = true)]
        to: String,
        /// Relative to the current target.
        #[arg(long)]
        relative: bool,
        /// Profile velocity (6081h), raw units; unset: the drive's own (a move with 0 is
        /// refused before it starts).
        #[arg(long)]
        velocity: Option<u32>,
        /// Profile acceleration and deceleration (6083h, 6084h), raw units.
        #[arg(long)]
        acceleration: Option<u32>,
        /// How long the move may take, in seconds.
        #[arg(long, default_value_t = 30.0)]
        within: f64,
    },
    /// Profile velocity (raw units); it keeps running.
    Velocity {
        /// Target velocity: raw units, or with the unit of the drive's sidecar (`60rpm`,
        /// `10mm/s`; needs --eds).
        #[arg(allow_hyphen_values = true)]
        value: String,
    },
}

/// A failure: its exit code and its one line.
struct Fail(u8, String);

fn usage(msg: impl Into<String>) -> Fail {
    Fail(2, msg.into())
}

fn main() -> ExitCode {
    let args = Args::parse();
    let runtime = match tokio::runtime::Builder::new_current_thread().enable_all().build() {
        Ok(r) => r,
        Err(e) => {
            eprintln!("od-master: cannot start the runtime: {e}");
            return ExitCode::from(2);
        }
    };
    match runtime.block_on(run(args)) {
        Ok(()) => ExitCode::SUCCESS,
        Err(Fail(code, msg)) => {
            eprintln!("od-master: {msg}");
            ExitCode::from(code)
        }
    }
}

/// The devices given with --eds: by node, and the one without a node.
struct Devices {
    by_node: BTreeMap<u8, Device>,
    default: Option<Device>,
}

impl Devices {
    fn load(specs: &[String]) -> Result<Self, Fail> {
        let mut by_node = BTreeMap::new();
        let mut default = None;
        for spec in specs {
            match spec.split_once('=') {
                Some((node, file)) if node.chars().all(|c| c.is_ascii_digit()) => {
                    let node = node_id(node)?;
                    by_node.insert(node, Device::load(&PathBuf::from(file)).map_err(usage)?);
                }
                _ => {
                    if default.is_some() {
                        return Err(usage("--eds FILE given twice: name the nodes with --eds NODE=FILE"));
                    }
                    default = Some(Device::load(&PathBuf::from(spec)).map_err(usage)?);
                }
            }
        }
        Ok(Self { by_node, default })
    }

    fn for_node(&self, node: u8) -> Option<&Device> {
        self.by_node.get(&node).or(self.default.as_ref())
    }
}

fn node_id(text: &str) -> Result<u8, Fail> {
    match text.parse::<u8>() {
        Ok(n @ 1..=127) => Ok(n),
        _ => Err(usage(format!("`{text}` is not a node id (1..=127)"))),
    }
}

fn target(object: &str, device: Option<&Device>) -> Result<Target, Fail> {
    resolve(object, device.map(|d| (&d.names, &d.model))).map_err(|e| usage(e.to_string()))
}

fn seconds(s: f64) -> Result<Duration, Fail> {
    if s.is_finite() && s >= 0.0 {
        Ok(Duration::from_secs_f64(s.min(1e9)))
    } else {
        Err(usage(format!("{s} is not a number of seconds")))
    }
}

fn print_json(value: &serde_json::Value) {
    let mut out = std::io::stdout().lock();
    let _ = writeln!(out, "{value}");
}

async fn run(args: Args) -> Result<(), Fail> {
    // `boot`: the network is read (and a plan printed) before any bus is opened.
    let network = match &args.command {
        Cmd::Boot { files, plan, .. } => {
            let network = cli::boot::load(files).map_err(usage)?;
            if *plan {
                cli::boot::print_plan(&network, args.json);
                return Ok(());
            }
            Some(network)
        }
        Cmd::Run { files, master_dcf } => {
            let mut network = cli::boot::load(files).map_err(usage)?;
            if let Some(dcf) = master_dcf {
                network.apply_master_dcf(dcf).map_err(|e| usage(e.to_string()))?;
            }
            Some(network)
        }
        Cmd::Top { files, .. } if !files.is_empty() => Some(cli::boot::load(files).map_err(usage)?),
        _ => None,
    };
    let Some(addr) = args.bus.clone() else { return Err(usage("--bus ADDR is required")) };
    let devices = Devices::load(&args.eds)?;
    let mode = match args.sdo_mode.as_str() {
        "segmented" => od_master::Mode::Segmented,
        "block" => od_master::Mode::Block,
        _ => od_master::Mode::Normal,
    };
    let sdo = SdoOptions {
        timeout: Duration::from_millis(args.timeout),
        retries: 0,
        mode,
        max_len: args.max_len,
        ..SdoOptions::default()
    };
    let config = Config { sdo, ..Config::default() };
    let bus = Bus::open(&addr, config).await.map_err(|e| usage(format!("cannot open the bus {addr}: {e}")))?;
    let fail = |e: od_master::Error| Fail(1, e.to_string());
    match args.command {
        Cmd::Read { node, object } => {
            let node = node_id(&node.to_string())?;
            let device = devices.for_node(node);
            let t = target(&object, device)?;
            if let Some(why) = t.not_readable() {
                return Err(usage(why));
            }
            let bytes = bus.node(node).map_err(fail)?.read_bytes(t.index, t.sub).await.map_err(fail)?;
            let shown = show(&bytes, t.data_type, t.index, t.sub);
            if args.json {
                print_json(&json!({
                    "node": node, "index": t.index, "subindex": t.sub, "name": t.name,
                    "value": shown.json(), "raw": cli::value::hex(&bytes),
                }));
            } else {
                println!("{}", shown.text());
            }
        }
        Cmd::Write { node, object, value } => {
            let node = node_id(&node.to_string())?;
            let device = devices.for_node(node);
            let t = target(&object, device)?;
            if let Some(why) = t.not_writable() {
                return Err(usage(why));
            }
            let bytes = match t.data_type {
                Some(dt) => encode(&value, dt),
                None => encode_typed(&value),
            }
            .map_err(|e| usage(e.to_string()))?;
            bus.node(node).map_err(fail)?.write_bytes(t.index, t.sub, &bytes).await.map_err(fail)?;
            if args.json {
                print_json(
                    &json!({ "node": node, "index": t.index, "subindex": t.sub, "name": t.name, "written": cli::value::hex(&bytes) }),
                );
            }
        }
        Cmd::Nmt { command, node } => {
            let cmd = match command.as_str() {
                "start" => NmtCommand::Start,
                "stop" => NmtCommand::Stop,
                "preop" => NmtCommand::EnterPreOperational,
                "reset" => NmtCommand::ResetNode,
                _ => NmtCommand::ResetCommunication,
            };
            let target = if node == "all" {
                od_master::Target::All
            } else {
                let id = node_id(&node)?;
                od_master::Target::Node(od_master::NodeId::new(id).ok_or_else(|| usage("bad node id"))?)
            };
            bus.nmt(cmd, target).await.map_err(fail)?;
        }
        Cmd::Boot { no_start, sequential, lss_step_timeout, .. } => {
            let options = od_master::BootOptions {
                start: !no_start,
                concurrent: !sequential,
                lss_step_timeout: Duration::from_millis(lss_step_timeout.max(1)),
            };
            let network = network.unwrap_or_default();
            if !cli::boot::run(&bus, &network, &options, args.json).await {
                return Err(Fail(1, "the network did not boot: see the nodes above".to_owned()));
            }
        }
        Cmd::Lss(lss) => {
            let eds = devices.default.as_ref().map(|d| &d.model);
            cli::lss::run(&bus, lss, eds, args.json).await.map_err(|(code, msg)| Fail(code, msg))?;
        }
        Cmd::Scan { last, retries } => scan(&bus, last.clamp(1, 127), args.json, args.timeout, retries).await?,
        Cmd::Run { .. } => {
            let network = network.unwrap_or_default();
            cli::run::run(bus.clone(), network, args.json).await.map_err(|e| Fail(1, e))?;
        }
        Cmd::Monitor { count, duration } => monitor(&bus, &devices, count, duration, args.json).await?,
        Cmd::Top { allow_writes, poll_ms, .. } => {
            let poll = (poll_ms > 0).then(|| Duration::from_millis(poll_ms.max(20)));
            let network = network.unwrap_or_default();
            top::run(&bus, &addr, &args.eds, &network, allow_writes, poll).await.map_err(|e| Fail(1, e))?
        }
        Cmd::Axis { node, action } => {
            let node = node_id(&node.to_string())?;
            let mut axis = Axis::new(bus.node(node).map_err(fail)?);
            let device = devices.for_node(node);
            // The drive's own warning register (and its limit bits), the modes it runs beside
            // 6502h and the EMCY texts, from its sidecar.
            if let Some(sidecar) = device.and_then(|d| d.sidecar.as_ref()) {
                axis = axis.with_sidecar(sidecar);
                bus.set_emcy_texts(node, od_master::EmcyTexts::from_sidecar(sidecar)).await.map_err(fail)?;
            }
            match action {
                AxisCmd::Enable => {
                    axis.enable().await.map_err(fail)?;
                    if args.json {
                        print_json(&json!({ "node": node, "state": "Operation enabled" }));
                    }
                }
                AxisCmd::Home { method } => {
                    let method = match method {
                        Some(m) => m,
                        None => axis.node().read::<i8>(0x6098, 0).await.map_err(fail)?,
                    };
                    let pos = axis.home(&Homing::method(method)).await.map_err(fail)?;
                    if args.json {
                        print_json(&json!({ "node": node, "homed": true, "method": method, "position": pos }));
                    } else {
                        println!("homed (method {method}), position {pos}");
                    }
                }
                AxisCmd::Move { to, relative, velocity, acceleration, within } => {
                    let timeout = seconds(within)?;
                    let m = Move {
                        relative,
                        velocity,
                        acceleration,
                        deceleration: acceleration,
                        timeout,
                        ..Move::default()
                    };
                    let to = axis_value(&axis, device, &to, Dimension::Position).await?;
                    let pos = axis.move_to(to, &m).await.map_err(fail)?;
                    if args.json {
                        print_json(&json!({ "node": node, "target": to, "position": pos }));
                    } else {
                        println!("position {pos}");
                    }
                }
                AxisCmd::Velocity { value } => {
                    let value = axis_value(&axis, device, &value, Dimension::Velocity).await?;
                    axis.run_velocity(value, None, None).await.map_err(fail)?;
                    if args.json {
                        print_json(&json!({ "node": node, "velocity": value }));
                    }
                }
            }
        }
    }
    Ok(())
}

/// An axis value: raw units, or a number with the unit the drive's sidecar gives (read the
/// device's unit configuration first).
async fn axis_value(axis: &Axis, device: Option<&Device>, text: &str, dim: Dimension) -> Result<i32, Fail> {
    let Some((number, unit)) = cli::units::split(text) else {
        return text.trim().parse().map_err(|_| usage(format!("`{text}` is not a value (raw units, or e.g. 90deg)")));
    };
    let Some(sidecar) = device.and_then(|d| d.sidecar.as_ref()) else {
        return Err(usage(format!("`{text}`: units need --eds with the device's sidecar (FILE.toml beside it)")));
    };
    let mut values = BTreeMap::new();
    for o in cli::units::objects(sidecar) {
        let bytes = axis.node().read_bytes(o.index, o.sub_or_zero()).await.map_err(|e| Fail(1, e.to_string()))?;
        let mut le = [0u8; 8];
        le[..bytes.len().min(8)].copy_from_slice(&bytes[..bytes.len().min(8)]);
        values.insert(o, i64::from_le_bytes(le));
    }
    cli::units::to_raw(number, unit, dim, sidecar, &values).map_err(usage)
}

/// Every node asked at once, each with `timeout` per answer and its first read retried
/// `retries` times; the others (identity, name) once, the node having answered.
async fn scan(bus: &Bus, last: u8, json: bool, timeout: u64, retries: u8) -> Result<(), Fail> {
    let fail = |e: od_master::Error| Fail(1, e.to_string());
    let mut tasks = Vec::new();
    for id in 1..=last {
        let node = bus.node(id).map_err(fail)?.with_timeout(Duration::from_millis(timeout)).with_retries(0);
        let probe = node.clone().with_retries(retries);
        tasks.push(tokio::spawn(async move {
            let device_type = probe.read::<u32>(0x1000, 0).await.ok()?;
            let mut identity = [None; 4];
            for (sub, slot) in identity.iter_mut().enumerate() {
                *slot = node.read::<u32>(0x1018, sub as u8 + 1).await.ok();
            }
            let name = node.read_string(0x1008, 0).await.ok();
            Some((id, device_type, identity, name))
        }));
    }
    for task in tasks {
        let Ok(Some((id, device_type, [vendor, product, revision, serial], name))) = task.await else { continue };
        if json {
            print_json(&json!({
                "node": id, "device_type": device_type, "vendor_id": vendor, "product_code": product,
                "revision": revision, "serial": serial, "name": name,
            }));
        } else {
            let h = |v: Option<u32>| v.map_or("-".to_owned(), |v| format!("0x{v:08X}"));
            println!(
                "node {id:3}: {}  vendor {} product {} revision {} serial {}",
                name.as_deref().unwrap_or("(no name)"),
                h(vendor),
                h(product),
                h(revision),
                h(serial)
            );
        }
    }
    Ok(())
}

async fn monitor(
    bus: &Bus,
    devices: &Devices,
    count: Option<u64>,
    duration: Option<f64>,
    json: bool,
) -> Result<(), Fail> {
    let mut frames = bus.frames();
    let deadline = match duration {
        Some(s) => Some(tokio::time::Instant::now() + seconds(s)?),
        None => None,
    };
    let mut seen = 0u64;
    loop {
        if count.is_some_and(|c| seen >= c) {
            return Ok(());
        }
        let next = async {
            match deadline {
                Some(d) => tokio::time::timeout_at(d, frames.recv()).await.ok(),
                None => Some(frames.recv().await),
            }
        };
        let frame = match next.await {
            None => return Ok(()),
            Some(Ok(f)) => f,
            Some(Err(tokio::sync::broadcast::error::RecvError::Lagged(n))) => {
                eprintln!("od-master: {n} frames dropped (the output is slower than the bus)");
                continue;
            }
            Some(Err(tokio::sync::broadcast::error::RecvError::Closed)) => {
                return Err(Fail(1, "the bus closed".into()));
            }
        };
        seen += 1;
        let d = decode(frame.id(), frame.is_remote(), frame.data(), &devices.by_node);
        if json {
            print_json(&d.json);
        } else {
            println!("{}", d.text);
        }
    }
}
