//! `drive-sim`: the command-line front end of the simulated drives.
//!
//! ```text
//! drive-sim run --device drvi --node-id 2 [--dcf FILE] [--machine PRESET|FILE] [--device akd --node-id 3 ...]
//!               [--state-dir DIR] (--listen 127.0.0.1:0 | --bus socketcand://127.0.0.1:29536/can0)
//!               [--trace FILE.csv] [--plot FILE.svg] [--trace-interval-ms 5]
//!               [hub limits with --listen] [--reconnect-ms 100 with --bus]
//! drive-sim demo [--device drvi] [--plot demo.svg] [--trace demo.csv]   the main job, in process
//! drive-sim hub --listen 127.0.0.1:29536        socketcand-compatible hub (python-can connects to it)
//!               [--max-clients 1024] [--handshake-timeout-ms 5000] [--max-rate 20000] [--bitrate BITS_PER_S]
//!               [--channel can0 ...]   serve only these channels (another is refused)
//! drive-sim dump --bus socketcand://127.0.0.1:29536/can0 [--count N] [--timeout SECONDS]
//! drive-sim send --bus socketcand://127.0.0.1:29536/can0 601#4041600000000000 000#0100 ...
//! drive-sim slcan (--bus socketcand://127.0.0.1:29536/can0 | --device drvi --node-id 2 ...)
//!               [--firmware canable|lawicel] [--link PATH] [--no-wire]   a simulated slcan adapter
//! drive-sim fault --control /tmp/drives.sock 3 power-cycle [OFF_MS]   faults on demand (run --control)
//! ```
//!
//! `run` simulates devices: each `--device` starts a group that the following `--node-id`,
//! `--dcf` and `--machine` belong to. `--machine` names a preset or a TOML machine file
//! (`drive::motion::Machine`); without it the DRVI is a bare motor turning freely, the DRCS the
//! belt axis of its EDS defaults, the AKD an axis with limit and reference switches
//! (`drive::drives::machine`). With `--listen` it starts a hub there, puts the devices on its channel
//! (`--channel`, default `can0`) and prints `listening on ADDRESS`; with `--bus` the devices
//! join that bus and it prints `running on BUS`. The devices of one `run` share one connection
//! and one thread (`drive::node::run_group`, 1 ms timer resolution): each sees every frame on
//! the bus and every frame the others send, as on one CAN bus, and a frame wakes one thread
//! rather than one per device. `--connection-per-device` gives each its own connection and
//! thread, as separate CAN controllers (an emulated wire then arbitrates between them too).
//!
//! With `--trace`/`--plot`, `run` records each device's demand and actual values and writes them
//! when it stops (one device: the files as named; several: `-<device>-node<id>` before the
//! extension).
//!
//! `demo` runs the main job in process on the virtual clock: a DRVI on an in-memory bus, the
//! project's master (`od-master`) taking it through NMT, the CiA 402 state machine, homing and
//! an absolute move in physical units with real frames (`drive::drives::demo`), printing what
//! happened.
//!
//! Devices on `--bus` survive the bus: when their connection fails they keep their state and run
//! on, and reconnect with backoff. The hub limits (`hub`, `run --listen`) are described in
//! `od_bus::HubConfig`: a full hub makes room by closing the longest-idle client that
//! never sent a frame, a flooding client is slowed down, a slow reader loses frames (logged)
//! rather than its connection, and `--bitrate` emulates the wire. `dump` reports frames the hub
//! dropped for it.
//!
//! `hub` prints `listening on ADDRESS` on stdout once it accepts connections (so a script can
//! ask for port 0 and read the port chosen). Every subcommand logs to stderr, and `run` and
//! `hub` stop cleanly on SIGINT or SIGTERM (exit status 0; 1 if a device failed first).

use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use clap::{ArgMatches, Args, CommandFactory, FromArgMatches, Parser, Subcommand};
use drive::drives::demo::{self, DemoOptions};
use drive::drives::{DeviceApps, machine};
use drive::node::{AnyNode, Backoff, BusEvent, DeviceKind, MonotonicClock, NodeConfig};
use od_bus::{BusAddr, CanFrame, DEFAULT_CHANNEL, Endpoint, Hub, HubConfig, TransportError};

#[derive(Debug, Parser)]
#[command(name = "drive-sim", version, about = "Simulated CANopen drives and the buses to reach them")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

