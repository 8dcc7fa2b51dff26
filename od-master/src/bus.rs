//! The bus task and its handle.
//!
//! One task owns the bus and every protocol machine of `od_runtime::master`; [`Bus`] handles
//! (cheap to clone, usable from any task) send it commands and wait for the answers. The task
//! runs as long as a handle exists, and ends when the bus is closed for good.
//!
//! SDO transfers use each node's default channel (requests on 600h + id, answers on
//! 580h + id); PDOs, SYNC (080h), EMCY (080h + id) and heartbeats (700h + id) their CiA 301
//! default identifiers, PDOs any identifier given.

use std::collections::{HashMap, VecDeque};
use std::sync::{Arc, Condvar, Mutex, Weak};
use std::time::Duration;

use od_bus::CanFrame;
use od_bus::tokio::{Bus as Link, BusReceiver, BusSender, LinkState};
use od_runtime::master::nmt::{self, Target};
use od_runtime::master::{
    Direction, Done, Emergency, HeartbeatProducer, NodeMonitor, PdoMapping, PdoValue, SdoClient, SdoError,
    SyncProducer, TransferError, Watch,
};
use od_runtime::od::AbortCode;
use od_runtime::{Frame, Micros, NmtCommand, NmtState, NodeId};
use tokio::sync::{broadcast, mpsc, oneshot, watch};
use tokio::time::Instant;

use crate::error::{Error, SdoContext};
use crate::event::{EmcyTexts, Event};
use crate::sdo_options::SdoOptions;

/// How the bus task runs, and the defaults of its nodes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Config {
    /// The SDO options of a [`Node`](crate::Node) handle made by [`Bus::node`]: timeout 1 s, 2 retries of
    /// reads and idempotent writes, normal (expedited or segmented) transfers, values up to
    /// 4 KiB.
    pub sdo: SdoOptions,
    /// The master's own heartbeat: its node id and period, so drives that consume it stop when
    /// this program dies. `None` (the default) sends none.
    pub heartbeat: Option<(NodeId, Duration)>,
    /// Events kept for a subscriber that does not read ([`Bus::events`]); past it the oldest
    /// are dropped and the subscriber is told how many.
    pub event_capacity: usize,
}

impl Default for Config {
    fn default() -> Self {
        Self { sdo: SdoOptions::default(), heartbeat: None, event_capacity: 1024 }
    }
}

/// A received TPDO, decoded by the mapping it was subscribed with.
#[derive(Clone, Debug, PartialEq)]
pub struct Tpdo {
    /// The PDO's COB-ID.
    pub cob_id: u16,
    /// When the bus task received it.
    pub at: Instant,
    /// One value per mapped field.
    pub values: Vec<PdoValue>,
}

/// A handle on the bus task: SDO transfers (through [`Node`](crate::Node)), NMT, events, SYNC and PDOs.
/// Clones share the task; it ends when the last handle is dropped or the bus closes.
#[derive(Clone, Debug)]
pub struct Bus {
    commands: mpsc::Sender<Command>,
    events: broadcast::Sender<Event>,
    frames: broadcast::Sender<CanFrame>,
    syncs: watch::Receiver<u64>,
    link: watch::Receiver<LinkState>,
    controller: od_bus::tokio::Controller,
    sdo: SdoOptions,
}

/// A request for the task; each carries the channel of its answer.
#[derive(Debug)]
enum Command {
    Sdo(SdoRequest),
    Send(CanFrame, oneshot::Sender<Result<(), Error>>),
    Watch {
        node: NodeId,
        watch: Option<Watch>,
        boot_timeout: Option<Duration>,
        reply: oneshot::Sender<()>,
    },
    Sync {
        period: Option<Duration>,
        counter: u8,
        reply: oneshot::Sender<Result<(), Error>>,
    },
    Tpdo {
        cob_id: u16,
        mapping: PdoMapping,
        to: mpsc::Sender<Tpdo>,
    },
    /// Sends `frame` right before every SYNC, replacing the frame of the same `owner`, until
    /// the owner (a [`CyclicPdo`]) is dropped.
    Cyclic {
        frame: Frame,
        owner: Weak<()>,
    },
    EmcyTexts {
        node: NodeId,
        texts: Arc<EmcyTexts>,
    },
}

/// What an SDO request moves.
#[derive(Debug)]
pub(crate) enum Op {
    /// Read a value of at most this many bytes.
    Upload(usize),
    /// Write this data; retried only when `idempotent`.
    Download { data: Vec<u8>, idempotent: bool },
}

#[derive(Debug)]
pub(crate) struct SdoRequest {
    pub node: NodeId,
    pub index: u16,
    pub sub: u8,
    pub op: Op,
    pub options: SdoOptions,
    pub reply: oneshot::Sender<Result<Vec<u8>, Error>>,
}

impl Bus {
    /// Opens the bus at `addr` (`socketcand://HOST:PORT/CHANNEL`, `socketcan://IFACE`,
    /// `mem://NAME`) and starts its task on the current tokio runtime.
    pub async fn open(addr: &str, config: Config) -> Result<Self, Error> {
        Ok(Self::start(Link::open(addr).await?, config))
    }

