//! The async side (feature `tokio`): a [`Bus`] opened from the same address strings as the
//! blocking endpoints, for a master written with tokio.
//!
//! * `mem://NAME` joins the in-memory bus of this process called NAME, the very bus blocking
//!   devices attached with [`MemoryBus::named`] (or [`Bus::attach`] to any [`MemoryBus`]) are
//!   on. Sending never waits; the receive queue is bounded and frames past it are counted in
//!   [`BusReceiver::lost`].
//! * `socketcand://HOST:PORT/CHANNEL` is a socketcand client on tokio's TCP, speaking the
//!   protocol through the same code as the blocking [`SocketcandClient`](crate::SocketcandClient)
//!   (handshake, parsing, formatting). When the connection fails it reconnects in the
//!   background with backoff ([`Options::reconnect`]); meanwhile [`BusSender::send`] fails with
//!   [`TransportError::Down`], and [`Bus::link`] shows the link going down and coming back.
//! * `socketcan://IFACE` (Linux) is the `socketcan` crate's tokio socket. It subscribes to the
//!   error frames that report the controller's state (warning, error-passive, bus-off,
//!   restarted, error-active again): [`Bus::controller`] reports each change.
//! * `slcan://PORT?bitrate=N` is an slcan adapter on a serial port, served by two threads of
//!   its own (serial ports have no portable async I/O): one reads and decodes
//!   ([`slcan::Session`](crate::slcan::Session): status flags polled and bus-off recovered on
//!   adapters that acknowledge), one writes what the halves send, several frames in one write.
//!   When the port fails (the adapter was unplugged) the link goes down, and the port is opened
//!   again with backoff ([`Options::reconnect`]) and set up afresh: [`Bus::link`] shows it.
//!
//! ```
//! # #[tokio::main(flavor = "current_thread")]
//! # async fn main() {
//! use od_bus::{CanFrame, Endpoint, MemoryBus, tokio::Bus};
//! let devices = MemoryBus::named("doc-example");
//! let mut device = devices.endpoint();
//! let mut master = Bus::open("mem://doc-example").await.unwrap();
//! master.send(CanFrame::standard(0x000, &[0x01, 0x00]).unwrap()).await.unwrap();
//! assert_eq!(device.try_recv().unwrap().unwrap().data(), &[0x01, 0x00]);
//! device.send(CanFrame::standard(0x701, &[0x05]).unwrap()).unwrap();
//! assert_eq!(master.recv().await.unwrap().id(), 0x701);
//! let (tx, mut rx) = master.split(); // one task sends, another receives
//! # drop((tx, rx.lost()));
//! # }
//! ```

use std::fmt;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::time::Duration;

use ::tokio::io::{AsyncReadExt, AsyncWriteExt};
use ::tokio::net::TcpStream;
use ::tokio::net::tcp::{OwnedReadHalf, OwnedWriteHalf};
use ::tokio::sync::{Mutex, Notify, mpsc, oneshot, watch};
use ::tokio::time::{Instant, sleep, timeout_at};

use crate::addr::BusAddr;
use crate::addr::host_for_connect;
use crate::bus::Channel;
use crate::bus::MemoryBus;
use crate::client::{ClientSession, map_io};
use crate::controller::ControllerState;
use crate::error::TransportError;
use crate::frame::CanFrame;
use crate::queue::BoundedQueue;
use crate::sink::{Delivery, MemberId, Sink, next_member_id};
use crate::socketcand::Message;
use crate::timestamp::Timestamp;

/// How a [`Bus`] is opened.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Options {
    /// Time allowed for the TCP connection and for each handshake reply (socketcand).
    pub connect_timeout: Duration,
    /// What a socketcand bus does when its connection fails.
    pub reconnect: Reconnect,
    /// Frames a socketcand bus holds for a receiver that is not reading; past it the client
    /// stops reading the socket and the server drops frames for it (counted in `lost`).
    pub receive_queue: usize,
}

impl Default for Options {
    fn default() -> Self {
        Self {
            connect_timeout: Duration::from_secs(5),
            reconnect: Reconnect::Backoff { first: Duration::from_millis(100), max: Duration::from_secs(5) },
            receive_queue: 4096,
        }
    }
}

/// What a socketcand bus does when its connection fails.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Reconnect {
    /// Nothing: the bus is closed ([`TransportError::Closed`]), as the blocking client.
    Never,
    /// Connect again after `first`, then after twice as long each time, up to `max`, for as
    /// long as the bus is held.
    Backoff {
        /// Wait before the first attempt.
        first: Duration,
        /// Longest wait between attempts.
        max: Duration,
    },
}

/// The state of a bus's link, as [`Bus::link`] reports it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum LinkState {
    /// Frames go through. `reconnects` counts the times the link came back.
    Up {
        /// Times the link was restored since the bus was opened.
        reconnects: u64,
    },
    /// The connection failed and is being restored; sends fail with [`TransportError::Down`].
    Down {
        /// Why it failed (or why the last attempt to restore it failed).
        reason: String,
        /// Attempts made so far to restore it.
        attempts: u32,
    },
    /// Gone for good (the connection failed and [`Reconnect::Never`] was asked for).
    Closed,
}