// (One value of this is made per run: the sizes of its variants do not matter.)
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Subcommand)]
enum Command {
    /// Simulate devices on a hub of their own (--listen) or on a bus (--bus).
    Run(RunArgs),
    /// Run a socketcand-compatible TCP hub: every channel a client opens is one CAN bus.
    Hub(HubArgs),
    /// Print the frames seen on a bus, one per line in cansend notation.
    Dump(DumpArgs),
    /// Put frames on a bus, given in cansend notation (601#2B40600006000000, 701#R).
    Send(SendArgs),
    /// The main job in process on the virtual clock: NMT, state machine, homing and an absolute
    /// move in physical units through real frames; prints what happened, writes plot and trace.
    Demo(DemoArgs),
    /// A simulated slcan adapter (a CANable, or a Lawicel CANUSB) on a pseudo-terminal: prints
    /// `slcan on PATH`; open PATH with od-master (--bus slcan://PATH), python-can's slcan
    /// interface or slcand. Its bus: a hub (--bus) or devices in this process (--device).
    Slcan(drive::slcan::SlcanArgs),
    /// Injects a fault into a device of a running `drive-sim run --control SOCKET`.
    #[command(long_about = FAULT_HELP)]
    Fault(FaultArgs),
}

const FAULT_HELP: &str = "Injects a fault into one device of a running `drive-sim run --control SOCKET`, to \
rehearse what a machine meets:

  power-cycle [OFF_MS]   power off for OFF_MS (default 10) ms, then on: the device boots again \
(boot-up message) with its stored parameters (1010h), forgetting its configuration
  silence MS             no heartbeat leaves the device for MS ms; it keeps running (a pulled \
cable, as the master sees it)
  fault [CODE] [sticky]  the drive goes to Fault with error code CODE (hex, default 5530h); with \
sticky the cause stays: it faults again after each fault reset, until `clear`
  clear                  the cause of a sticky fault is gone

The socket takes one line per command, `NODE COMMAND...`, and answers `ok` or `error: WHY` \
(so `echo '3 silence 2000' | socat - UNIX:/tmp/drives.sock` works too). A device killed with \
SIGKILL and started again is the other way to power-cycle one (with --state-dir it keeps what \
it saved).";

#[derive(Debug, Args)]
struct FaultArgs {
    /// The control socket of the running `drive-sim run --control SOCKET`.
    #[arg(long)]
    control: PathBuf,
    /// The device's node id.
    node: u8,
    /// The fault: power-cycle [OFF_MS] | silence MS | fault [CODE] [sticky] | clear.
    #[arg(required = true, num_args = 1.., allow_hyphen_values = true)]
    fault: Vec<String>,
}

#[derive(Debug, Args)]
struct DemoArgs {
    /// The device to demonstrate.
    #[arg(long, default_value = "drvi", value_parser = parse_kind)]
    device: DeviceKind,
    /// Its node id.
    #[arg(long, default_value_t = 2)]
    node_id: u8,
    /// Write the motion plot (SVG) here.
    #[arg(long)]
    plot: Option<PathBuf>,
    /// Write the motion trace (CSV) here.
    #[arg(long)]
    trace: Option<PathBuf>,
    /// Absolute target of the move, degrees.
    #[arg(long, default_value_t = 720, allow_hyphen_values = true)]
    target_deg: i64,
}

#[derive(Debug, Args)]
struct HubArgs {
    /// Address to listen on; port 0 picks a free port (printed on stdout).
    #[arg(long, default_value = "127.0.0.1:29536")]
    listen: String,
    /// Frames queued per client; a client that reads more slowly than the bus runs loses the
    /// frames beyond this (counted, logged once a second), not its connection.
    #[arg(long, default_value_t = HubConfig::default().client_queue)]
    queue: usize,
    #[command(flatten)]
    limits: HubLimits,
    /// Log only problems (no connect/disconnect lines).
    #[arg(long, short)]
    quiet: bool,
    /// Serve only this channel (repeat for several): a client opening another is refused, so a
    /// misspelt channel is an error, not an empty bus. Without it any channel is served, and one
    /// opened beside busy others is logged as a likely typo.
    #[arg(long = "channel")]
    channels: Vec<String>,
}

/// The hub's limits, shared by `hub` and `run --listen`.
#[derive(Debug, Args)]
#[command(next_help_heading = "Hub limits (hub, and run with --listen)")]
struct HubLimits {
    /// Connections served at once. When full, the connection idle longest among those that
    /// never sent a frame is closed to let a new one in; only if every client sends frames is
    /// the new one refused.
    #[arg(long, default_value_t = HubConfig::default().max_clients)]
    max_clients: usize,
    /// A connection must open a channel within this many milliseconds (the handshake).
    #[arg(long, default_value_t = HubConfig::default().open_timeout.as_millis() as u64)]
    handshake_timeout_ms: u64,
    /// Frames per second one client may send; a faster sender is slowed down (not
    /// disconnected), so a flood cannot starve the others. 0: no limit.
    #[arg(long, default_value_t = HubConfig::default().max_rate)]
    max_rate: u32,
    /// Emulate a CAN bus of this many bits per second (e.g. 1000000: about 8 to 9 thousand
    /// frames per second): a channel carries at most what such a bus carries, the lowest CAN
    /// id first when frames compete, and senders wait for the wire. Default: no limit.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1_000..=10_000_000))]
    bitrate: Option<u32>,
}