    /// Starts the task for a bus already open (a [`Link::attach`] to a test's memory bus, a
    /// socketcand bus opened with other options) on the current tokio runtime.
    pub fn start(link: Link, config: Config) -> Self {
        let (commands, command_rx) = mpsc::channel(256);
        let (events, _) = broadcast::channel(config.event_capacity.max(1));
        let (frames, _) = broadcast::channel(4096);
        let (sync_tx, syncs) = watch::channel(0);
        let link_state = link.link();
        let controller = link.controller();
        let (tx, rx) = link.split();
        let start = Instant::now();
        let heartbeat = config.heartbeat.map(|(id, period)| HeartbeatProducer::new(id, micros(period)));
        let task = Task {
            tx,
            rx,
            link: link_state.clone(),
            link_open: true,
            down_since: None,
            heard: 0,
            commands: command_rx,
            start,
            channels: HashMap::new(),
            monitor: Box::new(NodeMonitor::new()),
            heartbeat,
            sync: None,
            syncs: sync_tx,
            tpdos: HashMap::new(),
            texts: HashMap::new(),
            events: events.clone(),
            frames: frames.clone(),
            out: Vec::new(),
            wire: Vec::new(),
            sends: Vec::new(),
            clock: None,
            cyclic: Vec::new(),
        };
        tokio::spawn(task.run());
        Self { commands, events, frames, syncs, link: link_state, controller, sdo: config.sdo }
    }

    /// The SDO options of the node handles [`Bus::node`] makes.
    pub(crate) fn sdo_options(&self) -> SdoOptions {
        self.sdo
    }

    /// Subscribes to the bus's [`Event`]s from now on.
    pub fn events(&self) -> broadcast::Receiver<Event> {
        self.events.subscribe()
    }

    /// Subscribes to every frame received from now on (the master's own are not included).
    pub fn frames(&self) -> broadcast::Receiver<CanFrame> {
        self.frames.subscribe()
    }

    /// The link's state (a socketcand link goes down and comes back; see
    /// [`od_bus::tokio::LinkState`]).
    pub fn link(&self) -> watch::Receiver<LinkState> {
        self.link.clone()
    }

    /// The CAN controller's state changes (error warning, error-passive, bus-off, restarted,
    /// error-active again): a SocketCAN bus reports them from the kernel's error frames, an
    /// slcan bus its adapter's bus-off; see [`od_bus::tokio::Controller`].
    pub fn controller(&self) -> broadcast::Receiver<od_bus::ControllerState> {
        self.controller.subscribe()
    }

    /// The number of SYNCs sent so far; `changed().await` on it waits for the next one.
    pub fn syncs(&self) -> watch::Receiver<u64> {
        self.syncs.clone()
    }

    async fn call<T>(&self, make: impl FnOnce(oneshot::Sender<T>) -> Command) -> Result<T, Error> {
        let (reply, answer) = oneshot::channel();
        self.commands.send(make(reply)).await.map_err(|_| Error::Closed)?;
        answer.await.map_err(|_| Error::Closed)
    }

    pub(crate) async fn sdo(
        &self,
        node: NodeId,
        index: u16,
        sub: u8,
        op: Op,
        options: SdoOptions,
    ) -> Result<Vec<u8>, Error> {
        self.call(|reply| Command::Sdo(SdoRequest { node, index, sub, op, options, reply })).await?
    }

    /// Puts a frame on the bus as it is.
    pub async fn send(&self, frame: CanFrame) -> Result<(), Error> {
        self.call(|reply| Command::Send(frame, reply)).await?
    }

    /// Sends an NMT command to one node or to all.
    pub async fn nmt(&self, command: NmtCommand, target: Target) -> Result<(), Error> {
        self.send(CanFrame::from(nmt::command(command, target))).await
    }

    /// Watches `node` by heartbeat or node guarding: [`Event::Node`] reports it lost
    /// ([`NodeEvent::Lost`](crate::NodeEvent::Lost)) and recovered, and, with `boot_timeout`, never heard from
    /// ([`NodeEvent::NeverSeen`](crate::NodeEvent::NeverSeen)). Every node that sends a heartbeat is watched anyway without
    /// timeout, for its boot-up and state events.
    pub async fn watch(&self, node: u8, watch: Watch, boot_timeout: Option<Duration>) -> Result<(), Error> {
        let node = NodeId::new(node).ok_or(Error::NodeId(node))?;
        self.call(|reply| Command::Watch { node, watch: Some(watch), boot_timeout, reply }).await
    }

    /// Stops watching `node` for losses (its events are still reported).
    pub async fn unwatch(&self, node: u8) -> Result<(), Error> {
        let node = NodeId::new(node).ok_or(Error::NodeId(node))?;
        self.call(|reply| Command::Watch { node, watch: None, boot_timeout: None, reply }).await
    }