/// The CAN controller's state changes of a bus ([`Bus::controller`]): every listener
/// ([`subscribe`](Controller::subscribe)) gets each change, in order. A SocketCAN bus reports
/// them from the kernel's error frames, an slcan bus its adapter's bus-off (then restarted, once
/// the session opened the channel again); a memory or socketcand bus has no controller of its
/// own, and only [`report`](Controller::report) (a test playing a controller) says anything.
#[derive(Clone, Debug)]
pub struct Controller {
    changes: ::tokio::sync::broadcast::Sender<ControllerState>,
}

impl Controller {
    /// Changes kept for a listener that is behind; past them it misses the oldest
    /// (`RecvError::Lagged`).
    const KEPT: usize = 64;

    fn new() -> Self {
        Self { changes: ::tokio::sync::broadcast::channel(Self::KEPT).0 }
    }

    /// Every change from now on.
    pub fn subscribe(&self) -> ::tokio::sync::broadcast::Receiver<ControllerState> {
        self.changes.subscribe()
    }

    /// Reports a change to the listeners (none listening: nothing happens).
    pub fn report(&self, state: ControllerState) {
        let _ = self.changes.send(state);
    }
}

/// An async handle on a bus: send frames, receive the frames the other members send (never its
/// own), and [`split`](Bus::split) into halves for two tasks.
pub struct Bus {
    tx: BusSender,
    rx: BusReceiver,
}

/// The sending half of a [`Bus`]; clone it for more senders.
#[derive(Clone)]
pub struct BusSender {
    inner: Tx,
    link: watch::Receiver<LinkState>,
    controller: Controller,
}

/// The receiving half of a [`Bus`].
pub struct BusReceiver {
    inner: Rx,
    link: watch::Receiver<LinkState>,
    controller: Controller,
}

#[derive(Clone)]
enum Tx {
    Memory(Arc<MemMember>),
    /// The guard only has to live as long as the half.
    Socketcand {
        shared: Arc<TcpShared>,
        _stop: Arc<StopGuard>,
    },
    #[cfg(target_os = "linux")]
    SocketCan(Arc<socketcan::tokio::CanSocket>, Arc<str>),
    Slcan(Arc<SerialGuard>),
}

enum Rx {
    Memory(Arc<MemMember>),
    Socketcand {
        frames: mpsc::Receiver<CanFrame>,
        shared: Arc<TcpShared>,
        _stop: Arc<StopGuard>,
    },
    #[cfg(target_os = "linux")]
    SocketCan(Arc<socketcan::tokio::CanSocket>, Arc<str>),
    Slcan {
        frames: mpsc::Receiver<CanFrame>,
        guard: Arc<SerialGuard>,
    },
}

impl Bus {
    /// Opens the bus at `addr` (see [`BusAddr`]) with the default [`Options`].
    pub async fn open(addr: &str) -> Result<Self, TransportError> {
        Self::open_with(&addr.parse::<BusAddr>()?, &Options::default()).await
    }

    /// Opens the bus at `addr` with `options`. A socketcand bus is connected and through its
    /// handshake when this returns; its connection is then served by a task of its own, spawned
    /// on the current runtime, which ends when both halves are dropped.
    pub async fn open_with(addr: &BusAddr, options: &Options) -> Result<Self, TransportError> {
        match addr {
            BusAddr::Memory { name } => Ok(Self::attach(&MemoryBus::named(name))),
            BusAddr::Socketcand { host, port, channel } => open_socketcand(host, *port, channel, options).await,
            BusAddr::SocketCan { interface } => open_socketcan(interface),
            BusAddr::Slcan { port, bitrate, serial_baud, listen_only } => {
                let setup = crate::slcan::Setup { bitrate: *bitrate, listen_only: *listen_only };
                open_slcan(port, *serial_baud, setup, options).await
            }
        }
    }

    /// Joins `bus` (a private [`MemoryBus`] of a test, or a named one) as a new member.
    pub fn attach(bus: &MemoryBus) -> Self {
        let inbox = Arc::new(AsyncInbox {
            queue: BoundedQueue::new(bus.capacity()),
            ready: Notify::new(),
            dropped: AtomicU64::new(0),
            tx_dropped: AtomicU64::new(0),
        });
        let member = Arc::new(MemMember { id: next_member_id(), channel: Arc::clone(bus.channel()), inbox });
        member.channel.join(member.id, Arc::clone(&member.inbox) as Arc<dyn Sink>);
        let (link_tx, link) = watch::channel(LinkState::Up { reconnects: 0 });
        // Nothing ever changes a memory bus's link; the receivers see the value above.
        drop(link_tx);
        let controller = Controller::new();
        Self {
            tx: BusSender {
                inner: Tx::Memory(Arc::clone(&member)),
                link: link.clone(),
                controller: controller.clone(),
            },
            rx: BusReceiver { inner: Rx::Memory(member), link, controller },
        }
    }

    /// Puts a frame on the bus (see [`BusSender::send`]).
    pub async fn send(&self, frame: CanFrame) -> Result<(), TransportError> {
        self.tx.send(frame).await
    }

    /// The next frame from another member (see [`BusReceiver::recv`]).
    pub async fn recv(&mut self) -> Result<CanFrame, TransportError> {
        self.rx.recv().await
    }

