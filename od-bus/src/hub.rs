//! A socketcand-compatible TCP hub: a software CAN bus that masters and devices join over TCP.
//!
//! Every client is greeted with `< hi >`, opens a channel by any name (`< open can0 >`) and
//! switches to raw mode (`< rawmode >`); from then on it receives every frame the other members
//! of that channel send. A channel is one CAN bus; channels are created on first use and are
//! independent of each other. In-process devices join a channel with [`Hub::attach`].
//!
//! Threads: one accepting connections, and per client one reading (parsing commands, relaying
//! frames) and one writing (draining the client's send queue). Relaying never blocks: a frame
//! goes straight into a member's socket when the socket takes it at once and nothing is queued
//! for that member (on Linux; this saves a thread wake-up per frame and member, which is most
//! of a relay's cost), and into the member's bounded queue otherwise, for its writer thread. A
//! member whose queue is full (it reads more slowly than the bus runs) loses frames, counted
//! and logged at most once per [`HubConfig::drop_report_interval`], and keeps its connection:
//! it cannot hold up the others.
//!
//! Load and faults:
//! * Admission: up to [`HubConfig::max_clients`] connections (1024 by default; each costs a
//!   socket and two threads). A connection must open a channel within
//!   [`HubConfig::open_timeout`] (5 s). When the hub is full, the connection that has been idle
//!   longest among those that never sent a frame is closed to make room, so a master always
//!   gets in past silent or stuck clients; only when every client has sent frames is the new
//!   one refused.
//! * Floods: a client sending faster than [`HubConfig::max_rate`] frames per second is slowed
//!   down (its reader pauses, so TCP pushes back on it); the others keep their share.
//! * With [`HubConfig::bitrate`] every channel is an emulated wire ([`crate::wire`]): it
//!   carries what a CAN bus of that bit rate carries, frames arbitrated by identifier, and a
//!   client sending more waits for the wire.

use std::collections::HashMap;
use std::fmt;
use std::io::{self, Read, Write};
use std::net::{IpAddr, Ipv4Addr, Ipv6Addr, Shutdown, SocketAddr, TcpListener, TcpStream, ToSocketAddrs};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex, Weak};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crate::bus::{Channel, LocalEndpoint};
use crate::error::TransportError;
use crate::frame::CanFrame;
use crate::queue::{BoundedQueue, PushError, lock};
use crate::sink::{Delivery, MemberId, Sink, next_member_id};
use crate::socketcand::{Decoder, Message, ParseError, parse_channel};
use crate::timestamp::Timestamp;

/// Receives every [`HubEvent`]; called from the hub's threads, so it must be quick.
pub type HubObserver = Arc<dyn Fn(&HubEvent) + Send + Sync>;

/// Settings of a [`Hub`].
#[derive(Clone)]
pub struct HubConfig {
    /// Connections served at once. When full, the longest-idle connection that never sent a
    /// frame is closed for a new one; if every client sent frames, the new one is answered
    /// `< error ... >` and closed.
    pub max_clients: usize,
    /// Frames queued for one TCP client; further frames are dropped for it (counted) until it
    /// catches up.
    pub client_queue: usize,
    /// Frames queued for one in-process endpoint before further frames are dropped.
    pub endpoint_queue: usize,
    /// A write to a client that blocks this long (the client reads nothing at all, say `dump`
    /// piped into a pager that waits) disconnects it. Frames beyond its queue are dropped
    /// meanwhile; the blocked writer costs one thread.
    pub write_timeout: Duration,
    /// A client that has not opened a channel this long after connecting (the handshake) is
    /// disconnected. (After `open`, silence is normal: a client may only listen.)
    pub open_timeout: Duration,
    /// Frames per second one client may send; faster senders are slowed down (the hub stops
    /// reading from them for a while). 0: no limit.
    pub max_rate: u32,
    /// Emulate a CAN bus of this many bits per second on every channel (see
    /// [`crate::wire`]); `None`: frames are relayed as fast as they come.
    pub bitrate: Option<u32>,
    /// Frames dropped for a slow client are logged (and reported to clients that asked with
    /// `< dropreport >`) at most this often.
    pub drop_report_interval: Duration,
    /// Pause after the `< ok >` to `< rawmode >` (the reply frames follow) before the next frame
    /// goes to that client. python-can reads
    /// each handshake reply with one `recv` and compares the whole text with `< ok >`, so a
    /// frame arriving right behind the reply (likely on a bus busy with heartbeats) would make
    /// its connect fail; frames meanwhile are queued, not lost.
    pub reply_pause: Duration,
    /// Where events go; [`HubConfig::default`] prints them to stderr.
    pub observer: HubObserver,
    /// The channels this hub serves; opening another is refused (`< error channel can1 is not
    /// served here; this hub serves can0 >`), so that a misspelt channel is not an empty bus.
    /// Empty (the default): any name, each channel made when first used; a channel opened
    /// while others have members and it has none is then reported
    /// ([`HubEvent::LoneChannel`]).
    pub channels: Vec<String>,
}

impl HubConfig {
    /// Protocol errors reported per client before further ones are only counted.
    pub const LOGGED_ERRORS_PER_CLIENT: u32 = 10;

    /// The same settings with every event discarded.
    pub fn quiet(self) -> Self {
        self.with_observer(Arc::new(|_: &HubEvent| {}))
    }

    /// The same settings with events sent to `observer`.
    pub fn with_observer(self, observer: HubObserver) -> Self {
        Self { observer, ..self }
    }
}