    /// Starts sending SYNC on 080h every `period`, with a counter running 1..=`counter` when
    /// `counter` is 2..=240 (1019h), without one when it is 0. The first SYNC goes out at once.
    pub async fn start_sync(&self, period: Duration, counter: u8) -> Result<(), Error> {
        self.call(|reply| Command::Sync { period: Some(period), counter, reply }).await?
    }

    /// Stops sending SYNC.
    pub async fn stop_sync(&self) -> Result<(), Error> {
        self.call(|reply| Command::Sync { period: None, counter: 0, reply }).await?
    }

    /// Sends one SYNC now (080h, without counter), whether or not SYNC is also sent
    /// periodically ([`start_sync`](Self::start_sync)): for a program that paces the bus
    /// itself, as a test stepping a simulation does.
    ///
    /// ```
    /// # #[tokio::main(flavor = "current_thread")]
    /// # async fn main() {
    /// use od_bus::{Endpoint, MemoryBus};
    /// let wire = MemoryBus::new();
    /// let mut device = wire.endpoint();
    /// let bus = od_master::Bus::start(od_bus::tokio::Bus::attach(&wire), Default::default());
    /// bus.send_sync().await.unwrap();
    /// assert_eq!(device.try_recv().unwrap().unwrap().to_string(), "080#");
    /// # }
    /// ```
    pub async fn send_sync(&self) -> Result<(), Error> {
        self.send(CanFrame::from(SyncProducer::new(0).frame())).await
    }

    /// Sends one heartbeat now as node `id` in `state` (700h + id): the master's own heartbeat
    /// at times the program chooses, where [`Config::heartbeat`] sends it periodically.
    ///
    /// ```
    /// # #[tokio::main(flavor = "current_thread")]
    /// # async fn main() {
    /// use od_bus::{Endpoint, MemoryBus};
    /// let wire = MemoryBus::new();
    /// let mut device = wire.endpoint();
    /// let bus = od_master::Bus::start(od_bus::tokio::Bus::attach(&wire), Default::default());
    /// bus.send_heartbeat(1, od_master::NmtState::Operational).await.unwrap();
    /// assert_eq!(device.try_recv().unwrap().unwrap().to_string(), "701#05");
    /// assert!(bus.send_heartbeat(0, od_master::NmtState::Operational).await.is_err());
    /// # }
    /// ```
    pub async fn send_heartbeat(&self, id: u8, state: NmtState) -> Result<(), Error> {
        let node = NodeId::new(id).ok_or(Error::NodeId(id))?;
        let mut producer = HeartbeatProducer::new(node, 1);
        producer.set_state(state);
        let mut frame = None;
        producer.poll(0, |f| frame = Some(f));
        match frame {
            Some(f) => self.send(CanFrame::from(f)).await,
            None => Ok(()),
        }
    }

    /// Sends an RPDO: `values` packed by `mapping` on `cob_id`.
    pub async fn send_pdo(&self, cob_id: u16, mapping: &PdoMapping, values: &[PdoValue]) -> Result<(), Error> {
        let (data, len) = mapping.encode(values).map_err(|error| Error::Pdo { cob_id, error })?;
        let frame = CanFrame::standard(u32::from(cob_id), &data[..len]).map_err(od_bus::TransportError::from)?;
        self.send(frame).await
    }

    /// Sends an RPDO right before every SYNC from now on, in the same write as the SYNC:
    /// `values` packed by `mapping` on `cob_id`, until [`CyclicPdo::set`] gives others or the
    /// [`CyclicPdo`] is dropped. A synchronous RPDO (transmission type 1..=240) sent so is taken
    /// by the drive at that SYNC: one set-point each period, the latest given, even when the
    /// task that computes them is woken late (it then repeats the one before).
    pub async fn cyclic_pdo(&self, cob_id: u16, mapping: PdoMapping, values: &[PdoValue]) -> Result<CyclicPdo, Error> {
        let pdo = CyclicPdo { bus: self.clone(), cob_id, mapping, owner: Arc::new(()) };
        pdo.set(values).await?;
        Ok(pdo)
    }

    /// Receives the TPDOs on `cob_id` from now on, decoded by `mapping`. Up to `capacity` wait
    /// for the receiver; past that, new ones are dropped until it reads.
    pub async fn tpdo(&self, cob_id: u16, mapping: PdoMapping, capacity: usize) -> Result<mpsc::Receiver<Tpdo>, Error> {
        let (to, from) = mpsc::channel(capacity.max(1));
        self.commands.send(Command::Tpdo { cob_id, mapping, to }).await.map_err(|_| Error::Closed)?;
        Ok(from)
    }

    /// Gives the bus the error texts of `node`'s EMCY codes (from its sidecar:
    /// [`EmcyTexts::from_sidecar`]): its [`Event::Emergency`] events carry them.
    pub async fn set_emcy_texts(&self, node: u8, texts: EmcyTexts) -> Result<(), Error> {
        let node = NodeId::new(node).ok_or(Error::NodeId(node))?;
        self.commands.send(Command::EmcyTexts { node, texts: Arc::new(texts) }).await.map_err(|_| Error::Closed)
    }
}