    /// Frames lost on the way to this bus handle so far (see [`BusReceiver::lost`]).
    pub fn lost(&self) -> u64 {
        self.rx.lost()
    }

    /// The link's state, and a way to wait for it to change (`changed().await`).
    pub fn link(&self) -> watch::Receiver<LinkState> {
        self.rx.link.clone()
    }

    /// Its CAN controller's state changes (SocketCAN, slcan; see [`Controller`]).
    pub fn controller(&self) -> Controller {
        self.rx.controller.clone()
    }

    /// Splits the bus into a sender and a receiver, usable from different tasks. The bus stays
    /// joined until both are dropped.
    pub fn split(self) -> (BusSender, BusReceiver) {
        (self.tx, self.rx)
    }
}

impl BusSender {
    /// Puts a frame on the bus. A memory bus never waits; a socket waits for room in the OS
    /// send buffer. While a socketcand link is down this fails at once with
    /// [`TransportError::Down`] (the frame is not kept for later: a command sent to a bus that
    /// was restarted meanwhile could arrive in the wrong context).
    pub async fn send(&self, frame: CanFrame) -> Result<(), TransportError> {
        match &self.inner {
            Tx::Memory(member) => {
                if member.inbox.queue.is_closed() {
                    return Err(TransportError::Closed);
                }
                if !member.channel.relay(member.id, frame, Timestamp::now(), None) {
                    member.inbox.tx_dropped.fetch_add(1, Ordering::Relaxed);
                }
                Ok(())
            }
            Tx::Socketcand { shared, .. } => shared.send(frame).await,
            #[cfg(target_os = "linux")]
            Tx::SocketCan(socket, interface) => socket
                .write_frame(crate::socketcan::to_socketcan(&frame))
                .await
                .map_err(|e| TransportError::io(format!("cannot send on {interface}"), e)),
            Tx::Slcan(guard) => guard.0.send(frame).await,
        }
    }

    /// Puts several frames on the bus, in order, as [`send`](BusSender::send) would one by one;
    /// a socketcand link writes them with one system call, so a master with answers for
    /// several nodes at once wakes the hub once. Stops at the first frame that fails.
    pub async fn send_all(&self, frames: &[CanFrame]) -> Result<(), TransportError> {
        match &self.inner {
            Tx::Socketcand { shared, .. } if frames.len() > 1 => shared.send_all(frames).await,
            _ => {
                for frame in frames {
                    self.send(*frame).await?;
                }
                Ok(())
            }
        }
    }

    /// The link's state (see [`Bus::link`]).
    pub fn link(&self) -> watch::Receiver<LinkState> {
        self.link.clone()
    }

    /// The controller's state changes (see [`Bus::controller`]).
    pub fn controller(&self) -> Controller {
        self.controller.clone()
    }
}

impl BusReceiver {
    /// The next frame if one has already arrived, without waiting: `Ok(None)` when none is
    /// there now (on SocketCAN always: only [`recv`](BusReceiver::recv) reads the socket),
    /// [`TransportError::Closed`] once the bus is gone and every frame was handed out. Lets a
    /// task take everything that came in one read before it answers any of it.
    pub fn try_recv(&mut self) -> Result<Option<CanFrame>, TransportError> {
        match &mut self.inner {
            Rx::Memory(member) => member.inbox.queue.pop_timeout(Duration::ZERO).map_err(|_| TransportError::Closed),
            Rx::Socketcand { frames, .. } => match frames.try_recv() {
                Ok(frame) => Ok(Some(frame)),
                Err(mpsc::error::TryRecvError::Empty) => Ok(None),
                Err(mpsc::error::TryRecvError::Disconnected) => Err(TransportError::Closed),
            },
            #[cfg(target_os = "linux")]
            Rx::SocketCan(..) => Ok(None),
            Rx::Slcan { frames, .. } => match frames.try_recv() {
                Ok(frame) => Ok(Some(frame)),
                Err(mpsc::error::TryRecvError::Empty) => Ok(None),
                Err(mpsc::error::TryRecvError::Disconnected) => Err(TransportError::Closed),
            },
        }
    }

    /// The next frame sent by another member, in bus order. Waits as long as it takes, through
    /// reconnections of a socketcand link; cancel it (drop the future, `tokio::time::timeout`)
    /// to wait less: no frame is lost by cancelling. [`TransportError::Closed`] once the bus
    /// is gone for good and every frame received before was handed out.
    pub async fn recv(&mut self) -> Result<CanFrame, TransportError> {
        match &mut self.inner {
            Rx::Memory(member) => loop {
                match member.inbox.queue.pop_timeout(Duration::ZERO) {
                    Ok(Some(frame)) => return Ok(frame),
                    Ok(None) => member.inbox.ready.notified().await,
                    Err(_) => return Err(TransportError::Closed),
                }
            },
            Rx::Socketcand { frames, .. } => frames.recv().await.ok_or(TransportError::Closed),
            #[cfg(target_os = "linux")]
            Rx::SocketCan(socket, interface) => loop {
                let frame = socket
                    .read_frame()
                    .await
                    .map_err(|e| TransportError::io(format!("cannot read from {interface}"), e))?;
                match crate::socketcan::from_socketcan(&frame) {
                    Ok(frame) => return Ok(frame),
                    // An error frame: reported when it says the controller's state changed,
                    // then read on.
                    Err(_) => {
                        if let Some(state) = crate::socketcan::controller_state(&frame) {
                            self.controller.report(state);
                        }
                    }
                }
            },
            Rx::Slcan { frames, .. } => frames.recv().await.ok_or(TransportError::Closed),
        }
    }