impl Default for HubConfig {
    fn default() -> Self {
        Self {
            max_clients: 1024,
            client_queue: 4096,
            endpoint_queue: 4096,
            write_timeout: Duration::from_secs(60),
            open_timeout: Duration::from_secs(5),
            max_rate: 20_000,
            bitrate: None,
            drop_report_interval: Duration::from_secs(1),
            reply_pause: Duration::from_millis(50),
            observer: Arc::new(|event: &HubEvent| eprintln!("hub: {event}")),
            channels: Vec::new(),
        }
    }
}

impl fmt::Debug for HubConfig {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("HubConfig")
            .field("max_clients", &self.max_clients)
            .field("client_queue", &self.client_queue)
            .field("endpoint_queue", &self.endpoint_queue)
            .field("write_timeout", &self.write_timeout)
            .field("open_timeout", &self.open_timeout)
            .field("reply_pause", &self.reply_pause)
            .field("max_rate", &self.max_rate)
            .field("bitrate", &self.bitrate)
            .field("drop_report_interval", &self.drop_report_interval)
            .field("channels", &self.channels)
            .finish_non_exhaustive()
    }
}

/// Something that happened in a [`Hub`], for logging. `Display` gives the log line.
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub enum HubEvent {
    /// The hub accepts connections.
    Listening {
        /// Bound address (with the real port when 0 was asked for).
        addr: SocketAddr,
    },
    /// A client connected.
    Connected {
        /// Client number, unique in the process.
        client: u64,
        /// Its address.
        peer: SocketAddr,
    },
    /// A connection was refused.
    Rejected {
        /// Its address.
        peer: SocketAddr,
        /// Why.
        reason: String,
    },
    /// A client opened a channel.
    Opened {
        /// Client number.
        client: u64,
        /// Its address.
        peer: SocketAddr,
        /// Channel name.
        channel: String,
    },
    /// A client opened a channel nothing else is on while other channels have members: a
    /// misspelt channel name, most likely (it sees an empty bus).
    LoneChannel {
        /// Client number.
        client: u64,
        /// Its address.
        peer: SocketAddr,
        /// The channel it opened.
        channel: String,
        /// The channels that have members, sorted.
        others: Vec<String>,
    },
    /// A client entered raw mode and now receives the channel's frames.
    RawMode {
        /// Client number.
        client: u64,
        /// Its address.
        peer: SocketAddr,
    },
    /// A client sent something malformed or out of place.
    ProtocolError {
        /// Client number.
        client: u64,
        /// Its address.
        peer: SocketAddr,
        /// What was wrong.
        error: String,
    },
    /// A client made more than [`HubConfig::LOGGED_ERRORS_PER_CLIENT`] errors; the rest are
    /// not logged (each is still answered).
    ErrorsSuppressed {
        /// Client number.
        client: u64,
        /// Its address.
        peer: SocketAddr,
    },
    /// A client sends commands and does not read the replies: even its room for replies is full;
    /// it is being disconnected. (Frames are dropped for a slow reader instead, see
    /// [`HubEvent::FramesDropped`].)
    Overflow {
        /// Client number.
        client: u64,
        /// Its address.
        peer: SocketAddr,
        /// The queue length that was exceeded.
        capacity: usize,
    },
    /// The hub was full: this client, idle longest of those that never sent a frame, was
    /// closed to make room for a new connection.
    Evicted {
        /// Client number.
        client: u64,
        /// Its address.
        peer: SocketAddr,
        /// How long it had sent nothing.
        idle: Duration,
    },
    /// A client reads more slowly than the bus runs: frames were dropped for it (reported at
    /// most once per [`HubConfig::drop_report_interval`]).
    FramesDropped {
        /// Client number.
        client: u64,
        /// Its address.
        peer: SocketAddr,
        /// Dropped since the last report.
        dropped: u64,
        /// Dropped since it connected.
        total: u64,
    },
    /// An in-process endpoint's queue is full and frames are being dropped (reported at 1, 2,
    /// 4, 8 ... drops).
    EndpointOverflow {
        /// Its channel.
        channel: String,
        /// Frames dropped so far.
        dropped: u64,
    },
    /// A client is gone.
    Disconnected {
        /// Client number.
        client: u64,
        /// Its address.
        peer: SocketAddr,
        /// Why.
        reason: String,
    },
    /// `accept` failed (for instance the process ran out of file descriptors).
    AcceptFailed {
        /// The OS error.
        error: String,
    },
    /// The hub stopped.
    Stopped,
}