/// An RPDO the bus sends right before every SYNC ([`Bus::cyclic_pdo`]); dropping it stops it.
#[derive(Debug)]
pub struct CyclicPdo {
    bus: Bus,
    cob_id: u16,
    mapping: PdoMapping,
    /// The bus task keeps a weak reference: the PDO stops when this is dropped.
    owner: Arc<()>,
}

impl CyclicPdo {
    /// The values sent from the next SYNC on.
    pub async fn set(&self, values: &[PdoValue]) -> Result<(), Error> {
        let cob_id = self.cob_id;
        let (data, len) = self.mapping.encode(values).map_err(|error| Error::Pdo { cob_id, error })?;
        let can = CanFrame::standard(u32::from(cob_id), &data[..len]).map_err(od_bus::TransportError::from)?;
        // A standard frame (checked above) always converts.
        let frame = Frame::try_from(can).map_err(od_bus::TransportError::from)?;
        let owner = Arc::downgrade(&self.owner);
        self.bus.commands.send(Command::Cyclic { frame, owner }).await.map_err(|_| Error::Closed)
    }

    /// The bus it is sent on.
    pub fn bus(&self) -> &Bus {
        &self.bus
    }
}

pub(crate) fn micros(d: Duration) -> Micros {
    u64::try_from(d.as_micros()).unwrap_or(u64::MAX)
}

/// One node's SDO channel: the protocol machine, the transfer running and those waiting.
struct Channel {
    client: SdoClient<Vec<u8>>,
    active: Option<Active>,
    queue: VecDeque<SdoRequest>,
}

/// The running request: what to start again on a retry.
struct Active {
    request: SdoRequest,
    attempts: u8,
    /// Waiting for the link to come back, until this time (the transfer is not running).
    parked: Option<Micros>,
}

struct Task {
    tx: BusSender,
    rx: BusReceiver,
    link: watch::Receiver<LinkState>,
    link_open: bool,
    /// Since when the link has been down (`None` while it is up).
    down_since: Option<Micros>,
    /// The nodes something was received from since the start (bit n: node n), by the CiA 301
    /// default identifiers of their EMCY, TPDOs, SDO answers and heartbeats.
    heard: u128,
    commands: mpsc::Receiver<Command>,
    start: Instant,
    channels: HashMap<u8, Channel>,
    monitor: Box<NodeMonitor<127>>,
    heartbeat: Option<HeartbeatProducer>,
    sync: Option<SyncProducer>,
    syncs: watch::Sender<u64>,
    tpdos: HashMap<u16, Vec<(PdoMapping, mpsc::Sender<Tpdo>)>>,
    texts: HashMap<u8, Arc<EmcyTexts>>,
    events: broadcast::Sender<Event>,
    frames: broadcast::Sender<CanFrame>,
    out: Vec<Frame>,
    /// `out` as bus frames, for one write (kept to reuse its allocation).
    wire: Vec<CanFrame>,
    sends: Vec<(CanFrame, oneshot::Sender<Result<(), Error>>)>,
    /// Wakes the task at SYNC time to the microsecond while SYNC runs.
    clock: Option<SyncClock>,
    /// RPDOs sent right before each SYNC, while their owner lives.
    cyclic: Vec<(Frame, Weak<()>)>,
}

/// A waker for the SYNC producer's deadlines: a thread that sleeps until the next SYNC is due
/// and wakes the bus task. tokio's timers tick in whole milliseconds, so a SYNC every 1 ms on
/// them alone leaves 0..1 ms late and skips periods (measured over the hub: 3 393 SYNCs in
/// 5 s instead of 5 000). The task still sleeps on tokio's timer too, whichever comes first:
/// in tests on tokio's paused clock that one runs the show and this thread's wakes are spare.
struct SyncClock {
    shared: Arc<(Mutex<ClockState>, Condvar)>,
    wake: Arc<tokio::sync::Notify>,
}

#[derive(Default)]
struct ClockState {
    /// When to wake the task next.
    at: Option<std::time::Instant>,
    stop: bool,
}

impl SyncClock {
    fn start() -> Option<Self> {
        let shared = Arc::new((Mutex::new(ClockState::default()), Condvar::new()));
        let wake = Arc::new(tokio::sync::Notify::new());
        let (state, w) = (Arc::clone(&shared), Arc::clone(&wake));
        // Without a thread (the system refuses one) SYNC runs on tokio's timer alone.
        std::thread::Builder::new().name("od-master-sync".into()).spawn(move || clock_thread(&state, &w)).ok()?;
        Some(Self { shared, wake })
    }

