//! Broadcast domains ("channels") and the in-process endpoints attached to them.
//!
//! A [`Channel`] is one CAN bus: a list of members, each with a sink that accepts frames. A frame
//! relayed by one member reaches every other member, never the sender, in the order it was
//! relayed. [`MemoryBus`] is a channel on its own, for tests and single-process simulations; the
//! hub keeps one channel per name that TCP clients open, and its in-process endpoints are the
//! same [`LocalEndpoint`] type.

use std::collections::HashMap;
use std::fmt;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, OnceLock, Weak};
use std::time::Duration;

use crate::endpoint::Endpoint;
use crate::error::TransportError;
use crate::frame::CanFrame;
use crate::queue::{BoundedQueue, PushError, lock};
use crate::sink::{Delivery, MemberId, Sink, next_member_id};
use crate::timestamp::Timestamp;
use crate::wire::Wire;

/// One CAN bus: every member receives what the others relay.
///
/// Without a [`Wire`] a relayed frame reaches the members at once, however many are relayed.
/// With one (`--bitrate`), frames wait in their sender's transmit queue and the wire carries
/// them one at a time, each taking as long as it takes on a real CAN bus of that bit rate,
/// the lowest identifier first when several wait (see [`wire`](crate::wire)).
pub(crate) struct Channel {
    name: String,
    members: Mutex<Vec<(MemberId, Arc<dyn Sink>)>>,
    wire: Option<Arc<Wire>>,
}

impl Channel {
    pub(crate) fn new(name: &str) -> Self {
        Self { name: name.to_owned(), members: Mutex::new(Vec::new()), wire: None }
    }

    /// A channel whose frames go over an emulated wire of `bitrate` bits per second (a thread
    /// per channel carries them; it ends when the channel is dropped).
    pub(crate) fn with_bitrate(name: &str, bitrate: u32) -> Result<Arc<Self>, std::io::Error> {
        let wire = Arc::new(Wire::new(bitrate));
        let channel =
            Arc::new(Self { name: name.to_owned(), members: Mutex::new(Vec::new()), wire: Some(Arc::clone(&wire)) });
        let weak = Arc::downgrade(&channel);
        std::thread::Builder::new()
            .name(format!("wire-{name}"))
            .spawn(move || wire.carry(|batch, at| weak.upgrade().map(|c| c.deliver_batch(batch, at)).is_some()))?;
        Ok(channel)
    }

    pub(crate) fn name(&self) -> &str {
        &self.name
    }

    pub(crate) fn join(&self, id: MemberId, sink: Arc<dyn Sink>) {
        let mut members = lock(&self.members);
        if !members.iter().any(|(member, _)| *member == id) {
            members.push((id, sink));
        }
    }

    pub(crate) fn leave(&self, id: MemberId) {
        lock(&self.members).retain(|(member, _)| *member != id);
        if let Some(wire) = &self.wire {
            wire.forget(id);
        }
    }

    /// Whether frames cross an emulated wire ([`crate::wire`]) rather than reaching the other
    /// members at once.
    pub(crate) fn has_wire(&self) -> bool {
        self.wire.is_some()
    }

    pub(crate) fn member_count(&self) -> usize {
        lock(&self.members).len()
    }

    /// Puts `frame` from `from` on the bus. Without a wire it reaches every other member at
    /// once; with one it joins the sender's transmit queue, and `block` decides what a full
    /// queue means: wait up to that long for room (a TCP client's reader: the client is throttled to what the
    /// wire carries) or drop the frame (an in-process endpoint, which must never block).
    /// Returns false when the frame was dropped.
    pub(crate) fn relay(&self, from: MemberId, frame: CanFrame, at: Timestamp, block: Option<Duration>) -> bool {
        match &self.wire {
            None => {
                self.deliver(from, frame, at);
                true
            }
            Some(wire) => wire.submit(from, frame, block, &|batch, at| self.deliver_batch(batch, at)),
        }
    }