impl HubLimits {
    fn apply(&self, config: HubConfig) -> HubConfig {
        HubConfig {
            max_clients: self.max_clients,
            open_timeout: Duration::from_millis(self.handshake_timeout_ms),
            max_rate: self.max_rate,
            bitrate: self.bitrate,
            ..config
        }
    }
}

#[derive(Debug, Args)]
#[command(group(clap::ArgGroup::new("where").required(true).args(["listen", "bus"])))]
struct RunArgs {
    /// A device to simulate: drvi, drcs or akd. Repeat for several devices; the --node-id and
    /// --dcf after a --device belong to it.
    #[arg(long, required = true, value_parser = parse_kind)]
    device: Vec<DeviceKind>,
    /// Node id (1..=127) of the preceding --device; may be left out when its DCF names one.
    /// `none` (or 255): the device starts without one and waits for LSS (CiA 305).
    #[arg(long, value_parser = parse_node_id)]
    node_id: Vec<u8>,
    /// Serial number (1018h sub 4) of the preceding --device, instead of its EDS's: identical
    /// devices told apart over LSS. Its saved state is then kept under the serial number.
    #[arg(long)]
    serial: Vec<u32>,
    /// DCF whose ParameterValues the preceding --device applies at start and at every reset.
    #[arg(long)]
    dcf: Vec<PathBuf>,
    /// The machine around the preceding --device's motor: a preset or a TOML file (see
    /// --help for each device's default and presets).
    #[arg(long, value_name = "PRESET|FILE", long_help = drive::drives::machine::help())]
    machine: Vec<String>,
    /// Directory where parameters saved with 1010h are kept across runs (one file per device,
    /// node and area). Without it, saved parameters last until the process ends.
    #[arg(long)]
    state_dir: Option<PathBuf>,
    /// Start a hub on this address (port 0 picks a free port) and put the devices on it.
    #[arg(long)]
    listen: Option<String>,
    /// Join a running bus: socketcand://HOST:PORT/CHANNEL (a hub; tcp:// is the same) or
    /// socketcan://IFACE.
    #[arg(long, value_parser = parse_bus)]
    bus: Option<BusAddr>,
    /// Hub channel the devices are put on with --listen.
    #[arg(long, default_value = DEFAULT_CHANNEL)]
    channel: String,
    /// SDO server timeout in milliseconds (0 disables it).
    #[arg(long, default_value_t = 1000)]
    sdo_timeout_ms: u64,
    /// With --listen: log only hub problems (no connect/disconnect lines).
    #[arg(long, short)]
    quiet: bool,
    /// With --listen: the hub's limits.
    #[command(flatten)]
    limits: HubLimits,
    /// With --bus: when the bus fails, wait this many milliseconds before reconnecting (each
    /// device keeps its state and runs on meanwhile), doubling up to 5 s between attempts.
    #[arg(long, default_value_t = 100)]
    reconnect_ms: u64,
    /// Give each device its own connection and thread, as separate CAN controllers: an emulated
    /// wire (--bitrate) then arbitrates between the devices' frames too, and each reconnects
    /// alone. By default the devices share one connection and thread: a frame wakes one
    /// thread, not one per device.
    #[arg(long)]
    connection_per_device: bool,
    /// Record every device's motion and write it as CSV here when stopped.
    #[arg(long)]
    trace: Option<PathBuf>,
    /// Draw every device's motion as an SVG plot here when stopped.
    #[arg(long)]
    plot: Option<PathBuf>,
    /// With --trace/--plot: keep one sample per this many milliseconds (0: every tick).
    #[arg(long, default_value_t = 5)]
    trace_interval_ms: u64,
    /// Listen on this Unix socket for faults to inject: power cycles, silenced heartbeats,
    /// drive faults (see `drive-sim fault --help`).
    #[arg(long)]
    control: Option<PathBuf>,
}

fn parse_kind(s: &str) -> Result<DeviceKind, String> {
    s.parse()
}

/// A `--node-id`: 1..=127, or `none`/255 for a device that waits for LSS.
fn parse_node_id(s: &str) -> Result<u8, String> {
    if s.eq_ignore_ascii_case("none") {
        return Ok(od_runtime::lss::UNCONFIGURED);
    }
    // 1..=127 and 255; other numbers are refused with the device they belong to.
    s.parse::<u8>().map_err(|_| format!("{s}: a node id is 1..=127, or 'none' (255) for a device that waits for LSS"))
}

/// A `--bus` address. An in-memory bus (`mem://`) lives inside one process, so `drive-sim`
/// would be alone on it: refused, with the forms that reach other programs.
fn parse_bus(text: &str) -> Result<BusAddr, String> {
    match text.parse::<BusAddr>().map_err(|e| e.to_string())? {
        BusAddr::Memory { .. } => Err(format!(
            "{text}: an in-memory bus lives inside one process and nothing else would be on it; \
             give socketcand://HOST:PORT/CHANNEL (a drive-sim hub) or socketcan://IFACE"
        )),
        addr => Ok(addr),
    }
}