    /// Wakes the task `after` from now (or not at all).
    fn set(&self, after: Option<Duration>) {
        let at = after.map(|d| std::time::Instant::now() + d);
        let (state, changed) = &*self.shared;
        let mut s = state.lock().unwrap_or_else(|e| e.into_inner());
        // A change of less than 20 µs is the same deadline seen a little later.
        let same = match (s.at, at) {
            (Some(a), Some(b)) => a.max(b) - a.min(b) < Duration::from_micros(20),
            (a, b) => a.is_none() && b.is_none(),
        };
        if !same {
            s.at = at;
            changed.notify_one();
        }
    }
}

impl Drop for SyncClock {
    fn drop(&mut self) {
        let (state, changed) = &*self.shared;
        state.lock().unwrap_or_else(|e| e.into_inner()).stop = true;
        changed.notify_one();
    }
}

fn clock_thread(shared: &(Mutex<ClockState>, Condvar), wake: &tokio::sync::Notify) {
    let (state, changed) = shared;
    let mut s = state.lock().unwrap_or_else(|e| e.into_inner());
    loop {
        if s.stop {
            return;
        }
        s = match s.at {
            None => changed.wait(s).unwrap_or_else(|e| e.into_inner()),
            Some(at) => {
                let now = std::time::Instant::now();
                if now >= at {
                    s.at = None;
                    wake.notify_one();
                    continue;
                }
                changed.wait_timeout(s, at - now).unwrap_or_else(|e| e.into_inner()).0
            }
        };
    }
}

/// Frames and commands taken at most in one turn of the bus task before it sends what they
/// made (a flood of frames must not hold back the SDO timeouts and SYNCs of [`Task::poll`]).
const MAX_TAKEN: usize = 64;

/// Whether a failed transfer may be started again: the answer got lost or garbled on the way
/// (timeout, toggle bit, sequence, CRC, command specifier: the 0503xxxxh and 0504xxxxh codes,
/// from either side), not refused by the server for what it is, nor too large for the buffer.
fn retriable(error: SdoError) -> bool {
    let code = error.code();
    matches!(code.0 >> 16, 0x0503 | 0x0504) && code != AbortCode::OUT_OF_MEMORY
}

impl Task {
    fn now(&self) -> Micros {
        micros(self.start.elapsed())
    }

    async fn run(mut self) {
        loop {
            let now = self.now();
            self.poll(now);
            self.flush().await;
            let wake = self.deadline().map(|d| self.start + Duration::from_micros(d));
            if let Some(clock) = &self.clock {
                let due = self.sync.as_ref().and_then(SyncProducer::deadline);
                let start = self.start;
                clock.set(due.map(|d| (start + Duration::from_micros(d)).saturating_duration_since(Instant::now())));
            }
            let precise = self.clock.as_ref().map(|c| Arc::clone(&c.wake));
            tokio::select! {
                () = notified(precise) => {}
                command = self.commands.recv() => match command {
                    Some(command) => {
                        self.command(command);
                        self.take_waiting();
                    }
                    None => return,
                },
                frame = self.rx.recv() => match frame {
                    Ok(frame) => {
                        self.frame(frame);
                        self.take_waiting();
                    }
                    Err(_) => {
                        self.close();
                        return;
                    }
                },
                changed = self.link.changed(), if self.link_open => match changed {
                    Ok(()) => {
                        let state = self.link.borrow_and_update().clone();
                        self.link_changed(&state);
                        let _ = self.events.send(Event::Link(state));
                    }
                    // A bus whose link never changes (memory, SocketCAN).
                    Err(_) => self.link_open = false,
                },
                () = sleep_until(wake) => {}
            }
        }
    }

    /// Takes the frames and commands that are already waiting (answers of several nodes that
    /// came in one read, calls of several tasks), so that what they make the machines send goes
    /// out together, in one write. What is closed or empty is left to the `select!` to find.
    fn take_waiting(&mut self) {
        for _ in 0..MAX_TAKEN {
            let mut took = false;
            if let Ok(Some(frame)) = self.rx.try_recv() {
                self.frame(frame);
                took = true;
            }
            if let Ok(command) = self.commands.try_recv() {
                self.command(command);
                took = true;
            }
            if !took {
                return;
            }
        }
    }