    /// Delivers `frame` to every member but `from`; members whose sink reports
    /// [`Delivery::Gone`] are removed. Never blocks on a member. Returns how many members
    /// accepted the frame.
    pub(crate) fn deliver(&self, from: MemberId, frame: CanFrame, at: Timestamp) -> usize {
        let mut members = lock(&self.members);
        let mut accepted = 0;
        members.retain(|(id, sink)| {
            if *id == from {
                return true;
            }
            match sink.deliver(frame, at) {
                Delivery::Accepted => {
                    accepted += 1;
                    true
                }
                Delivery::Dropped => true,
                Delivery::Gone => false,
            }
        });
        accepted
    }

    /// Delivers the frames of `batch` (sender, frame) in order, each to every member but its
    /// sender, with one pass over the members.
    pub(crate) fn deliver_batch(&self, batch: &[(MemberId, CanFrame)], at: Timestamp) {
        let mut members = lock(&self.members);
        members.retain(|(id, sink)| sink.deliver_batch(batch, *id, at) != Delivery::Gone);
    }

    /// Closes every member (hub shutdown).
    pub(crate) fn close_all(&self) {
        let members = std::mem::take(&mut *lock(&self.members));
        for (_, sink) in members {
            sink.close();
        }
        if let Some(wire) = &self.wire {
            wire.close();
        }
    }
}

impl Drop for Channel {
    fn drop(&mut self) {
        if let Some(wire) = &self.wire {
            wire.close();
        }
    }
}

/// Called with the total count each time an in-process endpoint's queue overflows for the
/// first time and then at every power of two, so a stuck endpoint cannot flood the log.
pub(crate) type OverflowHook = Box<dyn Fn(u64) + Send + Sync>;

/// Receive queue of a [`LocalEndpoint`].
pub(crate) struct Inbox {
    queue: BoundedQueue<CanFrame>,
    dropped: AtomicU64,
    /// Frames this endpoint sent that the wire had no room for (`--bitrate` only).
    tx_dropped: AtomicU64,
    on_overflow: Option<OverflowHook>,
}

impl Inbox {
    pub(crate) fn new(capacity: usize, on_overflow: Option<OverflowHook>) -> Self {
        Self {
            queue: BoundedQueue::new(capacity),
            dropped: AtomicU64::new(0),
            tx_dropped: AtomicU64::new(0),
            on_overflow,
        }
    }
}

impl Sink for Inbox {
    fn deliver(&self, frame: CanFrame, _at: Timestamp) -> Delivery {
        match self.queue.push(frame) {
            Ok(()) => Delivery::Accepted,
            Err(PushError::Full) => {
                let total = self.dropped.fetch_add(1, Ordering::Relaxed) + 1;
                if let Some(hook) = &self.on_overflow
                    && total.is_power_of_two()
                {
                    hook(total);
                }
                Delivery::Dropped
            }
            Err(PushError::Closed) => Delivery::Gone,
        }
    }

    fn close(&self) {
        self.queue.close();
    }

    fn deliver_batch(&self, batch: &[(MemberId, CanFrame)], me: MemberId, _at: Timestamp) -> Delivery {
        let frames = batch.iter().filter(|(from, _)| *from != me).map(|(_, frame)| *frame);
        match self.queue.push_all(frames) {
            Ok(0) => Delivery::Accepted,
            Ok(refused) => {
                let before = self.dropped.fetch_add(refused as u64, Ordering::Relaxed);
                let total = before + refused as u64;
                // Reported when the total passes a power of two, as one by one.
                if let Some(hook) = &self.on_overflow
                    && (before + 1..=total).any(u64::is_power_of_two)
                {
                    hook(total);
                }
                Delivery::Dropped
            }
            Err(_) => Delivery::Gone,
        }
    }
}