    /// Frames lost on the way to this receiver so far: its queue was full (memory bus), or the
    /// socketcand hub dropped them because this client read more slowly than the bus ran
    /// (summed over reconnections), or an slcan adapter reported overruns (one each: a lower
    /// bound). 0 where the transport cannot tell (SocketCAN).
    pub fn lost(&self) -> u64 {
        match &self.inner {
            Rx::Memory(member) => member.inbox.dropped.load(Ordering::Relaxed),
            Rx::Socketcand { shared, .. } => shared.lost(),
            #[cfg(target_os = "linux")]
            Rx::SocketCan(..) => 0,
            Rx::Slcan { guard, .. } => guard.0.overruns.load(Ordering::Relaxed),
        }
    }

    /// The link's state (see [`Bus::link`]).
    pub fn link(&self) -> watch::Receiver<LinkState> {
        self.link.clone()
    }

    /// The controller's state changes (see [`Bus::controller`]); on SocketCAN they are found
    /// by [`recv`](BusReceiver::recv), which must be called for them to be reported.
    pub fn controller(&self) -> Controller {
        self.controller.clone()
    }
}

impl fmt::Debug for Bus {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("Bus").field("link", &*self.rx.link.borrow()).field("lost", &self.lost()).finish()
    }
}

impl fmt::Debug for BusSender {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("BusSender").field("link", &*self.link.borrow()).finish()
    }
}

impl fmt::Debug for BusReceiver {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("BusReceiver").field("link", &*self.link.borrow()).field("lost", &self.lost()).finish()
    }
}

// ---- memory ----

/// One async member of a memory bus; it leaves the bus when both halves are gone.
struct MemMember {
    id: MemberId,
    channel: Arc<Channel>,
    inbox: Arc<AsyncInbox>,
}

impl Drop for MemMember {
    fn drop(&mut self) {
        self.channel.leave(self.id);
    }
}

/// The receive queue of an async member: the blocking endpoints' bounded queue, and a
/// [`Notify`] to wake the task waiting in `recv` (its stored permit means a frame delivered
/// between the check and the wait is not missed).
struct AsyncInbox {
    queue: BoundedQueue<CanFrame>,
    ready: Notify,
    dropped: AtomicU64,
    tx_dropped: AtomicU64,
}

impl Sink for AsyncInbox {
    fn deliver(&self, frame: CanFrame, _at: Timestamp) -> Delivery {
        match self.queue.push(frame) {
            Ok(()) => {
                self.ready.notify_one();
                Delivery::Accepted
            }
            Err(crate::queue::PushError::Full) => {
                self.dropped.fetch_add(1, Ordering::Relaxed);
                Delivery::Dropped
            }
            Err(crate::queue::PushError::Closed) => Delivery::Gone,
        }
    }

    fn close(&self) {
        self.queue.close();
        self.ready.notify_one();
    }

    fn deliver_batch(&self, batch: &[(MemberId, CanFrame)], me: MemberId, _at: Timestamp) -> Delivery {
        let frames = batch.iter().filter(|(from, _)| *from != me).map(|(_, frame)| *frame);
        match self.queue.push_all(frames) {
            Ok(refused) => {
                self.ready.notify_one();
                if refused == 0 {
                    Delivery::Accepted
                } else {
                    self.dropped.fetch_add(refused as u64, Ordering::Relaxed);
                    Delivery::Dropped
                }
            }
            Err(_) => Delivery::Gone,
        }
    }
}

// ---- socketcand ----

/// What the halves of a socketcand bus and its connection task share.
struct TcpShared {
    /// The socket's write half and the number of its connection; `None` while the link is down.
    writer: Mutex<Option<(OwnedWriteHalf, u64)>>,
    link: watch::Sender<LinkState>,
    /// A send failed on the connection numbered `failed`: the connection task should give it
    /// up (unless it already has: the number tells a stale signal from a fresh one).
    broken: Notify,
    failed: AtomicU64,
    /// `< dropped N >` of the current connection, and the totals of the connections before.
    dropped_now: AtomicU64,
    dropped_before: AtomicU64,
}

/// Held by both halves; when the last one goes, the connection task ends.
struct StopGuard {
    _stop: oneshot::Sender<()>,
}

impl TcpShared {
    async fn send(&self, frame: CanFrame) -> Result<(), TransportError> {
        self.send_all(&[frame]).await
    }