    /// A boot-up of `node`, heard from before: the node forgot the transfer running on its SDO
    /// channel, so it ends
    /// at once (waiting for its timeout would only delay the node's reconfiguration). A read or
    /// an idempotent write starts again at once, as after a lost answer, while its retries
    /// last (a node that boots while a master reads its identity answers the read it gets
    /// after its boot-up); any other transfer, running or waiting, ends with
    /// [`Error::Rebooted`]: a plain write meant for the node as it was is not sent to the node
    /// as it is now. Reads and idempotent writes that wait keep their place. All before the
    /// boot-up event goes out.
    fn rebooted(&mut self, node: u8, now: Micros) {
        let Some(channel) = self.channels.get_mut(&node) else { return };
        let repeatable = |request: &SdoRequest| match &request.op {
            Op::Upload(_) => true,
            Op::Download { idempotent, .. } => *idempotent,
        };
        if let Some(mut active) = channel.active.take() {
            // The machine is made idle; its abort frame, if the request was on the bus, is
            // ignored by a server that has no transfer.
            let _ = channel.client.abort(AbortCode::GENERAL_ERROR);
            let again = active.parked.is_none()
                && repeatable(&active.request)
                && active.attempts <= active.request.options.retries
                && !active.request.reply.is_closed();
            if again && start(&mut channel.client, &active.request, now).is_ok() {
                active.attempts += 1;
                channel.active = Some(active);
            } else if active.parked.is_some() && repeatable(&active.request) {
                // Waiting for the link: it starts once the link is back, on the node as it is.
                channel.active = Some(active);
            } else {
                let (index, sub) = (active.request.index, active.request.sub);
                let _ = active.request.reply.send(Err(Error::Rebooted { node, index, sub }));
            }
        }
        let (keep, ended): (VecDeque<_>, VecDeque<_>) = channel.queue.drain(..).partition(|r| repeatable(r));
        channel.queue = keep;
        for request in ended {
            let (index, sub) = (request.index, request.sub);
            let _ = request.reply.send(Err(Error::Rebooted { node, index, sub }));
        }
        if channel.active.is_none() {
            self.next(node, now);
        }
    }

    /// Ends every transfer with [`Error::Closed`].
    fn close(&mut self) {
        let _ = self.events.send(Event::Link(LinkState::Closed));
        for (_, channel) in self.channels.drain() {
            if let Some(active) = channel.active {
                let _ = active.request.reply.send(Err(Error::Closed));
            }
            for request in channel.queue {
                let _ = request.reply.send(Err(Error::Closed));
            }
        }
    }

    fn deadline(&self) -> Option<Micros> {
        let parked = self.channels.values().filter_map(|c| c.active.as_ref().and_then(|a| a.parked));
        let sdo = self.channels.values().filter_map(|c| c.client.deadline()).chain(parked);
        let others = [
            self.monitor.deadline(),
            self.heartbeat.as_ref().and_then(HeartbeatProducer::deadline),
            self.sync.as_ref().and_then(SyncProducer::deadline),
        ];
        sdo.chain(others.into_iter().flatten()).min()
    }

    fn poll(&mut self, now: Micros) {
        let out = &mut self.out;
        let mut finished = Vec::new();
        for channel in self.channels.values_mut() {
            if let Some(done) = channel.client.poll(now, &mut |f| out.push(f)) {
                finished.push(done);
            }
        }
        for done in finished {
            self.finish(done, now);
        }
        self.give_up_parked(now);
        let out = &mut self.out;
        let events = &self.events;
        self.monitor.poll(
            now,
            |f| out.push(f),
            |e| {
                let _ = events.send(Event::Node(e));
            },
        );
        if let Some(hb) = &mut self.heartbeat {
            hb.poll(now, |f| out.push(f));
        }
        if let Some(sync) = &mut self.sync {
            let mut sent = 0;
            let cyclic = &mut self.cyclic;
            sync.poll(now, |f| {
                cyclic.retain(|(_, owner)| owner.strong_count() > 0);
                out.extend(cyclic.iter().map(|(frame, _)| *frame));
                out.push(f);
                sent += 1;
            });
            if sent > 0 {
                self.syncs.send_modify(|n| *n += sent);
            }
        }
    }

    /// Sends what the machines produced, then the frames callers asked for (each told how it
    /// went). A machine's frame that cannot be sent (a socketcand link that is down) is lost
    /// like a frame lost on the wire: the SDO timeout and retries deal with it.
    async fn flush(&mut self) {
        self.wire.clear();
        self.wire.extend(self.out.drain(..).map(CanFrame::from));
        if !self.wire.is_empty() {
            let _ = self.tx.send_all(&self.wire).await;
        }
        for (frame, reply) in std::mem::take(&mut self.sends) {
            let _ = reply.send(self.tx.send(frame).await.map_err(Error::from));
        }
    }

    fn command(&mut self, command: Command) {
        let now = self.now();
        match command {
            Command::Sdo(request) => {
                let node = request.node.get();
                let channel = self.channels.entry(node).or_insert_with(|| Channel {
                    client: SdoClient::new(request.node),
                    active: None,
                    queue: VecDeque::new(),
                });
                channel.queue.push_back(request);
                self.next(node, now);
            }
            Command::Send(frame, reply) => self.sends.push((frame, reply)),
            Command::Watch { node, watch, boot_timeout, reply } => {
                let watch = watch.unwrap_or(Watch::Heartbeat { timeout: 0 });
                // The table has a slot for each of the 127 node ids: it cannot be full.
                let _ = self.monitor.watch(node, watch, boot_timeout.map(micros), now);
                let _ = reply.send(());
            }
            Command::Sync { period, counter, reply } => {
                let result = match period {
                    None => {
                        self.sync = None;
                        self.clock = None;
                        Ok(())
                    }
                    Some(period) => match SyncProducer::new(micros(period).max(1)).with_counter(counter) {
                        Ok(mut sync) => {
                            sync.start(now);
                            self.sync = Some(sync);
                            if self.clock.is_none() {
                                self.clock = SyncClock::start();
                            }
                            Ok(())
                        }
                        Err(_) => Err(Error::SyncCounter(counter)),
                    },
                };
                let _ = reply.send(result);
            }
            Command::Tpdo { cob_id, mapping, to } => self.tpdos.entry(cob_id).or_default().push((mapping, to)),
            Command::Cyclic { frame, owner } => match self.cyclic.iter_mut().find(|(_, o)| o.ptr_eq(&owner)) {
                Some(entry) => entry.0 = frame,
                None => self.cyclic.push((frame, owner)),
            },
            Command::EmcyTexts { node, texts } => {
                self.texts.insert(node.get(), texts);
            }
        }
    }

