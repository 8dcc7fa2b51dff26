//! `od-master top`: a live full-screen view of a CANopen network (nodes, events, frames).
//!
//! Three parts, as a terminal UI is best built: the [`model`] is updated by the master's events,
//! the frames and the keys (no terminal, tested as is); the [`view`] draws a model (pure: tested
//! against ratatui's test backend); [`run_loop`] is generic over the backend and redraws on a tick
//! (20 Hz), never once a frame, so a busy bus costs the decoding and not the drawing.

pub mod model;
#[cfg(test)]
mod tests;
pub mod view;

use std::collections::BTreeMap;
use std::path::Path;
use std::time::Duration;

use crossterm::event::{Event as TermEvent, KeyEvent, KeyEventKind};
use od_master::{Bus, Event, Network, Watch};
use ratatui::Terminal;
use ratatui::backend::Backend;
use tokio::sync::broadcast::error::TryRecvError;
use tokio::sync::{broadcast, mpsc};
use tokio::time::Instant;

use crate::cli::device::Device;
use crate::cli::value::{hex, show};
use model::{Model, Request};

/// Redraws a second.
pub const HZ: u64 = 20;

/// An answer to a poll: node, index, the value (`None`: the read failed), or the end of the
/// node's poll.
enum Polled {
    Value(u8, u16, u8, Option<Vec<u8>>),
    Done(u8),
    Answer(String),
}

/// The master's events and frames, and the answers of the polls, taken into a model.
pub struct Feed {
    events: broadcast::Receiver<Event>,
    frames: broadcast::Receiver<od_bus::CanFrame>,
    polled_tx: mpsc::UnboundedSender<Polled>,
    polled: mpsc::UnboundedReceiver<Polled>,
    start: Instant,
}

impl Feed {
    /// Subscribes to `bus` from now on; times are counted from now.
    pub fn new(bus: &Bus) -> Self {
        let (polled_tx, polled) = mpsc::unbounded_channel();
        Self { events: bus.events(), frames: bus.frames(), polled_tx, polled, start: Instant::now() }
    }

    /// The time since the feed started.
    pub fn now(&self) -> Duration {
        self.start.elapsed()
    }

    /// Takes every event and frame waiting into `model` (frames a channel overran are counted
    /// as dropped; a lost event is said among the events).
    pub fn drain(&mut self, model: &mut Model, devices: &BTreeMap<u8, Device>) {
        let now = self.now();
        loop {
            match self.events.try_recv() {
                Ok(e) => model.on_event(now, &e, devices),
                Err(TryRecvError::Lagged(n)) => model.note(now, format!("{n} events dropped (the view was too slow)")),
                Err(_) => break,
            }
        }
        loop {
            match self.frames.try_recv() {
                Ok(f) => model.on_frame(now, f.id(), f.is_remote(), f.data(), devices),
                Err(TryRecvError::Lagged(n)) => model.dropped += n,
                Err(_) => break,
            }
        }
        while let Ok(p) = self.polled.try_recv() {
            match p {
                Polled::Value(node, index, sub, bytes) => model.on_polled(now, node, index, sub, bytes.as_deref()),
                Polled::Done(node) => model.poll_done(node, devices),
                Polled::Answer(text) => model.on_answer(text),
            }
        }
    }

    /// Starts the reads the model asks for, each node's in a task of its own (at most one a
    /// node, each read given 300 ms): the view never waits for them.
    pub fn poll(&self, bus: &Bus, model: &mut Model, devices: &BTreeMap<u8, Device>) {
        for r in std::mem::take(&mut model.requests) {
            let tx = self.polled_tx.clone();
            let bus = bus.clone();
            tokio::spawn(async move {
                let answer = match r {
                    Request::Read { node, index, sub, data_type } => match bus.node(node) {
                        Ok(n) => match n.read_bytes(index, sub).await {
                            Ok(bytes) => {
                                let shown = show(&bytes, Some(data_type), index, sub);
                                format!("{index:04X}h:{sub} = {}", shown.text())
                            }
                            Err(e) => format!("{index:04X}h:{sub}: {e}"),
                        },
                        Err(e) => e.to_string(),
                    },
                    Request::Write { node, index, sub, bytes } => match bus.node(node) {
                        Ok(n) => match n.write_bytes(index, sub, &bytes).await {
                            Ok(()) => format!("{index:04X}h:{sub} written: {}", hex(&bytes)),
                            Err(e) => format!("{index:04X}h:{sub}: {e}"),
                        },
                        Err(e) => e.to_string(),
                    },
                };
                let _ = tx.send(Polled::Answer(answer));
            });
        }
        for p in model.polls(self.now(), devices) {
            let Ok(node) = bus.node(p.node) else { continue };
            let node = node.with_timeout(Duration::from_millis(300)).with_retries(0);
            let tx = self.polled_tx.clone();
            tokio::spawn(async move {
                for (index, sub) in p.objects {
                    let value = node.read_bytes(index, sub).await.ok();
                    let _ = tx.send(Polled::Value(p.node, index, sub, value));
                }
                let _ = tx.send(Polled::Done(p.node));
            });
        }
    }

    /// Asks the master to watch the heartbeats whose period the model learnt, so that it reports
    /// their loss and recovery.
    pub async fn watch(&self, bus: &Bus, model: &mut Model) {
        for (node, timeout) in std::mem::take(&mut model.watch) {
            let timeout = u64::try_from(timeout.as_micros()).unwrap_or(u64::MAX);
            let _ = bus.watch(node, Watch::Heartbeat { timeout }, None).await;
        }
    }
}