    async fn send_all(&self, frames: &[CanFrame]) -> Result<(), TransportError> {
        let mut text = String::with_capacity(48 * frames.len());
        for frame in frames {
            Message::Send(*frame).write_to(&mut text);
        }
        let mut writer = self.writer.lock().await;
        let Some((stream, number)) = writer.as_mut() else { return Err(self.not_up()) };
        match stream.write_all(text.as_bytes()).await {
            Ok(()) => Ok(()),
            Err(error) => {
                self.failed.store(*number, Ordering::SeqCst);
                *writer = None;
                drop(writer);
                let error = map_io("cannot write to the server", error);
                self.link.send_replace(LinkState::Down { reason: error.to_string(), attempts: 0 });
                self.broken.notify_one();
                Err(TransportError::Down { reason: error.to_string() })
            }
        }
    }

    /// The error for a send while there is no connection.
    fn not_up(&self) -> TransportError {
        match &*self.link.borrow() {
            LinkState::Down { reason, .. } => TransportError::Down { reason: reason.clone() },
            _ => TransportError::Closed,
        }
    }

    fn lost(&self) -> u64 {
        self.dropped_before.load(Ordering::Relaxed) + self.dropped_now.load(Ordering::Relaxed)
    }
}

/// A connected socketcand session, through its handshake.
struct Connection {
    reader: OwnedReadHalf,
    writer: OwnedWriteHalf,
    session: ClientSession,
    /// Frames that came with the last handshake reply.
    early: Vec<CanFrame>,
}

/// Connects and performs the handshake (the steps [`ClientSession::handshake`] gives, each
/// reply within `timeout`).
async fn connect(host: &str, port: u16, channel: &str, timeout: Duration) -> Result<Connection, TransportError> {
    let steps = ClientSession::handshake(channel)?;
    let deadline = Instant::now() + timeout;
    let stream = timeout_at(deadline, TcpStream::connect((host_for_connect(host), port)))
        .await
        .map_err(|_| TransportError::Protocol(format!("no connection to {host}:{port} within {timeout:?}")))?
        .map_err(|e| TransportError::io(format!("cannot connect to {host}:{port}"), e))?;
    stream.set_nodelay(true).map_err(|e| TransportError::io("cannot configure the socket", e))?;
    crate::socketcand::bound_receive_buffer(&stream)?;
    let (mut reader, mut writer) = stream.into_split();
    let mut session = ClientSession::new();
    let mut early = Vec::new();
    let mut buf = vec![0u8; 4096];
    for (say, reply) in steps {
        if let Some(message) = say {
            write_message(&mut writer, &message).await?;
        }
        let deadline = Instant::now() + timeout;
        loop {
            if let Some(checked) = session.take_reply(&reply) {
                checked?;
                break;
            }
            let read = timeout_at(deadline, reader.read(&mut buf))
                .await
                .map_err(|_| TransportError::Protocol(format!("no {reply} from the server within {timeout:?}")))?;
            let n = read.map_err(|e| map_io("cannot read from the server", e))?;
            if n == 0 {
                return Err(TransportError::Closed);
            }
            session.feed(&buf[..n], |frame| early.push(frame));
        }
    }
    write_message(&mut writer, &ClientSession::AFTER_HANDSHAKE).await?;
    Ok(Connection { reader, writer, session, early })
}

async fn write_message(writer: &mut OwnedWriteHalf, message: &Message) -> Result<(), TransportError> {
    let mut text = String::with_capacity(32);
    message.write_to(&mut text);
    writer.write_all(text.as_bytes()).await.map_err(|e| map_io("cannot write to the server", e))
}

async fn open_socketcand(host: &str, port: u16, channel: &str, options: &Options) -> Result<Bus, TransportError> {
    let connection = connect(host, port, channel, options.connect_timeout).await?;
    let (link_tx, link) = watch::channel(LinkState::Up { reconnects: 0 });
    let shared = Arc::new(TcpShared {
        writer: Mutex::new(None),
        link: link_tx,
        broken: Notify::new(),
        failed: AtomicU64::new(0),
        dropped_now: AtomicU64::new(0),
        dropped_before: AtomicU64::new(0),
    });
    let (frames_tx, frames_rx) = mpsc::channel(options.receive_queue.max(1));
    let (stop_tx, stop_rx) = oneshot::channel();
    let guard = Arc::new(StopGuard { _stop: stop_tx });
    let task = ConnectionTask {
        shared: Arc::clone(&shared),
        frames: frames_tx,
        host: host.to_owned(),
        port,
        channel: channel.to_owned(),
        options: options.clone(),
    };
    *shared.writer.lock().await = Some((connection.writer, 1));
    ::tokio::spawn(task.run(connection.reader, connection.session, connection.early, stop_rx));
    let controller = Controller::new();
    Ok(Bus {
        tx: BusSender {
            inner: Tx::Socketcand { shared: Arc::clone(&shared), _stop: Arc::clone(&guard) },
            link: link.clone(),
            controller: controller.clone(),
        },
        rx: BusReceiver { inner: Rx::Socketcand { frames: frames_rx, shared, _stop: guard }, link, controller },
    })
}

/// Serves one socketcand bus: reads frames into the receiver's queue, and when the connection
/// fails, restores it.
struct ConnectionTask {
    shared: Arc<TcpShared>,
    frames: mpsc::Sender<CanFrame>,
    host: String,
    port: u16,
    channel: String,
    options: Options,
}