/// An endpoint living in this process, attached to a [`MemoryBus`] or to a channel of a
/// [`Hub`](crate::Hub). It leaves the bus when dropped.
///
/// Sending never blocks: the frame is copied into the receive queue of every other member. A
/// member whose queue is full loses the frame (like a CAN controller's receive overrun) and the
/// loss is counted in its [`dropped`](LocalEndpoint::dropped).
pub struct LocalEndpoint {
    id: MemberId,
    channel: Arc<Channel>,
    inbox: Arc<Inbox>,
}

impl LocalEndpoint {
    pub(crate) fn attach(channel: Arc<Channel>, capacity: usize, on_overflow: Option<OverflowHook>) -> Self {
        let id = next_member_id();
        let inbox = Arc::new(Inbox::new(capacity, on_overflow));
        channel.join(id, Arc::clone(&inbox) as Arc<dyn Sink>);
        Self { id, channel, inbox }
    }

    /// Frames lost because this endpoint's receive queue was full.
    pub fn dropped(&self) -> u64 {
        self.inbox.dropped.load(Ordering::Relaxed)
    }

    /// Frames this endpoint sent that were lost because its transmit queue on an emulated wire
    /// (`--bitrate`) was full: the bus was saturated by frames of higher priority.
    pub fn send_dropped(&self) -> u64 {
        self.inbox.tx_dropped.load(Ordering::Relaxed)
    }

    /// Frames waiting to be received.
    pub fn pending(&self) -> usize {
        self.inbox.queue.len()
    }

    /// Name of the channel this endpoint is attached to.
    pub fn channel(&self) -> &str {
        self.channel.name()
    }
}

impl Endpoint for LocalEndpoint {
    fn send(&mut self, frame: CanFrame) -> Result<(), TransportError> {
        if self.inbox.queue.is_closed() {
            return Err(TransportError::Closed);
        }
        if !self.channel.relay(self.id, frame, Timestamp::now(), None) {
            self.inbox.tx_dropped.fetch_add(1, Ordering::Relaxed);
        }
        Ok(())
    }

    /// The frames go to every other member in one pass, in order and together, as a socket
    /// client's `send_all` writes them in one write: no other member's frame falls between
    /// them, and a reader is woken once for the lot. On an emulated wire each frame is
    /// arbitrated as it would be on the bus.
    fn send_all(&mut self, frames: &[CanFrame]) -> Result<(), TransportError> {
        if self.inbox.queue.is_closed() {
            return Err(TransportError::Closed);
        }
        if self.channel.has_wire() {
            return frames.iter().try_for_each(|frame| self.send(*frame));
        }
        let batch: Vec<(MemberId, CanFrame)> = frames.iter().map(|frame| (self.id, *frame)).collect();
        self.channel.deliver_batch(&batch, Timestamp::now());
        Ok(())
    }

    fn recv_timeout(&mut self, timeout: Duration) -> Result<Option<CanFrame>, TransportError> {
        self.inbox.queue.pop_timeout(timeout).map_err(|_| TransportError::Closed)
    }

    fn buffered(&self) -> usize {
        self.pending()
    }

    fn lost(&self) -> u64 {
        self.dropped()
    }
}

impl Drop for LocalEndpoint {
    fn drop(&mut self) {
        self.channel.leave(self.id);
    }
}

impl fmt::Debug for LocalEndpoint {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("LocalEndpoint")
            .field("channel", &self.channel.name())
            .field("pending", &self.pending())
            .field("dropped", &self.dropped())
            .finish()
    }
}