impl fmt::Display for HubEvent {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            HubEvent::Listening { addr } => write!(f, "listening on {addr}"),
            HubEvent::Connected { client, peer } => write!(f, "client {client} ({peer}) connected"),
            HubEvent::Rejected { peer, reason } => write!(f, "connection from {peer} refused: {reason}"),
            HubEvent::Opened { client, peer, channel } => {
                write!(f, "client {client} ({peer}) opened channel {channel}")
            }
            HubEvent::LoneChannel { client, peer, channel, others } => write!(
                f,
                "client {client} ({peer}) opened channel {channel}, which nothing else is on (channels in use: {}): \
                 a misspelt channel name?",
                others.join(", ")
            ),
            HubEvent::RawMode { client, peer } => write!(f, "client {client} ({peer}) entered raw mode"),
            HubEvent::ProtocolError { client, peer, error } => write!(f, "client {client} ({peer}): {error}"),
            HubEvent::ErrorsSuppressed { client, peer } => {
                write!(f, "client {client} ({peer}): further protocol errors not logged")
            }
            HubEvent::Overflow { client, peer, capacity } => write!(
                f,
                "client {client} ({peer}) disconnected: it fell {capacity} replies behind (it does not read what it asked for)"
            ),
            HubEvent::Evicted { client, peer, idle } => write!(
                f,
                "client {client} ({peer}) closed to make room: the hub is full and it sent no frame (idle {:.1} s)",
                idle.as_secs_f64()
            ),
            HubEvent::FramesDropped { client, peer, dropped, total } => write!(
                f,
                "client {client} ({peer}) reads more slowly than the bus runs: {dropped} frames dropped for it ({total} in all)"
            ),
            HubEvent::EndpointOverflow { channel, dropped } => {
                write!(f, "in-process endpoint on channel {channel} is not reading: {dropped} frames dropped")
            }
            HubEvent::Disconnected { client, peer, reason } => {
                write!(f, "client {client} ({peer}) disconnected: {reason}")
            }
            HubEvent::AcceptFailed { error } => write!(f, "accept failed: {error}"),
            HubEvent::Stopped => write!(f, "stopped"),
        }
    }
}

/// A running socketcand hub. Dropping it stops it (as does [`Hub::stop`]): the listener
/// closes, every client is disconnected and every attached endpoint reports
/// [`TransportError::Closed`].
///
/// ```
/// use std::time::Duration;
/// use od_bus::{CanFrame, Endpoint, Hub, HubConfig, SocketcandClient};
///
/// let hub = Hub::bind("127.0.0.1:0", HubConfig::default().quiet()).unwrap();
/// let mut device = hub.attach("can0").unwrap();
/// let mut master = SocketcandClient::connect(hub.local_addr(), "can0").unwrap();
/// master.send(CanFrame::standard(0x000, &[0x01, 0x00]).unwrap()).unwrap();
/// let nmt = device.recv_timeout(Duration::from_secs(5)).unwrap().unwrap();
/// assert_eq!(nmt.data(), &[0x01, 0x00]);
/// ```
pub struct Hub {
    inner: Arc<HubInner>,
    accept: Mutex<Option<JoinHandle<()>>>,
}

struct HubInner {
    config: HubConfig,
    local_addr: SocketAddr,
    channels: Mutex<HashMap<String, Weak<Channel>>>,
    connections: Mutex<HashMap<u64, ConnectionEntry>>,
    stopping: AtomicBool,
    /// Origin of the connections' activity times.
    epoch: Instant,
}

struct ConnectionEntry {
    connection: Arc<Connection>,
    threads: Vec<JoinHandle<()>>,
}

impl Hub {
    /// Binds `addr` (use port 0 for a free port, then [`local_addr`](Hub::local_addr)) and
    /// starts accepting clients on a background thread.
    pub fn bind(addr: impl ToSocketAddrs, config: HubConfig) -> Result<Self, TransportError> {
        let listener = TcpListener::bind(addr).map_err(|e| TransportError::io("cannot listen", e))?;
        let local_addr = listener.local_addr().map_err(|e| TransportError::io("cannot read the bound address", e))?;
        let inner = Arc::new(HubInner {
            config,
            local_addr,
            channels: Mutex::new(HashMap::new()),
            connections: Mutex::new(HashMap::new()),
            stopping: AtomicBool::new(false),
            epoch: Instant::now(),
        });
        inner.emit(&HubEvent::Listening { addr: local_addr });
        let accept = {
            let inner = Arc::clone(&inner);
            std::thread::Builder::new()
                .name("hub-accept".into())
                .spawn(move || inner.accept_loop(&listener))
                .map_err(|e| TransportError::io("cannot start the accept thread", e))?
        };
        Ok(Self { inner, accept: Mutex::new(Some(accept)) })
    }

    /// The address clients connect to.
    pub fn local_addr(&self) -> SocketAddr {
        self.inner.local_addr
    }

    /// Attaches an in-process endpoint to `channel` (created if no client opened it yet). It
    /// receives what TCP clients in raw mode and other endpoints of the channel send, and they
    /// receive what it sends.
    pub fn attach(&self, channel: &str) -> Result<LocalEndpoint, TransportError> {
        if self.inner.stopping.load(Ordering::SeqCst) {
            return Err(TransportError::Closed);
        }
        let name = parse_channel(channel).map_err(|e| TransportError::Protocol(e.to_string()))?.to_owned();
        let channel = self.inner.channel(&name)?;
        let observer = Arc::clone(&self.inner.config.observer);
        let hook = Box::new(move |dropped| observer(&HubEvent::EndpointOverflow { channel: name.clone(), dropped }));
        Ok(LocalEndpoint::attach(channel, self.inner.config.endpoint_queue, Some(hook)))
    }

    /// Clients currently connected.
    pub fn client_count(&self) -> usize {
        lock(&self.inner.connections).len()
    }

    /// Names of the channels that have members, sorted.
    pub fn channels(&self) -> Vec<String> {
        self.inner.channel_names()
    }