impl ConnectionTask {
    async fn run(
        self,
        mut reader: OwnedReadHalf,
        mut session: ClientSession,
        mut early: Vec<CanFrame>,
        mut stop: oneshot::Receiver<()>,
    ) {
        let mut reconnects = 0u64;
        // Connections are numbered from 1 (the one `open` made).
        let mut number = 1u64;
        loop {
            let reason = ::tokio::select! {
                _ = &mut stop => return,
                () = self.send_failed(number) => "a send failed".to_owned(),
                error = self.read(&mut reader, &mut session, std::mem::take(&mut early)) => error.to_string(),
            };
            *self.shared.writer.lock().await = None;
            let before = self.shared.dropped_now.swap(0, Ordering::Relaxed);
            self.shared.dropped_before.fetch_add(before, Ordering::Relaxed);
            let Reconnect::Backoff { first, max } = self.options.reconnect else {
                self.shared.link.send_replace(LinkState::Closed);
                return;
            };
            self.shared.link.send_replace(LinkState::Down { reason, attempts: 0 });
            let mut delay = first;
            let mut attempts = 0u32;
            let connection = loop {
                ::tokio::select! {
                    _ = &mut stop => return,
                    () = sleep(delay) => {}
                }
                attempts = attempts.saturating_add(1);
                let attempt = ::tokio::select! {
                    _ = &mut stop => return,
                    attempt = connect(&self.host, self.port, &self.channel, self.options.connect_timeout) => attempt,
                };
                match attempt {
                    Ok(connection) => break connection,
                    Err(error) => {
                        self.shared.link.send_replace(LinkState::Down { reason: error.to_string(), attempts });
                        delay = delay.saturating_mul(2).min(max.max(first));
                    }
                }
            };
            reader = connection.reader;
            session = connection.session;
            early = connection.early;
            number += 1;
            *self.shared.writer.lock().await = Some((connection.writer, number));
            reconnects += 1;
            self.shared.link.send_replace(LinkState::Up { reconnects });
        }
    }

    /// Returns once a send failed on connection `number`.
    async fn send_failed(&self, number: u64) {
        while self.shared.failed.load(Ordering::SeqCst) != number {
            self.shared.broken.notified().await;
        }
    }

    /// Reads until the connection fails; returns why.
    async fn read(
        &self,
        reader: &mut OwnedReadHalf,
        session: &mut ClientSession,
        early: Vec<CanFrame>,
    ) -> TransportError {
        let mut buf = vec![0u8; 16 * 1024];
        let mut frames = early;
        loop {
            for frame in frames.drain(..) {
                // A receiver that was dropped takes nothing; the connection still serves the
                // sender (and notices failures).
                let _ = self.frames.send(frame).await;
            }
            let n = match reader.read(&mut buf).await {
                Ok(0) => return TransportError::Closed,
                Ok(n) => n,
                Err(error) if error.kind() == std::io::ErrorKind::Interrupted => continue,
                Err(error) => return map_io("cannot read from the server", error),
            };
            session.feed(&buf[..n], |frame| frames.push(frame));
            session.settle_replies();
            self.shared.dropped_now.store(session.server_dropped(), Ordering::Relaxed);
        }
    }
}

// ---- SocketCAN ----

#[cfg(target_os = "linux")]
fn open_socketcan(interface: &str) -> Result<Bus, TransportError> {
    let socket =
        socketcan::tokio::CanSocket::open(interface).map_err(|e| crate::socketcan::open_error(interface, e))?;
    crate::socketcan::subscribe_state_errors(&socket).map_err(|e| {
        TransportError::io(format!("cannot subscribe to the error frames of CAN interface {interface:?}"), e)
    })?;
    let socket = Arc::new(socket);
    let name: Arc<str> = Arc::from(interface);
    let (link_tx, link) = watch::channel(LinkState::Up { reconnects: 0 });
    drop(link_tx);
    let controller = Controller::new();
    Ok(Bus {
        tx: BusSender {
            inner: Tx::SocketCan(Arc::clone(&socket), Arc::clone(&name)),
            link: link.clone(),
            controller: controller.clone(),
        },
        rx: BusReceiver { inner: Rx::SocketCan(socket, name), link, controller },
    })
}

#[cfg(not(target_os = "linux"))]
fn open_socketcan(interface: &str) -> Result<Bus, TransportError> {
    Err(crate::addr::unavailable(interface))
}

// ---- slcan ----

/// What the halves of an slcan bus and its two threads share.
struct SerialShared {
    /// To the writer thread.
    out: mpsc::Sender<Out>,
    link: watch::Sender<LinkState>,
    /// Told of a bus-off and of the restart that follows.
    controller: Controller,
    /// Both halves are gone: the threads close the channel (`C`) and end.
    stop: AtomicBool,
    /// A write failed: the reader gives the port up and opens it again. (The writer holds
    /// this, not the whole: it must not hold a sender of its own channel, which ends when the
    /// halves and the reader are gone.)
    broken: Arc<AtomicBool>,
    overruns: AtomicU64,
}

/// What the writer thread writes.
enum Out {
    Frame(CanFrame),
    /// Commands of the session (status polls, bus-off recovery, the closing `C`).
    Raw(Vec<u8>),
}

/// Held by both halves; when the last one goes, the threads stop.
struct SerialGuard(Arc<SerialShared>);

