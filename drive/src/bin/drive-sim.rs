//! `drive-sim`: the command-line front end of the simulated drives.
//!
//! ```text
//! drive-sim hub --listen 127.0.0.1:29536        socketcand-compatible hub (python-can connects to it)
//! drive-sim dump --bus tcp://127.0.0.1:29536/can0 [--count N] [--timeout SECONDS]
//! drive-sim send --bus tcp://127.0.0.1:29536/can0 601#4041600000000000 000#0100 ...
//! ```
//!
//! `hub` prints `listening on ADDRESS` on stdout once it accepts connections (so a script can
//! ask for port 0 and read the port chosen), logs to stderr, and stops cleanly on SIGINT or
//! SIGTERM.
//!
//! Structure for what comes next: simulated devices will be added as one more subcommand (a
//! `run` with `--device` and `--bus`) and as `--device` options of `hub`, which attach them to
//! the hub in-process with `Hub::attach(channel)`; both hand the device a
//! `drive::transport::Endpoint` and share `wait_for_termination` below.

use std::io::Write;
use std::process::ExitCode;
use std::time::{Duration, Instant};

use clap::{Args, Parser, Subcommand};
use drive::transport::{BusSpec, CanFrame, Hub, HubConfig};

#[derive(Debug, Parser)]
#[command(name = "drive-sim", version, about = "Simulated CANopen drives and the buses to reach them")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Run a socketcand-compatible TCP hub: every channel a client opens is one CAN bus.
    Hub(HubArgs),
    /// Print the frames seen on a bus, one per line in cansend notation.
    Dump(DumpArgs),
    /// Put frames on a bus, given in cansend notation (601#2B40600006000000, 701#R).
    Send(SendArgs),
}

#[derive(Debug, Args)]
struct HubArgs {
    /// Address to listen on; port 0 picks a free port (printed on stdout).
    #[arg(long, default_value = "127.0.0.1:29536")]
    listen: String,
    /// Clients served at once.
    #[arg(long, default_value_t = HubConfig::default().max_clients)]
    max_clients: usize,
    /// Messages queued per client before a client that does not keep up is disconnected.
    #[arg(long, default_value_t = HubConfig::default().client_queue)]
    queue: usize,
    /// Log only problems (no connect/disconnect lines).
    #[arg(long, short)]
    quiet: bool,
}

#[derive(Debug, Args)]
struct DumpArgs {
    /// Bus to listen on: tcp://HOST:PORT[/CHANNEL] or socketcan:IFACE.
    #[arg(long)]
    bus: BusSpec,
    /// Stop after this many frames.
    #[arg(long)]
    count: Option<u64>,
    /// Stop after this many seconds.
    #[arg(long)]
    timeout: Option<f64>,
}

#[derive(Debug, Args)]
struct SendArgs {
    /// Bus to send on: tcp://HOST:PORT[/CHANNEL] or socketcan:IFACE.
    #[arg(long)]
    bus: BusSpec,
    /// Frames, such as 601#4041600000000000 or 00000123#R2.
    #[arg(required = true)]
    frames: Vec<CanFrame>,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Hub(args) => run_hub(&args),
        Command::Dump(args) => run_dump(&args),
        Command::Send(args) => run_send(&args),
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
    let mut config = HubConfig { max_clients: args.max_clients, client_queue: args.queue, ..HubConfig::default() };
    if args.quiet {
        config = config.with_observer(std::sync::Arc::new(|event| {
            use drive::transport::HubEvent::*;
            if matches!(event, Overflow { .. } | AcceptFailed { .. } | Rejected { .. } | EndpointOverflow { .. }) {
                eprintln!("hub: {event}");
            }
        }));
    }
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
    while args.count.is_none_or(|count| seen < count) {
        let wait = match deadline {
            Some(deadline) => deadline.saturating_duration_since(Instant::now()),
            None => Duration::from_secs(3600),
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

    fn wait(&self) -> &'static str {
        loop {
            std::thread::park();
        }
    }
}