    /// Stops the hub: closes the listener, disconnects every client, closes every attached
    /// endpoint and waits for the hub's threads. Calling it again does nothing.
    pub fn stop(&self) {
        if self.inner.stopping.swap(true, Ordering::SeqCst) {
            return;
        }
        // accept() has no timeout: wake it with a connection of our own, which it drops.
        let woke = TcpStream::connect_timeout(&wake_address(self.inner.local_addr), Duration::from_secs(1)).is_ok();
        if let Some(handle) = lock(&self.accept).take()
            && woke
        {
            let _ = handle.join();
        }
        let entries = std::mem::take(&mut *lock(&self.inner.connections));
        for entry in entries.values() {
            entry.connection.kill("hub stopped");
        }
        for entry in entries.into_values() {
            for thread in entry.threads {
                let _ = thread.join();
            }
        }
        let channels: Vec<Arc<Channel>> = lock(&self.inner.channels).drain().filter_map(|(_, c)| c.upgrade()).collect();
        for channel in channels {
            channel.close_all();
        }
        self.inner.emit(&HubEvent::Stopped);
    }
}

impl Drop for Hub {
    fn drop(&mut self) {
        self.stop();
    }
}

impl fmt::Debug for Hub {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Hub")
            .field("local_addr", &self.inner.local_addr)
            .field("clients", &self.client_count())
            .finish()
    }
}

/// Where to connect to reach a listener bound to `addr` (the loopback address when it listens
/// on all interfaces).
fn wake_address(addr: SocketAddr) -> SocketAddr {
    match addr.ip() {
        IpAddr::V4(ip) if ip.is_unspecified() => SocketAddr::new(Ipv4Addr::LOCALHOST.into(), addr.port()),
        IpAddr::V6(ip) if ip.is_unspecified() => SocketAddr::new(Ipv6Addr::LOCALHOST.into(), addr.port()),
        _ => addr,
    }
}

impl HubInner {
    fn emit(&self, event: &HubEvent) {
        (self.config.observer)(event);
    }

    /// Names of the channels that have members, sorted.
    fn channel_names(&self) -> Vec<String> {
        let mut names: Vec<String> = lock(&self.channels)
            .iter()
            .filter(|(_, channel)| channel.strong_count() > 0)
            .map(|(name, _)| name.clone())
            .collect();
        names.sort();
        names
    }

    fn channel(&self, name: &str) -> Result<Arc<Channel>, TransportError> {
        let mut channels = lock(&self.channels);
        if let Some(channel) = channels.get(name).and_then(Weak::upgrade) {
            return Ok(channel);
        }
        channels.retain(|_, channel| channel.strong_count() > 0);
        let channel = match self.config.bitrate {
            Some(bitrate) => Channel::with_bitrate(name, bitrate)
                .map_err(|e| TransportError::io("cannot start the channel's wire thread", e))?,
            None => Arc::new(Channel::new(name)),
        };
        channels.insert(name.to_owned(), Arc::downgrade(&channel));
        Ok(channel)
    }

    /// Microseconds since the hub started: the clock of the connections' activity times.
    fn micros(&self) -> u64 {
        u64::try_from(self.epoch.elapsed().as_micros()).unwrap_or(u64::MAX)
    }

    /// Closes the connection that has been idle longest among those that never sent a frame,
    /// to make room for a new one. Returns false when there is none (every client sent frames).
    fn evict_idle(&self, connections: &mut HashMap<u64, ConnectionEntry>) -> bool {
        let victim = connections
            .values()
            .filter(|entry| !entry.connection.sent_frames.load(Ordering::SeqCst))
            .min_by_key(|entry| (entry.connection.last_active.load(Ordering::SeqCst), entry.connection.id))
            .map(|entry| entry.connection.id);
        let Some(entry) = victim.and_then(|id| connections.remove(&id)) else { return false };
        let connection = entry.connection;
        let idle = self.micros().saturating_sub(connection.last_active.load(Ordering::SeqCst));
        self.emit(&HubEvent::Evicted {
            client: connection.id,
            peer: connection.peer,
            idle: Duration::from_micros(idle),
        });
        connection.kill("closed to make room for a new client (the hub was full and it sent no frame)");
        // Its threads end on their own once the socket is shut down.
        true
    }

    fn accept_loop(self: Arc<Self>, listener: &TcpListener) {
        loop {
            let accepted = listener.accept();
            if self.stopping.load(Ordering::SeqCst) {
                return;
            }
            match accepted {
                Ok((stream, peer)) => Arc::clone(&self).serve(stream, peer),
                Err(error) if error.kind() == io::ErrorKind::Interrupted => {}
                Err(error) => {
                    self.emit(&HubEvent::AcceptFailed { error: error.to_string() });
                    // Out of descriptors and the like: give the OS a moment instead of spinning.
                    std::thread::sleep(Duration::from_millis(50));
                }
            }
        }
    }