#[derive(Debug, Args)]
struct DumpArgs {
    /// Bus to listen on: socketcand://HOST:PORT/CHANNEL (a hub; tcp:// is the same) or
    /// socketcan://IFACE.
    #[arg(long, value_parser = parse_bus)]
    bus: BusAddr,
    /// Stop after this many frames.
    #[arg(long)]
    count: Option<u64>,
    /// Stop after this many seconds.
    #[arg(long)]
    timeout: Option<f64>,
}

#[derive(Debug, Args)]
struct SendArgs {
    /// Bus to send on: socketcand://HOST:PORT/CHANNEL (a hub; tcp:// is the same) or
    /// socketcan://IFACE.
    #[arg(long, value_parser = parse_bus)]
    bus: BusAddr,
    /// Frames, such as 601#4041600000000000 or 00000123#R2.
    #[arg(required = true)]
    frames: Vec<CanFrame>,
}

fn main() -> ExitCode {
    let matches = Cli::command().get_matches();
    let cli = match Cli::from_arg_matches(&matches) {
        Ok(cli) => cli,
        Err(e) => e.exit(),
    };
    let result = match cli.command {
        Command::Run(args) => match matches.subcommand_matches("run") {
            Some(m) => run_devices(&args, m),
            None => Err("internal error: no matches for run".into()),
        },
        Command::Hub(args) => run_hub(&args),
        Command::Dump(args) => run_dump(&args),
        Command::Send(args) => run_send(&args),
        Command::Demo(args) => run_demo(&args),
        Command::Slcan(args) => Termination::block()
            .map_err(|e| format!("cannot set up signal handling: {e}"))
            .and_then(|t| drive::slcan::run(&args, || eprintln!("drive-sim: {}, stopping", t.wait()))),
        Command::Fault(args) => run_fault(&args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(message) => {
            eprintln!("drive-sim: {message}");
            ExitCode::FAILURE
        }
    }
}

fn run_hub(args: &HubArgs) -> Result<(), String> {
    // Before any thread starts, so every thread inherits the blocked signal set.
    let termination = Termination::block().map_err(|e| format!("cannot set up signal handling: {e}"))?;
    let config = HubConfig { client_queue: args.queue, channels: args.channels.clone(), ..HubConfig::default() };
    let mut config = args.limits.apply(config);
    config = if args.quiet { quiet_hub(config) } else { logged_hub(config) };
    let hub = Hub::bind(args.listen.as_str(), config).map_err(|e| format!("hub on {}: {e}", args.listen))?;
    let mut stdout = std::io::stdout().lock();
    // Ignored if nobody reads stdout: the line is a convenience for scripts.
    let _ = writeln!(stdout, "listening on {}", hub.local_addr()).and_then(|()| stdout.flush());
    drop(stdout);
    let signal = termination.wait();
    eprintln!("hub: {signal}, stopping");
    hub.stop();
    Ok(())
}

/// One `--device` with the options that follow it.
#[derive(Debug, Clone, PartialEq, Eq)]
struct DeviceGroup {
    kind: DeviceKind,
    config: NodeConfig,
    /// `--machine`: a preset's name or a file; `None` for the device's default.
    machine: Option<String>,
}

/// Pairs every --node-id and --dcf with the --device before it on the command line.
fn device_groups(args: &RunArgs, m: &ArgMatches) -> Result<Vec<DeviceGroup>, String> {
    let positions = |id: &str| -> Vec<usize> { m.indices_of(id).map(Iterator::collect).unwrap_or_default() };
    let devices = positions("device");
    let mut groups: Vec<DeviceGroup> = args
        .device
        .iter()
        .map(|&kind| DeviceGroup {
            kind,
            config: NodeConfig {
                state_dir: args.state_dir.clone(),
                sdo_timeout: Some(args.sdo_timeout_ms.saturating_mul(1000)),
                ..NodeConfig::default()
            },
            machine: None,
        })
        .collect();
    let owner = |at: usize, option: &str| -> Result<usize, String> {
        devices
            .iter()
            .rposition(|&d| d < at)
            .ok_or_else(|| format!("--{option} must follow the --device it belongs to"))
    };
    for (at, &id) in positions("node_id").iter().zip(&args.node_id) {
        let g = owner(*at, "node-id")?;
        if groups[g].config.node_id.replace(id).is_some() {
            return Err(format!("device {} ({}) has two --node-id", g + 1, groups[g].kind));
        }
    }
    for (at, &serial) in positions("serial").iter().zip(&args.serial) {
        let g = owner(*at, "serial")?;
        if groups[g].config.serial.replace(serial).is_some() {
            return Err(format!("device {} ({}) has two --serial", g + 1, groups[g].kind));
        }
    }
    for (at, machine) in positions("machine").iter().zip(&args.machine) {
        let g = owner(*at, "machine")?;
        if groups[g].machine.replace(machine.clone()).is_some() {
            return Err(format!("device {} ({}) has two --machine", g + 1, groups[g].kind));
        }
    }
    for (at, dcf) in positions("dcf").iter().zip(&args.dcf) {
        let g = owner(*at, "dcf")?;
        if groups[g].config.dcf.replace(dcf.clone()).is_some() {
            return Err(format!("device {} ({}) has two --dcf", g + 1, groups[g].kind));
        }
    }
    Ok(groups)
}

fn run_demo(args: &DemoArgs) -> Result<(), String> {
    let options = DemoOptions {
        device: args.device,
        node_id: args.node_id,
        plot: args.plot.clone(),
        trace: args.trace.clone(),
        target_deg: args.target_deg,
    };
    let mut stdout = std::io::stdout().lock();
    demo::run(&options, &mut stdout).map(|_| ()).map_err(|e| format!("demo: {e}"))
}

/// `base` for a single device; `base` with `-<kind>-node<id>` before the extension otherwise.
fn per_device(base: &std::path::Path, kind: DeviceKind, id: u8, several: bool) -> PathBuf {
    if !several {
        return base.to_path_buf();
    }
    let stem = base.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let name = match base.extension() {
        Some(ext) => format!("{stem}-{kind}-node{id}.{}", ext.to_string_lossy()),
        None => format!("{stem}-{kind}-node{id}"),
    };
    base.with_file_name(name)
}

fn write_traces(args: &RunArgs, apps: &DeviceApps, nodes: &[(DeviceKind, Box<dyn AnyNode>)]) -> Result<(), String> {
    let traces = apps.traces();
    let several = traces.len() > 1;
    for ((kind, trace), (_, node)) in traces.iter().zip(nodes) {
        let id = node.node_id().get();
        let trace = trace.lock().map(|t| t.clone()).unwrap_or_default();
        if let Some(path) = &args.trace {
            let path = per_device(path, *kind, id, several);
            std::fs::write(&path, trace.to_csv()).map_err(|e| format!("{}: {e}", path.display()))?;
            eprintln!("drive-sim: {kind} node {id}: trace written to {}", path.display());
        }
        if let Some(path) = &args.plot {
            let path = per_device(path, *kind, id, several);
            let title = format!("{kind} node {id}");
            let svg = trace.to_svg(&demo::plot_options_for(*kind, &**node, &title));
            std::fs::write(&path, svg).map_err(|e| format!("{}: {e}", path.display()))?;
            eprintln!("drive-sim: {kind} node {id}: plot written to {}", path.display());
        }
    }
    Ok(())
}

fn run_devices(args: &RunArgs, m: &ArgMatches) -> Result<(), String> {
    let groups = device_groups(args, m)?;
    let apps = if args.trace.is_some() || args.plot.is_some() {
        DeviceApps::with_trace(args.trace_interval_ms.saturating_mul(1000))
    } else {
        DeviceApps::new()
    };
    let mut nodes: Vec<(String, Box<dyn AnyNode>)> = Vec::new();
    let kinds: Vec<DeviceKind> = groups.iter().map(|g| g.kind).collect();
    for g in &groups {
        let machine = match &g.machine {
            Some(spec) => Some(machine::resolve(g.kind, spec).map_err(|e| format!("{}: --machine {e}", g.kind))?),
            None => None,
        };
        apps.set_machine(machine);
        let node = g.kind.build(&g.config, &apps).map_err(|e| format!("{}: {e}", g.kind))?;
        let name = match (node.active_node_id(), g.config.serial) {
            (Some(id), None) => format!("{} node {}", g.kind, id.get()),
            (Some(id), Some(sn)) => format!("{} node {} (serial {sn})", g.kind, id.get()),
            (None, sn) => {
                format!("{} without node id (serial {})", g.kind, sn.map_or("of its EDS".into(), |s| s.to_string()))
            }
        };
        // Devices with their own serial numbers may share a node id: LSS sets them apart.
        if g.config.serial.is_none()
            && let Some(id) = node.active_node_id()
            && nodes.iter().any(|(_, n)| n.active_node_id() == Some(id))
        {
            return Err(format!("{name}: two devices with node id {}", node.node_id().get()));
        }
        nodes.push((name, node));
    }
    let nodes = match &args.control {
        Some(path) => faults_on_demand(path, nodes)?,
        None => nodes,
    };
    // Before any thread starts, so every thread inherits the blocked signal set.
    let termination = Termination::block().map_err(|e| format!("cannot set up signal handling: {e}"))?;
    // By default the devices share one connection (one endpoint) and one thread, as the
    // devices of one process: a frame on the bus wakes one thread, and the hub writes it once.
    let mut groups: Vec<Vec<(String, Box<dyn AnyNode>)>> = Vec::new();
    for node in nodes {
        match groups.last_mut() {
            Some(group) if !args.connection_per_device => group.push(node),
            _ => groups.push(vec![node]),
        }
    }
    let group_name = |group: &[(String, Box<dyn AnyNode>)]| -> String {
        group.iter().map(|(name, _)| name.as_str()).collect::<Vec<_>>().join(", ")
    };
    let mut hub = None;
    let mut endpoints: Vec<Box<dyn Endpoint>> = Vec::new();
    let ready = if let Some(listen) = &args.listen {
        // Its devices are on one channel: another name is a typo, refused.
        let mut config = args.limits.apply(HubConfig { channels: vec![args.channel.clone()], ..HubConfig::default() });
        config = if args.quiet { quiet_hub(config) } else { logged_hub(config) };
        let h = Hub::bind(listen.as_str(), config).map_err(|e| format!("hub on {listen}: {e}"))?;
        for _ in &groups {
            endpoints.push(Box::new(h.attach(&args.channel).map_err(|e| format!("channel {}: {e}", args.channel))?));
        }
        let line = format!("listening on {}", h.local_addr());
        hub = Some(h);
        line
    } else if let Some(bus) = &args.bus {
        for group in &groups {
            endpoints.push(bus.open().map_err(|e| format!("{}: {bus}: {e}", group_name(group)))?);
        }
        format!("running on {bus}")
    } else {
        return Err("give --listen ADDRESS or --bus BUS".into());
    };

    let stop = Arc::new(AtomicBool::new(false));
    let failed = Arc::new(AtomicBool::new(false));
    let clock = MonotonicClock::new();
    let backoff = Backoff { first: Duration::from_millis(args.reconnect_ms.max(1)), ..Backoff::default() };
    let mut threads = Vec::new();
    for (group, mut endpoint) in groups.into_iter().zip(endpoints) {
        let name = group_name(&group);
        for (device, _) in &group {
            eprintln!("drive-sim: {device} started");
        }
        let size = group.len();
        let mut nodes: Vec<Box<dyn AnyNode>> = group.into_iter().map(|(_, node)| node).collect();
        let (stop, failed) = (Arc::clone(&stop), Arc::clone(&failed));
        let reconnect = args.bus.clone();
        let thread = std::thread::Builder::new()
            .name(name.clone())
            .spawn(move || {
                let mut group: Vec<&mut dyn AnyNode> = nodes.iter_mut().map(|n| &mut **n as &mut dyn AnyNode).collect();
                if let Some(bus) = reconnect {
                    // A bus of their own: lost connections are opened again, the nodes run on.
                    let mut open = || bus.open();
                    let mut report = |event: BusEvent<'_>| match event {
                        BusEvent::Lost(e) => eprintln!("drive-sim: {name}: {bus}: {e}; reconnecting"),
                        BusEvent::RetryFailed { error, retry_in } => {
                            eprintln!("drive-sim: {name}: {bus}: {error}; next attempt in {retry_in:?}")
                        }
                        BusEvent::Reconnected { attempts } => {
                            eprintln!("drive-sim: {name}: {bus}: reconnected after {attempts} attempt(s)")
                        }
                        _ => {}
                    };
                    drive::node::run_group_reconnecting(
                        &mut group,
                        endpoint,
                        &mut open,
                        &clock,
                        &stop,
                        backoff,
                        &mut report,
                    );
                } else {
                    match drive::node::run_group(&mut group, &mut *endpoint, &clock, &stop) {
                        Ok(_) => {}
                        Err(TransportError::Closed) if stop.load(Ordering::SeqCst) => {}
                        Err(e) => {
                            eprintln!("drive-sim: {name}: {e}");
                            failed.store(true, Ordering::SeqCst);
                            Termination::trigger();
                        }
                    }
                }
                drop(group);
                nodes
            })
            .map_err(|e| format!("cannot start a device thread: {e}"))?;
        threads.push((thread, size));
    }
    let mut stdout = std::io::stdout().lock();
    // Ignored if nobody reads stdout: the line is a convenience for scripts.
    let _ = writeln!(stdout, "{ready}").and_then(|()| stdout.flush());
    drop(stdout);

    let signal = termination.wait();
    if !failed.load(Ordering::SeqCst) {
        eprintln!("drive-sim: {signal}, stopping");
    }
    stop.store(true, Ordering::SeqCst);
    let mut stopped: Vec<(DeviceKind, Box<dyn AnyNode>)> = Vec::new();
    let mut kinds = kinds.into_iter();
    for (thread, size) in threads {
        match thread.join() {
            Ok(nodes) => stopped.extend(kinds.by_ref().zip(nodes)),
            // A panicked thread's devices are gone (no trace of them); the others' kinds still
            // line up.
            Err(_) => kinds.by_ref().take(size).for_each(drop),
        }
    }
    if let Some(hub) = hub {
        hub.stop();
    }
    if args.trace.is_some() || args.plot.is_some() {
        write_traces(args, &apps, &stopped)?;
    }
    if failed.load(Ordering::SeqCst) { Err("a device stopped on a bus error".into()) } else { Ok(()) }
}