    /// Starts the next waiting transfer of `node` if its channel is free.
    fn next(&mut self, node: u8, now: Micros) {
        let Some(channel) = self.channels.get_mut(&node) else { return };
        while channel.active.is_none() {
            let Some(request) = channel.queue.pop_front() else { return };
            if request.reply.is_closed() {
                // The caller stopped waiting before the transfer began.
                continue;
            }
            if link_down(&self.link) && !request.options.link_wait.is_zero() {
                // Nothing would go out: wait for the link instead.
                let parked = Some(now.saturating_add(micros(request.options.link_wait)));
                channel.active = Some(Active { request, attempts: 0, parked });
                return;
            }
            match start(&mut channel.client, &request, now) {
                Ok(()) => channel.active = Some(Active { request, attempts: 1, parked: None }),
                Err(error) => {
                    let _ = request.reply.send(Err(error));
                }
            }
        }
    }

    /// A transfer ended: answer its caller, or start it again when the rules allow.
    fn finish(&mut self, done: Done<Vec<u8>>, now: Micros) {
        let node = done.node;
        let link = self.link_context(now);
        let heard = self.heard & (1 << node) != 0;
        let Some(channel) = self.channels.get_mut(&node) else { return };
        let Some(mut active) = channel.active.take() else { return };
        match done.result {
            Ok(n) => {
                let mut buf = done.buf;
                buf.truncate(n);
                if matches!(active.request.op, Op::Download { .. }) {
                    buf.clear();
                }
                let _ = active.request.reply.send(Ok(buf));
            }
            Err(error) => {
                let may_repeat = match &active.request.op {
                    Op::Upload(_) => true,
                    Op::Download { idempotent, .. } => *idempotent,
                };
                let retry = retriable(error)
                    && may_repeat
                    && active.attempts <= active.request.options.retries
                    && !active.request.reply.is_closed();
                let link_wait = active.request.options.link_wait;
                if link.is_some()
                    && retriable(error)
                    && may_repeat
                    && !link_wait.is_zero()
                    && !active.request.reply.is_closed()
                {
                    // Lost to a link that is down: start again once it is back.
                    active.parked = Some(now.saturating_add(micros(link_wait)));
                    channel.active = Some(active);
                    return;
                }
                if retry && link.is_none() && start(&mut channel.client, &active.request, now).is_ok() {
                    active.attempts += 1;
                    channel.active = Some(active);
                    return;
                }
                let context = match link {
                    Some(link) => Some(link),
                    None if error.is_timeout() && !heard => Some(SdoContext::NeverHeard),
                    None => None,
                };
                let error = TransferError { node, direction: done.direction, index: done.index, sub: done.sub, error };
                let _ = active.request.reply.send(Err(Error::Sdo { error, attempts: active.attempts, context }));
            }
        }
        self.next(node, now);
    }

    fn frame(&mut self, can: CanFrame) {
        if self.frames.receiver_count() > 0 {
            let _ = self.frames.send(can);
        }
        // Extended frames are no CANopen service's.
        let Ok(frame) = Frame::try_from(can) else { return };
        let now = self.now();
        let id = frame.id();
        let from = id & 0x7F;
        // A boot-up from a node heard before is a reboot; a node's first boot-up (a master that
        // started first, a drive powered on) ends none of the transfers it may yet answer.
        let heard_before = from != 0 && self.heard & (1 << from) != 0;
        // EMCY, TPDO 1..4, SDO answer, heartbeat: the node is on the bus.
        if from != 0 && matches!(id >> 7, 0x1 | 0x3 | 0x5 | 0x7 | 0x9 | 0xB | 0xE) {
            self.heard |= 1 << from;
        }
        if (0x581..=0x5FF).contains(&id)
            && let Some(channel) = self.channels.get_mut(&((id - 0x580) as u8))
            && let Some(done) = channel.client.on_frame(&frame, now)
        {
            self.finish(done, now);
        }
        if (0x701..=0x77F).contains(&id) && !frame.is_rtr() {
            let node = NodeId::new((id - 0x700) as u8);
            let mut event = self.monitor.on_frame(&frame, now);
            if let Some(node) = node
                && event.is_none()
                && self.monitor.state(node).is_none()
                && frame.len() == 1
            {
                // A node not watched yet: watch it without timeout, for its events.
                let _ = self.monitor.watch(node, Watch::Heartbeat { timeout: 0 }, None, now);
                event = self.monitor.on_frame(&frame, now);
            }
            if let Some(node_event) = event {
                if let od_runtime::master::NodeEvent::BootUp { node } = node_event
                    && heard_before
                {
                    self.rebooted(node, now);
                }
                let _ = self.events.send(Event::Node(node_event));
            }
        }
        if let Some(emcy) = Emergency::from_frame(&frame) {
            let text = self.texts.get(&emcy.node).and_then(|t| t.text(&emcy)).map(str::to_owned);
            let _ = self.events.send(Event::Emergency { emcy, text });
        }
        if let Some(subscribers) = self.tpdos.get_mut(&id) {
            let at = Instant::now();
            subscribers.retain(|(mapping, to)| {
                if to.is_closed() {
                    return false;
                }
                let mut values = vec![PdoValue::Unsigned(0); mapping.fields().len()];
                match mapping.decode(frame.data(), &mut values) {
                    Ok(_) => {
                        let _ = to.try_send(Tpdo { cob_id: id, at, values });
                    }
                    Err(error) => {
                        let _ = self.events.send(Event::PdoError { cob_id: id, error });
                    }
                }
                true
            });
        }
    }
}