    fn serve(self: Arc<Self>, stream: TcpStream, peer: SocketAddr) {
        let mut connections = lock(&self.connections);
        if connections.len() >= self.config.max_clients.max(1) && !self.evict_idle(&mut connections) {
            drop(connections);
            let reason = format!("{} clients already connected, all of them sending", self.config.max_clients);
            let mut stream = stream;
            let _ = stream.set_write_timeout(Some(Duration::from_millis(100)));
            let _ = stream.write_all(Message::Error(format!("too many clients, {reason}")).to_string().as_bytes());
            self.emit(&HubEvent::Rejected { peer, reason });
            return;
        }
        let setup = || -> io::Result<()> {
            stream.set_nodelay(true)?;
            stream.set_write_timeout(Some(self.config.write_timeout))
        };
        match setup() {
            Ok(()) => {}
            Err(error) => {
                drop(connections);
                self.emit(&HubEvent::Rejected { peer, reason: format!("socket setup failed: {error}") });
                return;
            }
        };
        let id = next_member_id();
        let connection = Arc::new(Connection {
            id,
            peer,
            stream,
            queue: BoundedQueue::new(self.config.client_queue),
            capacity: self.config.client_queue.max(1),
            reply_pause: self.config.reply_pause,
            closing: AtomicBool::new(false),
            reason: Mutex::new(None),
            observer: Arc::clone(&self.config.observer),
            last_active: AtomicU64::new(self.micros()),
            sent_frames: AtomicBool::new(false),
            dropped: AtomicU64::new(0),
            drop_report: AtomicBool::new(false),
            drop_report_interval: self.config.drop_report_interval,
            drops_reported: AtomicU64::new(0),
            last_drop_event: Mutex::new(None),
        });
        connections.insert(id, ConnectionEntry { connection: Arc::clone(&connection), threads: Vec::new() });
        drop(connections);
        self.emit(&HubEvent::Connected { client: id, peer });
        connection.reply(Message::Hi);

        let write_thread = {
            let connection = Arc::clone(&connection);
            std::thread::Builder::new().name(format!("hub-write-{id}")).spawn(move || connection.write_loop())
        };
        let read_thread = {
            let connection = Arc::clone(&connection);
            let hub = Arc::clone(&self);
            std::thread::Builder::new().name(format!("hub-read-{id}")).spawn(move || hub.read_loop(&connection))
        };
        let mut threads = Vec::new();
        let mut reading = true;
        for (spawned, is_reader) in [(write_thread, false), (read_thread, true)] {
            match spawned {
                Ok(handle) => threads.push(handle),
                Err(error) => {
                    connection.kill(&format!("cannot start a thread: {error}"));
                    reading &= !is_reader;
                }
            }
        }
        if !reading {
            // No reader thread, so nobody else will clean up this connection.
            lock(&self.connections).remove(&id);
            self.emit(&HubEvent::Disconnected { client: id, peer, reason: connection.reason() });
            return;
        }
        if let Some(entry) = lock(&self.connections).get_mut(&id) {
            entry.threads = threads;
        }
        // Otherwise the reader already finished and removed the entry; its threads end alone.
    }

    fn read_loop(&self, connection: &Arc<Connection>) {
        let mut reader: &TcpStream = &connection.stream;
        let mut session = Session { hub: self, connection, mode: Mode::NoBus, channel: None, errors: 0, sent: 0 };
        let mut decoder = Decoder::new();
        let mut buf = vec![0u8; 16 * 1024];
        let open_deadline = Instant::now() + self.config.open_timeout;
        let mut throttle = Throttle::new(self.config.max_rate);
        let ended = loop {
            if session.mode == Mode::NoBus {
                let left = open_deadline.saturating_duration_since(Instant::now());
                if left.is_zero() || reader.set_read_timeout(Some(left)).is_err() {
                    break format!("no channel opened within {:?}", self.config.open_timeout);
                }
            }
            match reader.read(&mut buf) {
                Ok(0) => break "client closed the connection".to_owned(),
                Ok(n) => {
                    connection.last_active.store(self.micros(), Ordering::SeqCst);
                    let was_open = session.mode != Mode::NoBus;
                    let sent_before = session.sent;
                    decoder.feed(&buf[..n], |message| session.handle(message));
                    if session.sent > sent_before {
                        connection.sent_frames.store(true, Ordering::SeqCst);
                        // Paused in slices, so a client closed meanwhile is let go promptly.
                        let mut pause = throttle.sent(session.sent - sent_before);
                        while !pause.is_zero() && !connection.closing.load(Ordering::SeqCst) {
                            let slice = pause.min(Duration::from_millis(100));
                            std::thread::sleep(slice);
                            pause -= slice;
                        }
                    }
                    if connection.closing.load(Ordering::SeqCst) {
                        break connection.reason();
                    }
                    if !was_open && session.mode != Mode::NoBus && reader.set_read_timeout(None).is_err() {
                        break "cannot configure the socket".to_owned();
                    }
                }
                Err(error) if error.kind() == io::ErrorKind::Interrupted => {}
                Err(error) if matches!(error.kind(), io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut) => {
                    if session.mode == Mode::NoBus {
                        continue; // the deadline check above decides
                    }
                    break format!("read failed: {error}");
                }
                Err(error) => break format!("read failed: {error}"),
            }
        };
        if let Some(channel) = session.channel.take() {
            channel.leave(connection.id);
        }
        connection.kill(&ended);
        lock(&self.connections).remove(&connection.id);
        self.emit(&HubEvent::Disconnected {
            client: connection.id,
            peer: connection.peer,
            reason: connection.reason(),
        });
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Mode {
    NoBus,
    Bcm,
    Raw,
}

/// The protocol state of one client, driven by its reader thread.
struct Session<'a> {
    hub: &'a HubInner,
    connection: &'a Arc<Connection>,
    mode: Mode,
    channel: Option<Arc<Channel>>,
    errors: u32,
    /// Frames the client put on the bus.
    sent: u64,
}

/// Slows a client down to `rate` frames per second on average (a token bucket holding a tenth
/// of a second's worth): when it has sent more, its reader sleeps, and TCP flow control makes
/// the client wait.
struct Throttle {
    rate: u32,
    tokens: f64,
    refilled: Instant,
}

impl Throttle {
    fn new(rate: u32) -> Self {
        Self { rate, tokens: Self::burst(rate), refilled: Instant::now() }
    }

