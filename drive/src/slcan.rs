//! A simulated slcan adapter (`drive-sim slcan`): a pseudo-terminal that behaves as a CANable
//! (or a Lawicel CANUSB) on a bus, so od-master (`slcan://PTY`), python-can's `slcan`
//! interface or Linux's `slcand` can be tried without hardware.
//!
//! The adapter reads the host's commands from the pseudo-terminal's master side
//! ([`od_bus::slcan::CommandDecoder`]), puts the frames it is given on its bus and writes the
//! frames of the bus to the host while its channel is open. [`Firmware::Canable`] answers
//! nothing, as the stock CANable firmware (`O C S0-S8 M/m A/a V t T r R`); [`Firmware::Lawicel`]
//! acknowledges every command (`\r`, `z`/`Z` for a frame, BEL when refused), reports its status
//! flags (`F`), time-stamps frames after `Z1`, and after [`Adapter::bus_off`] refuses frames
//! until the host closes and opens the channel again. With the wire emulated (the default),
//! each frame holds the adapter's CAN side for its length in bits at the bit rate of the `Sn`
//! command.
//!
//! Unix only (a pseudo-terminal); elsewhere [`Adapter::start`] says so.

// Off Unix only the types and the error are built: the adapter's innards go unused there.
#![cfg_attr(not(unix), allow(dead_code, unused_imports))]

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
#[cfg(unix)]
use std::time::Duration;

use od_bus::tokio::Bus;
use od_bus::{BusAddr, CanFrame, MemoryBus};

/// How the simulated adapter answers.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum Firmware {
    /// The stock CANable firmware: no acknowledgements, no status flags, no time stamps.
    #[default]
    Canable,
    /// A Lawicel CANUSB: `\r`/BEL acknowledgements, `z`/`Z` for frames, `F` status flags,
    /// `Z1` time stamps, bus-off recovered only by `C` then `O`.
    Lawicel,
}

/// Where the adapter's CAN side is.
#[derive(Debug, Clone)]
pub enum Upstream {
    /// A bus opened from its address (a hub: `socketcand://HOST:PORT/CHANNEL`).
    Addr(BusAddr),
    /// An in-memory bus of this process (devices run in the same process).
    Memory(MemoryBus),
}

/// How the adapter is started.
#[derive(Debug, Clone, Default)]
pub struct AdapterOptions {
    /// What it answers.
    pub firmware: Firmware,
    /// A symbolic link made to the pseudo-terminal (and removed with the adapter): a stable
    /// name, as `/dev/serial/by-id/...` is for a real adapter plugged in again.
    pub link: Option<PathBuf>,
    /// Do not hold the frames for their time on the wire at the `Sn` bit rate.
    pub no_wire: bool,
}

/// The adapter's state, shared by its reader thread and its bus task.
#[derive(Debug)]
struct State {
    firmware: Firmware,
    open: bool,
    listen_only: bool,
    bitrate: u32,
    timestamps: bool,
    flags: u8,
    bus_off: bool,
}

/// A running simulated adapter; dropping it (or [`Adapter::stop`]) closes the pseudo-terminal,
/// as unplugging a real one does.
pub struct Adapter {
    path: PathBuf,
    link: Option<PathBuf>,
    state: Arc<Mutex<State>>,
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<()>>,
}

impl std::fmt::Debug for Adapter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Adapter").field("path", &self.path).field("link", &self.link).finish()
    }
}

impl Adapter {
    /// The pseudo-terminal a host opens (the link, when one was asked for).
    pub fn path(&self) -> &Path {
        self.link.as_deref().unwrap_or(&self.path)
    }

    /// The pseudo-terminal itself (`/dev/pts/N`).
    pub fn pty(&self) -> &Path {
        &self.path
    }

    /// The controller goes bus-off: frames are refused (BEL) and the status flags say so until
    /// the host sends `C` and `O` (Lawicel); a CANable just stops sending.
    pub fn bus_off(&self) {
        let mut state = lock(&self.state);
        state.bus_off = true;
        state.flags |= od_bus::slcan::status::BUS_ERROR;
    }

    /// Whether the channel is open now.
    pub fn is_open(&self) -> bool {
        lock(&self.state).open
    }