/// An in-memory CAN bus: any number of [`LocalEndpoint`]s, each frame sent by one delivered to
/// all the others, in send order.
///
/// It is deterministic and needs no threads: `send` copies the frame into the other endpoints'
/// queues before it returns, so a test can drive a master and several devices from one thread,
/// step by step. It is also thread-safe: endpoints are `Send`, and
/// [`recv_timeout`](Endpoint::recv_timeout) blocks until a frame arrives, so devices can run on
/// their own threads.
///
/// ```
/// use od_bus::{CanFrame, Endpoint, MemoryBus};
/// let bus = MemoryBus::new();
/// let mut master = bus.endpoint();
/// let mut node = bus.endpoint();
/// master.send(CanFrame::standard(0x000, &[0x01, 0x00]).unwrap()).unwrap();
/// assert_eq!(node.try_recv().unwrap().unwrap().data(), &[0x01, 0x00]);
/// assert_eq!(master.try_recv().unwrap(), None); // a sender does not hear itself
/// ```
#[derive(Clone)]
pub struct MemoryBus {
    channel: Arc<Channel>,
    capacity: usize,
}

impl MemoryBus {
    /// Receive queue length of each endpoint unless [`with_capacity`](MemoryBus::with_capacity)
    /// says otherwise.
    pub const DEFAULT_CAPACITY: usize = 4096;

    /// A bus whose endpoints queue up to [`DEFAULT_CAPACITY`](MemoryBus::DEFAULT_CAPACITY)
    /// frames each.
    pub fn new() -> Self {
        Self::with_capacity(Self::DEFAULT_CAPACITY)
    }

    /// A bus whose endpoints queue up to `capacity` frames each (at least one).
    pub fn with_capacity(capacity: usize) -> Self {
        Self { channel: Arc::new(Channel::new("memory")), capacity: capacity.max(1) }
    }

    /// The bus of this process called `name`, the one the address `mem://NAME` opens
    /// (`mem://` is the name ""): every call with the same name returns the same bus, as long as
    /// something still holds it (a `MemoryBus` or an endpoint); after that the name starts a
    /// new, empty bus. This is how code that opens its bus from an address string (an async
    /// master, say) and devices attached in the same process meet.
    ///
    /// ```
    /// use od_bus::{CanFrame, Endpoint, MemoryBus};
    /// let bus = MemoryBus::named("line-1");
    /// let mut device = bus.endpoint();
    /// let mut master = od_bus::open("mem://line-1").unwrap();
    /// master.send(CanFrame::standard(0x000, &[0x01, 0x00]).unwrap()).unwrap();
    /// assert_eq!(device.try_recv().unwrap().unwrap().data(), &[0x01, 0x00]);
    /// ```
    pub fn named(name: &str) -> Self {
        static NAMED: OnceLock<Mutex<HashMap<String, Weak<Channel>>>> = OnceLock::new();
        let mut named = lock(NAMED.get_or_init(Default::default));
        if let Some(channel) = named.get(name).and_then(Weak::upgrade) {
            return Self { channel, capacity: Self::DEFAULT_CAPACITY };
        }
        named.retain(|_, channel| channel.strong_count() > 0);
        let channel = Arc::new(Channel::new(name));
        named.insert(name.to_owned(), Arc::downgrade(&channel));
        Self { channel, capacity: Self::DEFAULT_CAPACITY }
    }

    /// Attaches a new endpoint. It receives every frame sent by another endpoint from now on.
    pub fn endpoint(&self) -> LocalEndpoint {
        LocalEndpoint::attach(Arc::clone(&self.channel), self.capacity, None)
    }

    /// Number of endpoints attached.
    pub fn endpoint_count(&self) -> usize {
        self.channel.member_count()
    }

    /// The channel, for the other kinds of member (the async endpoints).
    #[cfg_attr(not(feature = "tokio"), allow(dead_code))]
    pub(crate) fn channel(&self) -> &Arc<Channel> {
        &self.channel
    }

    /// Receive queue length of each endpoint.
    pub fn capacity(&self) -> usize {
        self.capacity
    }
}

impl Default for MemoryBus {
    fn default() -> Self {
        Self::new()
    }
}

impl fmt::Debug for MemoryBus {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("MemoryBus")
            .field("endpoints", &self.endpoint_count())
            .field("capacity", &self.capacity)
            .finish()
    }
}