/// Every event on stderr but `listening on`, which stdout says (once).
fn logged_hub(config: HubConfig) -> HubConfig {
    config.with_observer(std::sync::Arc::new(|event| {
        if !matches!(event, od_bus::HubEvent::Listening { .. }) {
            eprintln!("hub: {event}");
        }
    }))
}

/// Devices by name, as `run` starts them.
type Named = Vec<(String, Box<dyn AnyNode>)>;

/// Wraps every device in a fault injector and serves `path` for commands to them.
#[cfg(unix)]
fn faults_on_demand(path: &std::path::Path, nodes: Named) -> Result<Named, String> {
    use std::io::{BufRead, BufReader, Read};
    use std::os::unix::fs::FileTypeExt;
    use std::os::unix::net::UnixListener;
    if let Ok(meta) = std::fs::symlink_metadata(path) {
        if !meta.file_type().is_socket() {
            return Err(format!("--control {}: exists and is not a socket; give another path", path.display()));
        }
        // A socket left by an earlier run.
        std::fs::remove_file(path).map_err(|e| format!("--control {}: {e}", path.display()))?;
    }
    let listener = UnixListener::bind(path).map_err(|e| format!("--control {}: {e}", path.display()))?;
    let mut handles = std::collections::BTreeMap::new();
    let mut wrapped = Vec::new();
    for (name, node) in nodes {
        let id = node.node_id().get();
        let (faulty, handle) = drive::node::Faulty::new(node);
        handles.insert(id, handle);
        wrapped.push((name, Box::new(faulty) as Box<dyn AnyNode>));
    }
    eprintln!("drive-sim: faults on demand at {}", path.display());
    std::thread::Builder::new()
        .name("fault-control".into())
        .spawn(move || {
            for stream in listener.incoming().flatten() {
                let Ok(mut writer) = stream.try_clone() else { continue };
                // One line at most 256 bytes: a command is a few words.
                for line in BufReader::new(stream.take(64 * 1024)).lines() {
                    let Ok(line) = line else { break };
                    if line.trim().is_empty() {
                        continue;
                    }
                    let answer = match fault_command(&line, &handles) {
                        Ok(what) => {
                            eprintln!("drive-sim: fault: {what}");
                            "ok".to_owned()
                        }
                        Err(e) => format!("error: {e}"),
                    };
                    if writeln!(writer, "{answer}").is_err() {
                        break;
                    }
                }
            }
        })
        .map_err(|e| format!("cannot start the control thread: {e}"))?;
    Ok(wrapped)
}