impl Drop for SerialGuard {
    fn drop(&mut self) {
        self.0.stop.store(true, Ordering::SeqCst);
    }
}

/// A serial port opened twice: the reader's handle and the writer's.
type PortPair = (Box<dyn serialport::SerialPort>, Box<dyn serialport::SerialPort>);

/// The port the writer writes to; `None` while the link is down.
type PortSlot = Arc<std::sync::Mutex<Option<Box<dyn serialport::SerialPort>>>>;

impl SerialShared {
    async fn send(&self, frame: CanFrame) -> Result<(), TransportError> {
        if let LinkState::Down { reason, .. } = &*self.link.borrow() {
            return Err(TransportError::Down { reason: reason.clone() });
        }
        self.out.send(Out::Frame(frame)).await.map_err(|_| TransportError::Closed)
    }
}

/// Opens the port and writes the setup (blocking calls, on tokio's blocking pool).
async fn open_port(port: &str, serial_baud: u32, setup: crate::slcan::Setup) -> Result<PortPair, TransportError> {
    let name = port.to_owned();
    ::tokio::task::spawn_blocking(move || open_port_blocking(&name, serial_baud, setup))
        .await
        .map_err(|e| TransportError::Unavailable(format!("opening {port}: {e}")))?
}

fn open_port_blocking(name: &str, serial_baud: u32, setup: crate::slcan::Setup) -> Result<PortPair, TransportError> {
    use std::io::Write as _;
    let reader = crate::slcan::open_serial(name, serial_baud)?;
    let mut writer =
        reader.try_clone().map_err(|e| TransportError::io(format!("cannot use {name}"), std::io::Error::from(e)))?;
    let mut commands = Vec::with_capacity(32);
    setup.open_commands(&mut commands);
    writer
        .write_all(&commands)
        .and_then(|()| writer.flush())
        .map_err(|e| TransportError::io(format!("cannot write to {name}"), e))?;
    Ok((reader, writer))
}

async fn open_slcan(
    port: &str,
    serial_baud: u32,
    setup: crate::slcan::Setup,
    options: &Options,
) -> Result<Bus, TransportError> {
    if crate::slcan::bitrate_code(setup.bitrate).is_none() {
        return Err(TransportError::Unavailable(crate::slcan::bitrate_error(setup.bitrate)));
    }
    let (reader, writer) = open_port(port, serial_baud, setup).await?;
    let (link_tx, link) = watch::channel(LinkState::Up { reconnects: 0 });
    let (out_tx, out_rx) = mpsc::channel(256);
    let (frames_tx, frames_rx) = mpsc::channel(options.receive_queue.max(1));
    let controller = Controller::new();
    let shared = Arc::new(SerialShared {
        out: out_tx,
        link: link_tx,
        controller: controller.clone(),
        stop: AtomicBool::new(false),
        broken: Arc::new(AtomicBool::new(false)),
        overruns: AtomicU64::new(0),
    });
    let slot: PortSlot = Arc::new(std::sync::Mutex::new(Some(writer)));
    let reader_task = SerialReader {
        shared: Arc::clone(&shared),
        slot: Arc::clone(&slot),
        frames: frames_tx,
        name: port.to_owned(),
        serial_baud,
        session: crate::slcan::Session::new(setup),
        reconnect: options.reconnect,
    };
    let broken = Arc::clone(&shared.broken);
    std::thread::Builder::new()
        .name(format!("slcan writer {port}"))
        .spawn(move || write_loop(out_rx, slot, broken))
        .map_err(|e| TransportError::io("cannot start the slcan writer thread", e))?;
    std::thread::Builder::new()
        .name(format!("slcan reader {port}"))
        .spawn(move || reader_task.run(reader))
        .map_err(|e| TransportError::io("cannot start the slcan reader thread", e))?;
    let guard = Arc::new(SerialGuard(shared));
    Ok(Bus {
        tx: BusSender { inner: Tx::Slcan(Arc::clone(&guard)), link: link.clone(), controller: controller.clone() },
        rx: BusReceiver { inner: Rx::Slcan { frames: frames_rx, guard }, link, controller },
    })
}

/// Writes what the halves send, every frame waiting at the time in one write; ends when the
/// halves and the reader are gone (after writing what they left, the reader's closing `C`).
fn write_loop(mut out: mpsc::Receiver<Out>, slot: PortSlot, broken: Arc<AtomicBool>) {
    use std::io::Write as _;
    let mut bytes = Vec::with_capacity(4096);
    let push = |item: Out, bytes: &mut Vec<u8>| match item {
        Out::Frame(frame) => crate::slcan::encode(&frame, bytes),
        Out::Raw(raw) => bytes.extend_from_slice(&raw),
    };
    while let Some(first) = out.blocking_recv() {
        bytes.clear();
        push(first, &mut bytes);
        while bytes.len() < 4096 {
            match out.try_recv() {
                Ok(item) => push(item, &mut bytes),
                Err(_) => break,
            }
        }
        let mut port = slot.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
        // While the link is down the port is gone and what was queued is dropped, as frames
        // on an unplugged adapter are.
        if let Some(writer) = port.as_mut()
            && writer.write_all(&bytes).and_then(|()| writer.flush()).is_err()
        {
            *port = None;
            broken.store(true, Ordering::SeqCst);
        }
    }
}