/// Runs the view on `terminal` until `q` or Ctrl-C: takes the keys from `keys`, the bus's
/// traffic from `feed`, and redraws every `1/HZ` s.
pub async fn run_loop<B: Backend>(
    terminal: &mut Terminal<B>,
    bus: &Bus,
    devices: &BTreeMap<u8, Device>,
    model: &mut Model,
    feed: &mut Feed,
    keys: &mut mpsc::Receiver<KeyEvent>,
) -> Result<(), String> {
    let mut tick = tokio::time::interval(Duration::from_millis(1000 / HZ));
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    loop {
        tokio::select! {
            _ = tick.tick() => {
                let t0 = std::time::Instant::now();
                feed.drain(model, devices);
                feed.watch(bus, model).await;
                feed.poll(bus, model, devices);
                let t1 = std::time::Instant::now();
                let now = feed.now();
                terminal.draw(|f| view::draw(f, model, now)).map_err(|e| format!("cannot draw: {e}"))?;
                model.stats.tick(t1 - t0, t1.elapsed());
            }
            key = keys.recv() => match key {
                Some(k) => model.on_key(k, devices),
                None => return Ok(()),
            },
        }
        if model.quit {
            return Ok(());
        }
    }
}

/// The devices by node, and the nodes of a network description with their names.
pub type Described = (BTreeMap<u8, Device>, Vec<(u8, String)>);

/// The devices of a network description's nodes (each with its EDS or DCF, the sidecar beside
/// it and the PDOs the network configures: the writes of its boot plan) and of the `--eds
/// NODE=FILE` arguments (which add nodes or replace a described node's file); and the described
/// nodes with their names, listed before they are heard.
pub fn devices(network: &Network, eds: &[String]) -> Result<Described, String> {
    let mut devices = BTreeMap::new();
    let mut listed = Vec::new();
    for node in &network.nodes {
        let mut device = Device::load(Path::new(&node.device)).map_err(|e| format!("node `{}`: {e}", node.name))?;
        device.configure(node.plan.writes.iter().map(|w| (w.index, w.sub, w.data.as_slice())));
        devices.insert(node.node_id, device);
        listed.push((node.node_id, node.name.clone()));
    }
    let given = crate::Devices::load(eds).map_err(|crate::Fail(_, m)| m)?;
    devices.extend(given.by_node);
    Ok((devices, listed))
}

/// `od-master top` in this terminal, with the nodes of `network` and the devices of `eds` (the
/// `--eds` arguments).
///
/// The view runs on a thread of its own (its own one-thread runtime): the bus's task keeps this
/// one, so drawing never delays the reading of the bus (on a current-thread runtime a redraw
/// would hold the socket unread and a busy hub would drop frames for this client).
pub async fn run(
    bus: &Bus,
    addr: &str,
    eds: &[String],
    network: &Network,
    allow_writes: bool,
    poll: Option<Duration>,
) -> Result<(), String> {
    use std::io::IsTerminal;
    if !std::io::stdout().is_terminal() {
        return Err("top needs a terminal: run it in one (for a log, use `monitor`)".into());
    }
    let (bus, addr, eds, network) = (bus.clone(), addr.to_owned(), eds.to_vec(), network.clone());
    tokio::task::spawn_blocking(move || {
        // Loaded here: a Device is not Send. A bad file is said before the terminal is taken.
        let (devices, listed) = devices(&network, &eds)?;
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .map_err(|e| format!("cannot start the view's runtime: {e}"))?;
        runtime.block_on(view_main(&bus, &addr, &devices, &listed, allow_writes, poll))
    })
    .await
    .map_err(|e| format!("the view stopped: {e}"))?
}

async fn view_main(
    bus: &Bus,
    addr: &str,
    devices: &BTreeMap<u8, Device>,
    listed: &[(u8, String)],
    allow_writes: bool,
    poll: Option<Duration>,
) -> Result<(), String> {
    // Keys come from a thread of their own: crossterm's read blocks.
    let (tx, mut keys) = mpsc::channel(64);
    std::thread::spawn(move || {
        while let Ok(e) = crossterm::event::read() {
            if let TermEvent::Key(k) = e
                && k.kind != KeyEventKind::Release
                && tx.blocking_send(k).is_err()
            {
                return;
            }
        }
    });
    let mut terminal = ratatui::try_init().map_err(|e| format!("cannot set up the terminal: {e}"))?;
    let mut model = Model::new(addr);
    model.allow_writes = allow_writes;
    model.poll = poll;
    for (id, name) in listed {
        model.list(*id, name, devices);
    }
    let mut feed = Feed::new(bus);
    let result = run_loop(&mut terminal, bus, devices, &mut model, &mut feed, &mut keys).await;
    ratatui::try_restore().map_err(|e| format!("cannot restore the terminal: {e}"))?;
    // For the benchmark (scripts/bench_top.py): the loop's figures, one JSON line.
    if let Some(path) = std::env::var_os("OD_MASTER_TOP_STATS") {
        let s = &model.stats;
        let line = serde_json::json!({
            "seconds": feed.now().as_secs_f64(), "redraws": s.redraws,
            "draw_mean_us": s.draw.as_micros() as f64 / s.redraws.max(1) as f64, "draw_max_us": s.draw_max.as_micros(),
            "take_mean_us": s.take.as_micros() as f64 / s.redraws.max(1) as f64,
            "frames": model.frame_count, "dropped": model.dropped, "events": s.events, "emcys": s.emcys,
        });
        std::fs::write(&path, format!("{line}\n")).map_err(|e| format!("cannot write {}: {e}", path.display()))?;
    }
    result
}