#[cfg(not(unix))]
fn faults_on_demand(path: &std::path::Path, _nodes: Named) -> Result<Named, String> {
    Err(format!("--control {}: control sockets are Unix sockets; not available here", path.display()))
}

/// `NODE COMMAND...` to the device's fault injector.
#[cfg(unix)]
fn fault_command(
    line: &str,
    handles: &std::collections::BTreeMap<u8, drive::node::FaultHandle>,
) -> Result<String, String> {
    let line = line.trim();
    if line.len() > 256 {
        return Err("command longer than 256 bytes".into());
    }
    let (node, rest) =
        line.split_once(char::is_whitespace).ok_or_else(|| format!("`{line}`: expected NODE COMMAND"))?;
    let id: u8 = node.parse().map_err(|_| format!("`{node}` is not a node id"))?;
    let handle = handles.get(&id).ok_or_else(|| {
        let ids: Vec<String> = handles.keys().map(u8::to_string).collect();
        format!("no device with node id {id} here (these are: {})", ids.join(", "))
    })?;
    let fault: drive::node::Fault = rest.parse()?;
    handle.inject(fault);
    Ok(format!("node {id}: {fault:?}"))
}

#[cfg(unix)]
fn run_fault(args: &FaultArgs) -> Result<(), String> {
    use std::io::{BufRead, BufReader};
    let line = format!("{} {}", args.node, args.fault.join(" "));
    // Checked here too, for a message before connecting.
    line.split_once(' ').map(|(_, f)| f.parse::<drive::node::Fault>()).transpose()?;
    let mut stream = std::os::unix::net::UnixStream::connect(&args.control).map_err(|e| {
        format!("{}: {e} (is `drive-sim run --control {}` running?)", args.control.display(), args.control.display())
    })?;
    stream.set_read_timeout(Some(Duration::from_secs(5))).map_err(|e| e.to_string())?;
    writeln!(stream, "{line}").map_err(|e| format!("{}: {e}", args.control.display()))?;
    let mut answer = String::new();
    BufReader::new(stream).read_line(&mut answer).map_err(|e| format!("{}: {e}", args.control.display()))?;
    match answer.trim() {
        "ok" => Ok(()),
        other => Err(other.strip_prefix("error: ").unwrap_or(other).to_owned()),
    }
}