impl Task {
    /// The link went down or came back: transfers waiting for it start again.
    fn link_changed(&mut self, state: &LinkState) {
        let now = self.now();
        match state {
            LinkState::Up { .. } => {
                self.down_since = None;
                let nodes: Vec<u8> = self.channels.keys().copied().collect();
                for node in nodes {
                    let Some(channel) = self.channels.get_mut(&node) else { continue };
                    let Some(active) = channel.active.as_mut().filter(|a| a.parked.is_some()) else { continue };
                    active.parked = None;
                    match start(&mut channel.client, &active.request, now) {
                        Ok(()) => active.attempts = active.attempts.saturating_add(1),
                        Err(error) => {
                            if let Some(active) = channel.active.take() {
                                let _ = active.request.reply.send(Err(error));
                            }
                            self.next(node, now);
                        }
                    }
                }
            }
            LinkState::Down { .. } => {
                self.down_since.get_or_insert(now);
            }
            LinkState::Closed => {}
        }
    }

    /// What to say about the link when a transfer fails now: `Some` while it is down.
    fn link_context(&self, now: Micros) -> Option<SdoContext> {
        match &*self.link.borrow() {
            LinkState::Down { reason, .. } => Some(SdoContext::LinkDown {
                reason: reason.clone(),
                down_for: Duration::from_micros(now.saturating_sub(self.down_since.unwrap_or(now))),
            }),
            _ => None,
        }
    }

    /// Transfers that waited for the link as long as they may fail, saying it is down.
    fn give_up_parked(&mut self, now: Micros) {
        let due: Vec<u8> = self
            .channels
            .iter()
            .filter(|(_, c)| c.active.as_ref().and_then(|a| a.parked).is_some_and(|at| at <= now))
            .map(|(n, _)| *n)
            .collect();
        for node in due {
            let context = self.link_context(now).or_else(|| {
                Some(SdoContext::LinkDown { reason: "link state unknown".into(), down_for: Duration::ZERO })
            });
            let Some(active) = self.channels.get_mut(&node).and_then(|c| c.active.take()) else { continue };
            let r = &active.request;
            let direction = match r.op {
                Op::Upload(_) => Direction::Upload,
                Op::Download { .. } => Direction::Download,
            };
            let error = TransferError {
                node,
                direction,
                index: r.index,
                sub: r.sub,
                error: SdoError::Client(AbortCode::TIMEOUT),
            };
            let _ = active.request.reply.send(Err(Error::Sdo { error, attempts: active.attempts, context }));
            self.next(node, now);
        }
    }
}

fn link_down(link: &watch::Receiver<LinkState>) -> bool {
    matches!(*link.borrow(), LinkState::Down { .. })
}

/// Starts `request` on `client`, with the request's timeout.
fn start(client: &mut SdoClient<Vec<u8>>, request: &SdoRequest, now: Micros) -> Result<(), Error> {
    client.set_timeout(micros(request.options.timeout));
    client.set_block_fallback(request.options.block_fallback);
    let (node, index, sub) = (request.node.get(), request.index, request.sub);
    let started = match &request.op {
        Op::Upload(capacity) => client.upload(index, sub, vec![0; *capacity], request.options.mode, now),
        Op::Download { data, .. } => client.download(index, sub, data.clone(), request.options.mode, now),
    };
    started.map_err(|rejected| {
        let len = rejected.buf.len();
        Error::TooLong { node, index, sub, len }
    })
}

async fn notified(wake: Option<Arc<tokio::sync::Notify>>) {
    match wake {
        Some(wake) => wake.notified().await,
        None => std::future::pending().await,
    }
}

async fn sleep_until(wake: Option<Instant>) {
    match wake {
        Some(at) => tokio::time::sleep_until(at).await,
        None => std::future::pending().await,
    }
}