    fn burst(rate: u32) -> f64 {
        (f64::from(rate) / 10.0).max(16.0)
    }

    /// Counts `frames` sent; returns how long the client must wait before it is read again.
    fn sent(&mut self, frames: u64) -> Duration {
        if self.rate == 0 {
            return Duration::ZERO;
        }
        let rate = f64::from(self.rate);
        let now = Instant::now();
        let refill = now.saturating_duration_since(self.refilled).as_secs_f64() * rate;
        self.refilled = now;
        self.tokens = (self.tokens + refill).min(Self::burst(self.rate)) - frames as f64;
        if self.tokens < 0.0 { Duration::from_secs_f64(-self.tokens / rate) } else { Duration::ZERO }
    }
}

impl Session<'_> {
    fn handle(&mut self, message: Result<Message, ParseError>) {
        let message = match message {
            Ok(message) => message,
            Err(error @ ParseError::Junk(_)) => {
                // socketcand ignores bytes between messages; only log them.
                self.log_error(error.to_string());
                return;
            }
            Err(error) => return self.refuse(error.to_string()),
        };
        match (message, self.mode) {
            (Message::Echo, _) => self.connection.reply(Message::Echo),
            (Message::Open(name), Mode::NoBus) => {
                let served = &self.hub.config.channels;
                if !served.is_empty() && !served.contains(&name) {
                    return self
                        .refuse(format!("channel {name} is not served here; this hub serves {}", served.join(", ")));
                }
                let others = self.hub.channel_names();
                if !others.is_empty() && !others.contains(&name) {
                    self.hub.emit(&HubEvent::LoneChannel {
                        client: self.connection.id,
                        peer: self.connection.peer,
                        channel: name.clone(),
                        others,
                    });
                }
                match self.hub.channel(&name) {
                    Ok(channel) => self.channel = Some(channel),
                    Err(error) => return self.refuse(format!("cannot open channel {name}: {error}")),
                }
                self.mode = Mode::Bcm;
                self.connection.reply(Message::Ok);
                self.hub.emit(&HubEvent::Opened {
                    client: self.connection.id,
                    peer: self.connection.peer,
                    channel: name,
                });
            }
            (Message::Open(_), _) => self.refuse("a channel is already open".into()),
            (Message::RawMode | Message::BcmMode | Message::Send(_), Mode::NoBus) => {
                self.refuse("open a channel first".into())
            }
            (Message::RawMode, Mode::Bcm) => {
                // `< ok >` goes out before the first frame (python-can waits for it alone) and
                // only once the client is on the bus: python-can returns from its constructor on
                // it, and a frame another client sends right then must reach this one. Held
                // until the join, the reply cannot reach the client while this thread is
                // preempted between the two.
                self.connection.queue.hold();
                self.connection.reply(Message::Ok);
                self.connection.pause();
                if let Some(channel) = &self.channel {
                    channel.join(self.connection.id, Arc::clone(self.connection) as Arc<dyn Sink>);
                }
                self.connection.queue.release();
                self.mode = Mode::Raw;
                self.hub.emit(&HubEvent::RawMode { client: self.connection.id, peer: self.connection.peer });
            }
            (Message::BcmMode, Mode::Raw) => {
                if let Some(channel) = &self.channel {
                    channel.leave(self.connection.id);
                }
                self.mode = Mode::Bcm;
                self.connection.reply(Message::Ok);
            }
            (Message::RawMode, Mode::Raw) | (Message::BcmMode, Mode::Bcm) => self.connection.reply(Message::Ok),
            (Message::Send(frame), _) => {
                if let Some(channel) = &self.channel {
                    self.sent += 1;
                    // With an emulated wire a full transmit queue waits (bounded, so a client
                    // closed meanwhile is noticed): the flooder is the one slowed down.
                    channel.relay(self.connection.id, frame, Timestamp::now(), Some(Duration::from_millis(500)));
                }
            }
            (Message::DropReport, _) => self.connection.drop_report.store(true, Ordering::SeqCst),
            (
                server @ (Message::Hi | Message::Ok | Message::Frame { .. } | Message::Error(_) | Message::Dropped(_)),
                _,
            ) => {
                let name = server.to_string();
                let command = name.split_whitespace().nth(1).unwrap_or_default();
                self.refuse(format!("'{command}' is a server message"));
            }
        }
    }

    fn refuse(&mut self, error: String) {
        self.connection.reply(Message::Error(error.clone()));
        self.log_error(error);
    }

    fn log_error(&mut self, error: String) {
        self.errors = self.errors.saturating_add(1);
        let (client, peer) = (self.connection.id, self.connection.peer);
        if self.errors <= HubConfig::LOGGED_ERRORS_PER_CLIENT {
            self.hub.emit(&HubEvent::ProtocolError { client, peer, error });
        } else if self.errors == HubConfig::LOGGED_ERRORS_PER_CLIENT + 1 {
            self.hub.emit(&HubEvent::ErrorsSuppressed { client, peer });
        }
    }
}

/// What the writer thread sends to a client.
enum Outgoing {
    /// A frame from another member, stamped when the hub received it.
    Frame(CanFrame, Timestamp),
    /// A reply to the client's own command; written on its own.
    Reply(Message),
    /// `reply_pause` before what comes next (after the reply to `< rawmode >`, which frames
    /// follow; not after the one to `< open >`, which nothing can follow before the client's
    /// `< rawmode >`: a pause there only delayed that reply and the first frames).
    Pause,
    /// The rest of a frame that was being sent directly when the socket filled up.
    Rest(String),
}