/// Reads and decodes the port; when it fails, opens it again.
struct SerialReader {
    shared: Arc<SerialShared>,
    slot: PortSlot,
    frames: mpsc::Sender<CanFrame>,
    name: String,
    serial_baud: u32,
    session: crate::slcan::Session,
    reconnect: Reconnect,
}

/// How often the reader looks up from a quiet port (to notice that the bus was dropped).
const SERIAL_TICK: Duration = Duration::from_millis(50);

impl SerialReader {
    fn run(mut self, mut port: Box<dyn serialport::SerialPort>) {
        let mut reconnects = 0u64;
        loop {
            // Dropped: the writer keeps the port for the closing `C`, then closes it.
            let Some(reason) = self.read(&mut port) else { return };
            *self.slot.lock().unwrap_or_else(std::sync::PoisonError::into_inner) = None;
            let Reconnect::Backoff { first, max } = self.reconnect else {
                self.shared.link.send_replace(LinkState::Closed);
                return;
            };
            self.shared.link.send_replace(LinkState::Down { reason, attempts: 0 });
            let mut delay = first;
            let mut attempts = 0u32;
            let (reader, writer) = loop {
                if !self.sleep(delay) {
                    return;
                }
                attempts = attempts.saturating_add(1);
                match open_port_blocking(&self.name, self.serial_baud, *self.session.setup()) {
                    Ok(ports) => break ports,
                    Err(error) => {
                        self.shared.link.send_replace(LinkState::Down { reason: error.to_string(), attempts });
                        delay = delay.saturating_mul(2).min(max.max(first));
                    }
                }
            };
            port = reader;
            self.session.restart();
            self.shared.broken.store(false, Ordering::SeqCst);
            *self.slot.lock().unwrap_or_else(std::sync::PoisonError::into_inner) = Some(writer);
            reconnects += 1;
            self.shared.link.send_replace(LinkState::Up { reconnects });
        }
    }

    /// Sleeps `delay` in ticks; false when the bus was dropped meanwhile.
    fn sleep(&self, delay: Duration) -> bool {
        let until = std::time::Instant::now() + delay;
        loop {
            if self.shared.stop.load(Ordering::SeqCst) {
                return false;
            }
            let left = until.saturating_duration_since(std::time::Instant::now());
            if left.is_zero() {
                return true;
            }
            std::thread::sleep(left.min(SERIAL_TICK));
        }
    }

    /// Reads until the port fails (`Some(why)`) or the bus is dropped (`None`, after writing
    /// `C` to close the channel).
    fn read(&mut self, port: &mut Box<dyn serialport::SerialPort>) -> Option<String> {
        let mut buf = vec![0u8; 4096];
        let mut frames = Vec::new();
        let mut commands = Vec::new();
        if let Err(error) = port.set_timeout(SERIAL_TICK) {
            return Some(format!("cannot use {}: {error}", self.name));
        }
        loop {
            if self.shared.stop.load(Ordering::SeqCst) {
                let _ = self.shared.out.try_send(Out::Raw(b"C\r".to_vec()));
                return None;
            }
            if self.shared.broken.load(Ordering::SeqCst) {
                return Some(format!("cannot write to {} (was the adapter unplugged?)", self.name));
            }
            let n = match std::io::Read::read(port, &mut buf) {
                Ok(0) => return Some(format!("{} was closed (was the adapter unplugged?)", self.name)),
                Ok(n) => n,
                Err(e) if matches!(e.kind(), std::io::ErrorKind::TimedOut | std::io::ErrorKind::WouldBlock) => 0,
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => 0,
                Err(e) => return Some(format!("cannot read from {} (was the adapter unplugged?): {e}", self.name)),
            };
            let now = std::time::Instant::now();
            let mut bus_off = None;
            self.session.feed(
                &buf[..n],
                now,
                &mut commands,
                |frame| frames.push(frame),
                |event| {
                    if let crate::slcan::Event::BusOff { flags } = event {
                        bus_off = Some(flags);
                    }
                },
            );
            self.shared.overruns.store(self.session.overruns(), Ordering::Relaxed);
            self.session.poll(now, &mut commands);
            if !commands.is_empty() && self.shared.out.blocking_send(Out::Raw(std::mem::take(&mut commands))).is_err() {
                return None;
            }
            if let Some(flags) = bus_off {
                // Seen as a short outage: the channel was closed and opened again.
                let reconnects = match &*self.shared.link.borrow() {
                    LinkState::Up { reconnects } => *reconnects,
                    _ => 0,
                };
                self.shared.link.send_replace(LinkState::Down {
                    reason: format!("bus-off (status flags {flags:02X}h): channel closed and opened again"),
                    attempts: 1,
                });
                self.shared.link.send_replace(LinkState::Up { reconnects: reconnects + 1 });
                self.shared.controller.report(ControllerState::BusOff);
                self.shared.controller.report(ControllerState::Restarted);
            }
            for frame in frames.drain(..) {
                // A receiver that was dropped takes nothing; the sender still works.
                let _ = self.frames.blocking_send(frame);
            }
        }
    }
}