    /// Closes the pseudo-terminal (the adapter unplugged) and waits for the threads.
    pub fn stop(mut self) {
        self.shutdown();
    }

    fn shutdown(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
        for thread in self.threads.drain(..) {
            let _ = thread.join();
        }
        if let Some(link) = &self.link {
            let _ = std::fs::remove_file(link);
        }
    }
}

impl Drop for Adapter {
    fn drop(&mut self) {
        self.shutdown();
    }
}

fn lock<T>(mutex: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    mutex.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

#[cfg(not(unix))]
impl Adapter {
    /// Elsewhere than on Unix there is no pseudo-terminal to simulate an adapter on.
    pub fn start(_upstream: Upstream, _options: &AdapterOptions) -> Result<Self, String> {
        Err(format!(
            "a simulated slcan adapter needs a pseudo-terminal (Linux, macOS); this is {}",
            std::env::consts::OS
        ))
    }
}

#[cfg(unix)]
impl Adapter {
    /// Creates the pseudo-terminal and starts the adapter on `upstream`.
    pub fn start(upstream: Upstream, options: &AdapterOptions) -> Result<Self, String> {
        use serialport::SerialPort as _;
        let (master, slave) =
            serialport::TTYPort::pair().map_err(|e| format!("cannot create a pseudo-terminal: {e}"))?;
        let path = PathBuf::from(slave.name().ok_or("the pseudo-terminal has no name")?);
        // The host opens the terminal by its name; the adapter holds only the master side, so
        // that a host that closes it and opens it again is alone on it (serial ports are opened
        // exclusively).
        drop(slave);
        if let Some(link) = &options.link {
            let _ = std::fs::remove_file(link);
            std::os::unix::fs::symlink(&path, link)
                .map_err(|e| format!("cannot link {} to {}: {e}", link.display(), path.display()))?;
        }
        let writer = master.try_clone_native().map_err(|e| format!("cannot use the pseudo-terminal: {e}"))?;
        let state = Arc::new(Mutex::new(State {
            firmware: options.firmware,
            open: false,
            listen_only: false,
            bitrate: 500_000,
            timestamps: false,
            flags: 0,
            bus_off: false,
        }));
        let stop = Arc::new(AtomicBool::new(false));
        let writer = Arc::new(Mutex::new(writer));
        let (to_bus, from_host) = tokio::sync::mpsc::channel::<CanFrame>(256);
        let mut threads = Vec::new();
        let (ready_tx, ready_rx) = std::sync::mpsc::channel();
        {
            let (state, stop, writer) = (Arc::clone(&state), Arc::clone(&stop), Arc::clone(&writer));
            let wire = !options.no_wire;
            threads.push(
                std::thread::Builder::new()
                    .name("slcan adapter bus".into())
                    .spawn(move || bus_side(upstream, from_host, state, writer, stop, wire, ready_tx))
                    .map_err(|e| format!("cannot start a thread: {e}"))?,
            );
        }
        match ready_rx.recv() {
            Ok(Ok(())) => {}
            Ok(Err(e)) => {
                stop.store(true, Ordering::SeqCst);
                for t in threads {
                    let _ = t.join();
                }
                return Err(e);
            }
            Err(_) => return Err("the adapter's bus thread ended".into()),
        }
        {
            let (state, stop, writer) = (Arc::clone(&state), Arc::clone(&stop), Arc::clone(&writer));
            threads.push(
                std::thread::Builder::new()
                    .name("slcan adapter host".into())
                    .spawn(move || host_side(master, writer, state, to_bus, stop))
                    .map_err(|e| format!("cannot start a thread: {e}"))?,
            );
        }
        Ok(Self { path, link: options.link.clone(), state, stop, threads })
    }
}

/// Writes `bytes` to the host; false when it could not (the host reads nothing, or is gone).
#[cfg(unix)]
fn write_host(writer: &Mutex<serialport::TTYPort>, bytes: &[u8]) -> bool {
    use std::io::Write as _;
    lock(writer).write_all(bytes).is_ok()
}

/// Reads the host's commands and carries them out.
#[cfg(unix)]
fn host_side(
    mut master: serialport::TTYPort,
    writer: Arc<Mutex<serialport::TTYPort>>,
    state: Arc<Mutex<State>>,
    to_bus: tokio::sync::mpsc::Sender<CanFrame>,
    stop: Arc<AtomicBool>,
) {
    use od_bus::slcan::{Command, CommandDecoder};
    use serialport::SerialPort as _;
    let _ = master.set_timeout(Duration::from_millis(50));
    let mut decoder = CommandDecoder::new();
    let mut buf = [0u8; 1024];
    let mut replies = Vec::new();
    let mut connected = false;
    while !stop.load(Ordering::SeqCst) {
        let n = match std::io::Read::read(&mut master, &mut buf) {
            Ok(n) => n,
            Err(e) if matches!(e.kind(), std::io::ErrorKind::TimedOut | std::io::ErrorKind::WouldBlock) => 0,
            Err(e) => {
                // No host has the terminal open (a hang-up): the adapter resets, as one
                // unplugged and plugged in again does, and waits for the next host.
                if connected {
                    eprintln!("slcan adapter: the host closed the terminal ({e}); channel closed");
                    connected = false;
                    let mut s = lock(&state);
                    s.open = false;
                    s.flags = 0;
                }
                std::thread::sleep(Duration::from_millis(10));
                continue;
            }
        };
        connected |= n > 0;
        replies.clear();
        let mut frames = Vec::new();
        {
            let mut s = lock(&state);
            decoder.feed(&buf[..n], |command| {
                let lawicel = s.firmware == Firmware::Lawicel;
                // Lawicel answers `\r` (done) or BEL (refused); the CANable nothing.
                let answer = |ok: bool, replies: &mut Vec<u8>| {
                    if lawicel {
                        replies.push(if ok { b'\r' } else { 0x07 });
                    }
                };
                match command {
                    Ok(Command::Transmit(frame)) => {
                        let ok = s.open && !s.listen_only && !s.bus_off;
                        if ok {
                            frames.push(frame);
                        }
                        if lawicel && ok {
                            replies.extend_from_slice(if frame.is_extended() { b"Z\r" } else { b"z\r" });
                        } else {
                            answer(false, &mut replies);
                        }
                    }
                    Ok(Command::Open) => {
                        let ok = !s.open;
                        if ok {
                            s.open = true;
                            s.bus_off = false;
                            s.flags &= !od_bus::slcan::status::BUS_ERROR;
                        }
                        answer(ok, &mut replies);
                    }
                    Ok(Command::ListenOnly) if lawicel => {
                        let ok = !s.open;
                        if ok {
                            s.open = true;
                            s.listen_only = true;
                            s.bus_off = false;
                        }
                        answer(ok, &mut replies);
                    }
                    Ok(Command::Close) => {
                        let ok = s.open;
                        s.open = false;
                        if lawicel {
                            s.listen_only = false;
                        }
                        answer(ok, &mut replies);
                    }
                    Ok(Command::Bitrate(code)) => {
                        let ok = !s.open;
                        if ok {
                            s.bitrate = od_bus::slcan::BITRATES[usize::from(code)];
                        }
                        answer(ok, &mut replies);
                    }
                    Ok(Command::Silent(silent)) if !lawicel => s.listen_only = silent,
                    Ok(Command::AutoRetransmit(_)) if !lawicel => {}
                    Ok(Command::Version) if lawicel => replies.extend_from_slice(b"V1013\r"),
                    Ok(Command::Version) => replies.extend_from_slice(b"vSIM1\r"),
                    Ok(Command::SerialNumber) if lawicel => replies.extend_from_slice(b"NSIM1\r"),
                    Ok(Command::Status) if lawicel => {
                        let flags = s.flags;
                        // Reading the flags clears them, but a controller still bus-off says
                        // so again.
                        s.flags = if s.bus_off { od_bus::slcan::status::BUS_ERROR } else { 0 };
                        replies.extend_from_slice(format!("F{flags:02X}\r").as_bytes());
                    }
                    Ok(Command::Timestamps(on)) if lawicel => {
                        let ok = !s.open;
                        if ok {
                            s.timestamps = on;
                        }
                        answer(ok, &mut replies);
                    }
                    Ok(Command::Acceptance(..) | Command::BitTiming(_)) if lawicel => answer(!s.open, &mut replies),
                    // An empty line clears a partial command: no answer from either firmware.
                    Ok(Command::Empty) => {}
                    // What this firmware does not have: the CANable ignores it, Lawicel refuses.
                    Ok(_) | Err(_) => answer(false, &mut replies),
                }
            });
        }
        for frame in frames {
            if to_bus.blocking_send(frame).is_err() {
                return;
            }
        }
        if !replies.is_empty() {
            write_host(&writer, &replies);
        }
    }
}

/// The adapter's CAN side: frames from the host onto the bus, frames of the bus to the host,
/// each held for its time on the wire.
#[cfg(unix)]
fn bus_side(
    upstream: Upstream,
    mut from_host: tokio::sync::mpsc::Receiver<CanFrame>,
    state: Arc<Mutex<State>>,
    writer: Arc<Mutex<serialport::TTYPort>>,
    stop: Arc<AtomicBool>,
    wire: bool,
    ready: std::sync::mpsc::Sender<Result<(), String>>,
) {
    let runtime = match tokio::runtime::Builder::new_current_thread().enable_all().build() {
        Ok(runtime) => runtime,
        Err(e) => {
            let _ = ready.send(Err(format!("cannot start a runtime: {e}")));
            return;
        }
    };
    runtime.block_on(async move {
        let bus = match upstream {
            Upstream::Addr(addr) => match Bus::open_with(&addr, &Default::default()).await {
                Ok(bus) => bus,
                Err(e) => {
                    let _ = ready.send(Err(format!("{addr}: {e}")));
                    return;
                }
            },
            Upstream::Memory(bus) => Bus::attach(&bus),
        };
        let _ = ready.send(Ok(()));
        let (tx, mut rx) = bus.split();
        let started = std::time::Instant::now();
        let mut busy_until = tokio::time::Instant::now();
        // Holds a frame for its time on the wire; sleeps only when more than a millisecond
        // ahead (tokio's timers tick in milliseconds). A sleep overshoots by up to a tick, so
        // the wire's schedule goes on from where it was (idle time up to `SLACK` back counts),
        // not from the late wake-up: the average rate is the wire's, not lower.
        const SLACK: Duration = Duration::from_millis(2);
        let mut hold = |frame: &CanFrame, bitrate: u32| {
            if !wire {
                return None;
            }
            let now = tokio::time::Instant::now();
            let bits = u64::from(od_bus::wire::frame_bits(frame));
            let length = Duration::from_nanos(bits * 1_000_000_000 / u64::from(bitrate.max(1)));
            busy_until = busy_until.max(now.checked_sub(SLACK).unwrap_or(now)) + length;
            (busy_until > now + Duration::from_millis(1)).then_some(busy_until)
        };
        let mut tick = tokio::time::interval(Duration::from_millis(50));
        let mut line = Vec::with_capacity(32);
        loop {
            tokio::select! {
                frame = from_host.recv() => {
                    let Some(frame) = frame else { return };
                    let bitrate = lock(&state).bitrate;
                    if let Some(until) = hold(&frame, bitrate) {
                        tokio::time::sleep_until(until).await;
                    }
                    // A bus that is down (a hub restarting) loses the frame, as a bus-off
                    // controller would.
                    let _ = tx.send(frame).await;
                }
                frame = rx.recv() => {
                    let Ok(frame) = frame else { return };
                    let (open, bitrate, timestamps, lawicel) = {
                        let s = lock(&state);
                        (s.open && !s.bus_off, s.bitrate, s.timestamps, s.firmware == Firmware::Lawicel)
                    };
                    if !open {
                        continue;
                    }
                    if let Some(until) = hold(&frame, bitrate) {
                        tokio::time::sleep_until(until).await;
                    }
                    line.clear();
                    od_bus::slcan::encode(&frame, &mut line);
                    if timestamps && lawicel {
                        let ms = (started.elapsed().as_millis() % 60_000) as u16;
                        line.pop();
                        line.extend_from_slice(format!("{ms:04X}\r").as_bytes());
                    }
                    if !write_host(&writer, &line) {
                        lock(&state).flags |= od_bus::slcan::status::OVERRUN;
                    }
                }
                _ = tick.tick() => {
                    if stop.load(Ordering::SeqCst) {
                        return;
                    }
                }
            }
        }
    });
}

/// `drive-sim slcan`: a simulated slcan adapter on a pseudo-terminal.
#[derive(Debug, clap::Args)]
#[command(group(clap::ArgGroup::new("upstream").required(true).args(["bus", "device"])))]
pub struct SlcanArgs {
    /// The bus the adapter is on: socketcand://HOST:PORT/CHANNEL (a drive-sim hub) or
    /// socketcan://IFACE. Or give --device instead, for devices in this process.
    #[arg(long)]
    pub bus: Option<BusAddr>,
    /// A device to simulate in this process on the adapter's bus: drvi, drcs or akd (repeat
    /// for several, each with a --node-id, in the same order).
    #[arg(long, value_parser = |s: &str| s.parse::<crate::node::DeviceKind>())]
    pub device: Vec<crate::node::DeviceKind>,
    /// The node id of each --device, in order.
    #[arg(long)]
    pub node_id: Vec<u8>,
    /// What the adapter answers: canable (the stock firmware: nothing) or lawicel
    /// (acknowledgements, status flags, time stamps).
    #[arg(long, value_enum, default_value_t = Firmware::Canable)]
    pub firmware: Firmware,
    /// Also make this symbolic link to the pseudo-terminal (a stable name to open).
    #[arg(long)]
    pub link: Option<PathBuf>,
    /// Pass frames at once instead of holding each for its time on the wire at the bit rate
    /// the host chose (S0-S8).
    #[arg(long)]
    pub no_wire: bool,
}

/// Runs `drive-sim slcan` until `wait` returns (a signal); prints `slcan on PATH` once the
/// adapter is ready.
pub fn run(args: &SlcanArgs, wait: impl FnOnce()) -> Result<(), String> {
    use std::io::Write as _;
    if args.device.len() != args.node_id.len() {
        return Err(format!(
            "give one --node-id for each --device ({} devices, {} node ids)",
            args.device.len(),
            args.node_id.len()
        ));
    }
    let options = AdapterOptions { firmware: args.firmware, link: args.link.clone(), no_wire: args.no_wire };
    let stop = Arc::new(AtomicBool::new(false));
    let mut devices = None;
    let upstream = match &args.bus {
        Some(BusAddr::Memory { .. }) => {
            return Err("an in-memory bus lives inside one process: give --bus socketcand://HOST:PORT/CHANNEL \
                        (a drive-sim hub), socketcan://IFACE, or --device for devices in this process"
                .into());
        }
        Some(addr) => Upstream::Addr(addr.clone()),
        None => {
            let bus = MemoryBus::new();
            let apps = crate::drives::DeviceApps::new();
            let mut nodes = Vec::new();
            for (&kind, &id) in args.device.iter().zip(&args.node_id) {
                let config = crate::node::NodeConfig { node_id: Some(id), ..Default::default() };
                nodes.push(kind.build(&config, &apps).map_err(|e| format!("{kind}: {e}"))?);
            }
            let mut endpoint = bus.endpoint();
            let stop = Arc::clone(&stop);
            devices = Some(
                std::thread::Builder::new()
                    .name("devices".into())
                    .spawn(move || {
                        let mut group: Vec<&mut dyn crate::node::AnyNode> =
                            nodes.iter_mut().map(|n| &mut **n as &mut dyn crate::node::AnyNode).collect();
                        let clock = crate::node::MonotonicClock::new();
                        if let Err(e) = crate::node::run_group(&mut group, &mut endpoint, &clock, &stop) {
                            eprintln!("drive-sim: devices: {e}");
                        }
                    })
                    .map_err(|e| format!("cannot start the devices' thread: {e}"))?,
            );
            Upstream::Memory(bus)
        }
    };
    let adapter = Adapter::start(upstream, &options)?;
    let mut stdout = std::io::stdout().lock();
    // Ignored if nobody reads stdout: the line is a convenience for scripts.
    let _ = writeln!(stdout, "slcan on {}", adapter.path().display()).and_then(|()| stdout.flush());
    drop(stdout);
    wait();
    adapter.stop();
    stop.store(true, Ordering::SeqCst);
    if let Some(devices) = devices {
        let _ = devices.join();
    }
    Ok(())
}