/// One TCP client, shared by its reader thread, its writer thread and the channel it receives
/// from.
struct Connection {
    id: MemberId,
    peer: SocketAddr,
    stream: TcpStream,
    queue: BoundedQueue<Outgoing>,
    capacity: usize,
    reply_pause: Duration,
    closing: AtomicBool,
    reason: Mutex<Option<String>>,
    observer: HubObserver,
    /// When the client last sent anything, in [`HubInner::micros`].
    last_active: AtomicU64,
    /// Whether it ever put a frame on the bus (clients that did are never evicted).
    sent_frames: AtomicBool,
    /// Frames dropped for it because its queue was full.
    dropped: AtomicU64,
    /// It asked for `< dropped N >` reports.
    drop_report: AtomicBool,
    drop_report_interval: Duration,
    /// `dropped` when [`HubEvent::FramesDropped`] last reported it, and when that was.
    drops_reported: AtomicU64,
    last_drop_event: Mutex<Option<Instant>>,
}

impl Connection {
    /// Queues a reply. Replies are never dropped; they may use a second queue's worth of room
    /// beyond the frames, and a client so far behind that even this does not fit (it sends
    /// commands and does not read the answers) is disconnected.
    fn reply(&self, message: Message) {
        if let Err(PushError::Full) = self.queue.push_within(Outgoing::Reply(message), self.capacity.saturating_mul(2))
        {
            self.overflow();
        }
    }

    /// Queues a pause of `reply_pause` (see [`Outgoing::Pause`]).
    fn pause(&self) {
        if let Err(PushError::Full) = self.queue.push_within(Outgoing::Pause, self.capacity.saturating_mul(2)) {
            self.overflow();
        }
    }

    fn overflow(&self) {
        if !self.closing.load(Ordering::SeqCst) {
            (self.observer)(&HubEvent::Overflow { client: self.id, peer: self.peer, capacity: self.capacity });
        }
        self.kill(&format!("fell {} replies behind", self.capacity));
    }

    /// Disconnects the client (the first reason given is kept): its queue closes, and the
    /// socket shuts down, which wakes both of its threads.
    fn kill(&self, reason: &str) {
        if self.closing.swap(true, Ordering::SeqCst) {
            return;
        }
        *lock(&self.reason) = Some(reason.to_owned());
        self.queue.close();
        let _ = self.stream.shutdown(Shutdown::Both);
    }

    /// Counts `n` frames dropped for this client and raises [`HubEvent::FramesDropped`], at
    /// most once per [`HubConfig::drop_report_interval`]. Raised here, where the frames are
    /// dropped, and not by the client's writer: a writer blocked on a full socket whose reader
    /// takes a little now and then (a receive buffer the kernel keeps growing) may not get back
    /// to its loop for minutes, and the drops would go unreported all that time.
    fn note_drops(&self, n: u64) {
        let total = self.dropped.fetch_add(n, Ordering::Relaxed) + n;
        // Another thread reporting at this moment covers these frames too (or the next report
        // will): never wait for it on the senders' path.
        let Ok(mut last) = self.last_drop_event.try_lock() else { return };
        if last.is_some_and(|at| at.elapsed() < self.drop_report_interval) {
            return;
        }
        // (A thread that counted earlier may get here later, with a smaller total.)
        let before = self.drops_reported.load(Ordering::Relaxed);
        if total <= before {
            return;
        }
        self.drops_reported.store(total, Ordering::Relaxed);
        *last = Some(Instant::now());
        drop(last);
        (self.observer)(&HubEvent::FramesDropped { client: self.id, peer: self.peer, dropped: total - before, total });
    }

    fn reason(&self) -> String {
        lock(&self.reason).clone().unwrap_or_else(|| "closed".to_owned())
    }

    fn write_loop(&self) {
        const BATCH: usize = 256;
        let writer: &TcpStream = &self.stream;
        let mut batch = Vec::with_capacity(BATCH);
        let mut text = String::with_capacity(BATCH * 64);
        let mut reported = 0u64;
        let mut last_report: Option<Instant> = None;
        while self.queue.drain_blocking(&mut batch, BATCH).is_ok() {
            text.clear();
            let mut result = Ok(());
            // The client's own report (`< dropped N >`), if it asked for one; the hub's event is
            // raised where frames are dropped (`note_drops`).
            let dropped = self.dropped.load(Ordering::Relaxed);
            if dropped > reported && last_report.is_none_or(|at| at.elapsed() >= self.drop_report_interval) {
                if self.drop_report.load(Ordering::SeqCst) {
                    Message::Dropped(dropped).write_to(&mut text);
                }
                reported = dropped;
                last_report = Some(Instant::now());
            }
            for item in batch.drain(..) {
                match item {
                    Outgoing::Frame(frame, timestamp) => Message::Frame { frame, timestamp }.write_to(&mut text),
                    Outgoing::Rest(rest) => text.push_str(&rest),
                    Outgoing::Reply(message) => {
                        // Written alone: python-can reads its handshake replies with a single
                        // recv() and compares the whole text.
                        result = result.and_then(|()| flush(writer, &mut text));
                        message.write_to(&mut text);
                        result = result.and_then(|()| flush(writer, &mut text));
                    }
                    Outgoing::Pause => {
                        result = result.and_then(|()| flush(writer, &mut text));
                        if result.is_ok() {
                            std::thread::sleep(self.reply_pause);
                        }
                    }
                }
            }
            if let Err(error) = result.and_then(|()| flush(writer, &mut text)) {
                let reason = match error.kind() {
                    io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut => "not reading (write timed out)".to_owned(),
                    _ => format!("write failed: {error}"),
                };
                self.kill(&reason);
                return;
            }
        }
    }
}