#[cfg(not(unix))]
fn run_fault(args: &FaultArgs) -> Result<(), String> {
    Err(format!("{}: control sockets are Unix sockets; not available here", args.control.display()))
}

fn quiet_hub(config: HubConfig) -> HubConfig {
    config.with_observer(std::sync::Arc::new(|event| {
        use od_bus::HubEvent::*;
        if matches!(
            event,
            Overflow { .. }
                | AcceptFailed { .. }
                | Rejected { .. }
                | EndpointOverflow { .. }
                | LoneChannel { .. }
                | Evicted { .. }
                | FramesDropped { .. }
        ) {
            eprintln!("hub: {event}");
        }
    }))
}

fn run_dump(args: &DumpArgs) -> Result<(), String> {
    let mut bus = args.bus.open().map_err(|e| format!("{}: {e}", args.bus))?;
    eprintln!("dump: on {}", args.bus);
    let deadline = match args.timeout {
        Some(seconds) if seconds.is_finite() && seconds >= 0.0 => {
            Some(Instant::now() + Duration::from_secs_f64(seconds))
        }
        Some(_) => return Err("--timeout must be a number of seconds".into()),
        None => None,
    };
    let mut seen = 0u64;
    let mut stdout = std::io::stdout().lock();
    // Frames lost on the way to us (the hub drops frames for a reader slower than the bus),
    // reported at most once a second and when dump ends.
    let mut lost_reported = 0u64;
    let mut last_report = Instant::now();
    let mut report_lost = |lost: u64, force: bool| {
        if lost > lost_reported && (force || last_report.elapsed() >= Duration::from_secs(1)) {
            eprintln!(
                "dump: {} frames lost ({lost} in all): dump reads more slowly than the bus runs",
                lost - lost_reported
            );
            lost_reported = lost;
            last_report = Instant::now();
        }
    };
    while args.count.is_none_or(|count| seen < count) {
        report_lost(bus.lost(), false);
        let wait = match deadline {
            Some(deadline) => deadline.saturating_duration_since(Instant::now()),
            None => Duration::from_secs(1),
        };
        if deadline.is_some() && wait.is_zero() {
            break;
        }
        match bus.recv_timeout(wait).map_err(|e| format!("{}: {e}", args.bus))? {
            Some(frame) => {
                seen += 1;
                if writeln!(stdout, "{frame}").and_then(|()| stdout.flush()).is_err() {
                    break; // stdout closed
                }
            }
            None => continue,
        }
    }
    report_lost(bus.lost(), true);
    Ok(())
}

fn run_send(args: &SendArgs) -> Result<(), String> {
    let mut bus = args.bus.open().map_err(|e| format!("{}: {e}", args.bus))?;
    for frame in &args.frames {
        bus.send(*frame).map_err(|e| format!("{}: sending {frame}: {e}", args.bus))?;
    }
    Ok(())
}

/// SIGINT and SIGTERM, received synchronously: the signals are blocked in every thread and one
/// thread collects them with `sigwait`, so no code runs in signal-handler context.
#[cfg(unix)]
struct Termination {
    set: libc::sigset_t,
}

#[cfg(unix)]
impl Termination {
    /// Blocks SIGINT and SIGTERM in the calling thread and in the threads it starts later.
    fn block() -> std::io::Result<Self> {
        // SAFETY: sigset_t is plain data initialised by sigemptyset before use; the pointers
        // passed are to locals that outlive the calls.
        unsafe {
            let mut set: libc::sigset_t = std::mem::zeroed();
            libc::sigemptyset(&raw mut set);
            libc::sigaddset(&raw mut set, libc::SIGINT);
            libc::sigaddset(&raw mut set, libc::SIGTERM);
            let rc = libc::pthread_sigmask(libc::SIG_BLOCK, &raw const set, std::ptr::null_mut());
            if rc != 0 {
                return Err(std::io::Error::from_raw_os_error(rc));
            }
            Ok(Self { set })
        }
    }

    /// Makes [`Termination::wait`] return, from any thread (sends SIGTERM to this process;
    /// it stays pending, as every thread blocks it, until `wait` collects it).
    fn trigger() {
        // SAFETY: kill with our own pid and a valid signal number has no memory effects.
        unsafe {
            libc::kill(libc::getpid(), libc::SIGTERM);
        }
    }

    /// Waits for SIGINT or SIGTERM and names it.
    fn wait(&self) -> &'static str {
        loop {
            let mut signal: libc::c_int = 0;
            // SAFETY: `self.set` was initialised in `block`; `signal` is a valid out pointer.
            let rc = unsafe { libc::sigwait(&raw const self.set, &raw mut signal) };
            match (rc, signal) {
                (0, libc::SIGINT) => return "SIGINT",
                (0, libc::SIGTERM) => return "SIGTERM",
                _ => continue,
            }
        }
    }
}

/// Elsewhere: no signal set to block; wait until the process is killed.
#[cfg(not(unix))]
struct Termination;

#[cfg(not(unix))]
impl Termination {
    fn block() -> std::io::Result<Self> {
        Ok(Self)
    }

    fn trigger() {
        std::process::exit(1);
    }

    fn wait(&self) -> &'static str {
        loop {
            std::thread::park();
        }
    }
}