fn flush(mut writer: &TcpStream, text: &mut String) -> io::Result<()> {
    if !text.is_empty() {
        writer.write_all(text.as_bytes())?;
        text.clear();
    }
    Ok(())
}

/// Sends what the socket takes at once without waiting; returns how many bytes it took. Only
/// where a send can be told not to block on its own (Linux): elsewhere it takes nothing and
/// every frame goes through the writer thread.
#[cfg(any(target_os = "linux", target_os = "android"))]
fn send_now(stream: &TcpStream, bytes: &[u8]) -> usize {
    use std::os::fd::AsRawFd;
    // SAFETY: the pointer and length describe `bytes`, a live slice; the descriptor is
    // `stream`'s, open for the whole call. MSG_DONTWAIT makes this one call non-blocking (the
    // descriptor stays blocking for the reader and the writer thread); MSG_NOSIGNAL turns a
    // closed peer into an error instead of SIGPIPE, as std's own writes do.
    let sent = unsafe {
        libc::send(stream.as_raw_fd(), bytes.as_ptr().cast(), bytes.len(), libc::MSG_DONTWAIT | libc::MSG_NOSIGNAL)
    };
    // An error (a full socket, a peer gone): the writer thread takes the frame and meets the
    // error itself, so it is handled in one place.
    usize::try_from(sent).unwrap_or(0)
}

#[cfg(not(any(target_os = "linux", target_os = "android")))]
fn send_now(_stream: &TcpStream, _bytes: &[u8]) -> usize {
    0
}

impl Connection {
    /// Writes a frame to the client straight from the thread relaying it, when the socket takes
    /// it without waiting: a thread wake-up less per frame and client than handing it to the
    /// writer thread. Returns what is left for the writer (the frame, or the rest of its text).
    fn send_directly(&self, item: Outgoing) -> Option<Outgoing> {
        hand_over(item, |bytes| send_now(&self.stream, bytes))
    }
}

/// Offers a frame's text to `send` (which returns how many bytes it took); returns what is left
/// for the writer thread: nothing, the whole item, or the rest of its text.
fn hand_over(item: Outgoing, send: impl FnOnce(&[u8]) -> usize) -> Option<Outgoing> {
    let Outgoing::Frame(frame, timestamp) = item else { return Some(item) };
    let mut text = String::with_capacity(48);
    Message::Frame { frame, timestamp }.write_to(&mut text);
    match send(text.as_bytes()) {
        0 => Some(item),
        sent if sent >= text.len() => None,
        // The text is ASCII: any byte offset is a character boundary.
        sent => Some(Outgoing::Rest(text[sent..].to_owned())),
    }
}

impl Sink for Connection {
    fn deliver(&self, frame: CanFrame, at: Timestamp) -> Delivery {
        // Written at once when nothing waits for the writer thread, queued behind it otherwise.
        match self.queue.push_or_hand(Outgoing::Frame(frame, at), |item| self.send_directly(item)) {
            Ok(()) => Delivery::Accepted,
            Err(PushError::Full) => {
                // A slow reader loses frames, not its connection.
                self.note_drops(1);
                Delivery::Dropped
            }
            Err(PushError::Closed) => Delivery::Gone,
        }
    }

    fn close(&self) {
        self.kill("hub stopped");
    }

    fn deliver_batch(&self, batch: &[(MemberId, CanFrame)], me: MemberId, at: Timestamp) -> Delivery {
        let frames = batch.iter().filter(|(from, _)| *from != me).map(|(_, frame)| Outgoing::Frame(*frame, at));
        match self.queue.push_all(frames) {
            Ok(0) => Delivery::Accepted,
            Ok(refused) => {
                // A slow reader loses frames, not its connection.
                self.note_drops(refused as u64);
                Delivery::Dropped
            }
            Err(_) => Delivery::Gone,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_the_socket_took_part_of_leaves_exactly_the_rest_for_the_writer() {
        let frame = CanFrame::standard(0x581, &[0x43, 0x00, 0x10, 0x00, 0x92, 0x01, 0x02, 0x00]).unwrap();
        let at = Timestamp::new(12, 345).unwrap();
        let text = Message::Frame { frame, timestamp: at }.to_string();
        for taken in 0..=text.len() {
            let mut offered = Vec::new();
            let left = hand_over(Outgoing::Frame(frame, at), |bytes| {
                offered = bytes.to_vec();
                taken
            });
            assert_eq!(offered, text.as_bytes());
            match left {
                None => assert_eq!(taken, text.len()),
                Some(Outgoing::Frame(f, t)) => assert_eq!((taken, f, t), (0, frame, at)),
                Some(Outgoing::Rest(rest)) => assert_eq!(format!("{}{rest}", &text[..taken]), text),
                Some(Outgoing::Reply(_) | Outgoing::Pause) => panic!("a frame came back as a reply"),
            }
        }
        // Replies are never written directly: they keep their place behind queued frames.
        assert!(matches!(hand_over(Outgoing::Reply(Message::Ok), |_| unreachable!()), Some(Outgoing::Reply(_))));
    }
}
