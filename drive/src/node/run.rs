//! Running a node in real time on an endpoint.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use od_runtime::Micros;

use super::AnyNode;
use od_bus::{CanFrame, Endpoint, TransportError};

/// A source of the current time in microseconds.
pub trait Clock {
    /// Microseconds since the clock's origin; never goes backwards.
    fn now(&self) -> Micros;
}

/// The monotonic clock of the OS, counted from when the value was made.
#[derive(Clone, Copy, Debug)]
pub struct MonotonicClock {
    origin: Instant,
}

impl MonotonicClock {
    /// A clock whose time is 0 now.
    pub fn new() -> Self {
        Self { origin: Instant::now() }
    }
}

impl Default for MonotonicClock {
    fn default() -> Self {
        Self::new()
    }
}

impl Clock for MonotonicClock {
    fn now(&self) -> Micros {
        Micros::try_from(self.origin.elapsed().as_micros()).unwrap_or(Micros::MAX)
    }
}

/// What [`run`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RunStats {
    /// Frames received from the bus.
    pub received: u64,
    /// Frames the node sent.
    pub sent: u64,
    /// Polls run.
    pub polls: u64,
}

/// Longest single wait for a frame, so that the stop flag is noticed promptly even when the
/// node has nothing to do.
const MAX_WAIT: Duration = Duration::from_millis(20);

/// Runs `node` on `bus` until `stop` is set (returns `Ok`) or the bus fails (returns the
/// error; [`TransportError::Closed`] when the hub went away).
///
/// The loop waits for frames until the node's next deadline ([`AnyNode::next_deadline`]: the
/// application's next tick or the device's 1 ms timer poll), hands each frame to the node the
/// moment it arrives and polls right after it, so an SDO response leaves within microseconds of
/// its request, not at the next millisecond.
pub fn run(
    node: &mut dyn AnyNode,
    bus: &mut dyn Endpoint,
    clock: &dyn Clock,
    stop: &AtomicBool,
) -> Result<RunStats, TransportError> {
    run_group(&mut [node], bus, clock, stop)
}

/// Runs several nodes on one bus endpoint from one thread, as the devices of one process on
/// one connection: every frame from the bus goes to each node, and every frame a node sends
/// goes on the bus and to the other nodes (a bus does not give a sender its own frames back,
/// and here the sender is the whole group). Frames that came in one read are all handed over
/// before the nodes answer, and the answers go out in one write.
///
/// Compared with a thread and a connection per device, a frame on the bus wakes one thread
/// instead of one per device, and the hub writes it once instead of once per device.
pub fn run_group(
    nodes: &mut [&mut dyn AnyNode],
    bus: &mut dyn Endpoint,
    clock: &dyn Clock,
    stop: &AtomicBool,
) -> Result<RunStats, TransportError> {
    let mut stats = RunStats::default();
    run_counting(nodes, bus, clock, stop, &mut stats).map(|()| stats)
}

fn run_counting(
    nodes: &mut [&mut dyn AnyNode],
    bus: &mut dyn Endpoint,
    clock: &dyn Clock,
    stop: &AtomicBool,
    stats: &mut RunStats,
) -> Result<(), TransportError> {
    // Frames sent by the group's nodes this round, with the sender's place in `nodes`.
    let mut out: Vec<(usize, CanFrame)> = Vec::with_capacity(16);
    let mut frames: Vec<CanFrame> = Vec::with_capacity(16);
    // The nodes were handed frames of each other's they have not been polled after.
    let mut owed_poll = false;
    loop {
        if stop.load(Ordering::Relaxed) {
            return Ok(());
        }
        let now = clock.now();
        // (No nodes: nothing is due, frames are still taken off the bus.)
        let deadline = nodes.iter().map(|n| n.next_deadline()).min().unwrap_or(Micros::MAX);
        if owed_poll {
            // No waiting, but what the bus has is taken: nodes busy with each other must not
            // shut the bus out.
            let mut after_sync = false;
            for _ in 0..MAX_LOCAL_ROUNDS {
                let Some(frame) = bus.try_recv()? else { break };
                answer_sync(nodes, &mut out, &mut after_sync, &frame, clock.now(), stats);
                hand_over(nodes, None, &frame, clock.now());
                stats.received += 1;
            }
        } else if now < deadline {
            let wait = Duration::from_micros(deadline - now).min(MAX_WAIT);
            let Some(frame) = bus.recv_timeout(wait)? else { continue };
            hand_over(nodes, None, &frame, clock.now());
            stats.received += 1;
            let mut after_sync = is_sync(&frame);
            // What came with it in the same read is handled before anyone answers, but for
            // the SYNCs: each is answered before the next frame (see `answer_sync`).
            while bus.buffered() > 0 {
                let Some(frame) = bus.try_recv()? else { break };
                answer_sync(nodes, &mut out, &mut after_sync, &frame, clock.now(), stats);
                hand_over(nodes, None, &frame, clock.now());
                stats.received += 1;
            }
        }
        // Polled until quiet: a node's frame reaches the other nodes at once (they may answer
        // it: an SDO request or NMT command from one device to another).
        owed_poll = false;
        for round in 0.. {
            let start = out.len();
            let now = clock.now();
            for (i, node) in nodes.iter_mut().enumerate() {
                node.poll(now, &mut |frame| out.push((i, frame)));
            }
            stats.polls += 1;
            if nodes.len() == 1 || out.len() == start {
                break;
            }
            for &(from, frame) in &out[start..] {
                hand_over(nodes, Some(from), &frame, now);
            }
            if round == MAX_LOCAL_ROUNDS {
                // What they answer comes at the next turn, which does not wait.
                owed_poll = true;
                break;
            }
        }
        frames.clear();
        frames.extend(out.drain(..).map(|(_, frame)| frame));
        match frames.as_slice() {
            [] => {}
            [frame] => bus.send(*frame)?,
            all => bus.send_all(all)?,
        }
        stats.sent += frames.len() as u64;
    }
}

/// Rounds of local delivery in one turn of the loop; beyond this, the nodes' answers to what
/// they were last handed come at the next turn, after what is due on the bus has gone out (two
/// nodes that answered each other forever would otherwise starve the bus).
const MAX_LOCAL_ROUNDS: usize = 8;

/// CiA 301's SYNC (the default COB-ID 80h, which every simulated device consumes).
fn is_sync(frame: &CanFrame) -> bool {
    frame.id() == 0x080 && !frame.is_extended() && !frame.is_remote()
}

/// Before `next` is handed over: when the frame handed over before it was a SYNC, the nodes
/// are polled first (their frames kept in `out` for the turn's one write), so that each SYNC
/// gets its synchronous TPDOs. Several SYNCs in one read (the thread was late, or the master
/// sent them close together) would otherwise be handled before one poll, and a device answers
/// what is due once: a TPDO missing for every SYNC but the last.
fn answer_sync(
    nodes: &mut [&mut dyn AnyNode],
    out: &mut Vec<(usize, CanFrame)>,
    after_sync: &mut bool,
    next: &CanFrame,
    now: Micros,
    stats: &mut RunStats,
) {
    if std::mem::replace(after_sync, is_sync(next)) {
        let start = out.len();
        for (i, node) in nodes.iter_mut().enumerate() {
            node.poll(now, &mut |frame| out.push((i, frame)));
        }
        stats.polls += 1;
        if nodes.len() > 1 {
            for &(from, frame) in &out[start..] {
                hand_over(nodes, Some(from), &frame, now);
            }
        }
    }
}

/// Gives `frame` to every node of the group but its sender.
fn hand_over(nodes: &mut [&mut dyn AnyNode], from: Option<usize>, frame: &CanFrame, now: Micros) {
    for (i, node) in nodes.iter_mut().enumerate() {
        if Some(i) != from {
            node.handle(frame, now);
        }
    }
}

/// How [`run_reconnecting`] waits between attempts to get the bus back: `first`, doubling up
/// to `max`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Backoff {
    /// Wait before the first attempt.
    pub first: Duration,
    /// Longest wait between attempts.
    pub max: Duration,
}

impl Default for Backoff {
    /// 100 ms, doubling up to 5 s.
    fn default() -> Self {
        Self { first: Duration::from_millis(100), max: Duration::from_secs(5) }
    }
}

/// What [`run_reconnecting`] reports.
#[derive(Debug)]
#[non_exhaustive]
pub enum BusEvent<'a> {
    /// The bus failed; the node keeps running (its frames go nowhere) until it is back.
    Lost(&'a TransportError),
    /// An attempt to open the bus again failed; the next comes after `retry_in`.
    RetryFailed {
        /// Why.
        error: &'a TransportError,
        /// Wait before the next attempt.
        retry_in: Duration,
    },
    /// The bus is back after `attempts` attempts.
    Reconnected {
        /// Attempts it took.
        attempts: u32,
    },
}

/// Runs `node` like [`run`], but a failing bus does not end it: the node keeps its state and
/// keeps running (motion, timers; what it sends meanwhile is lost, as on a CAN controller cut
/// off the bus), while `open` is called again after `backoff.first`, then after waits doubling
/// up to `backoff.max`, until it gives a bus. Returns when `stop` is set.
pub fn run_reconnecting(
    node: &mut dyn AnyNode,
    bus: Box<dyn Endpoint>,
    open: &mut dyn FnMut() -> Result<Box<dyn Endpoint>, TransportError>,
    clock: &dyn Clock,
    stop: &AtomicBool,
    backoff: Backoff,
    report: &mut dyn FnMut(BusEvent<'_>),
) -> RunStats {
    run_group_reconnecting(&mut [node], bus, open, clock, stop, backoff, report)
}

/// [`run_reconnecting`] for a group of nodes on one connection, as [`run_group`] runs them.
pub fn run_group_reconnecting(
    nodes: &mut [&mut dyn AnyNode],
    mut bus: Box<dyn Endpoint>,
    open: &mut dyn FnMut() -> Result<Box<dyn Endpoint>, TransportError>,
    clock: &dyn Clock,
    stop: &AtomicBool,
    backoff: Backoff,
    report: &mut dyn FnMut(BusEvent<'_>),
) -> RunStats {
    let mut total = RunStats::default();
    loop {
        let mut stats = RunStats::default();
        let result = run_counting(nodes, &mut *bus, clock, stop, &mut stats);
        total.received += stats.received;
        total.sent += stats.sent;
        total.polls += stats.polls;
        let error = match result {
            Ok(()) => return total,
            Err(error) => error,
        };
        report(BusEvent::Lost(&error));
        drop(bus);
        let mut wait = backoff.first;
        let mut attempts = 0u32;
        bus = loop {
            if !idle(nodes, clock, stop, wait) {
                return total;
            }
            attempts = attempts.saturating_add(1);
            match open() {
                Ok(bus) => {
                    report(BusEvent::Reconnected { attempts });
                    break bus;
                }
                Err(error) => {
                    wait = (wait * 2).min(backoff.max.max(backoff.first));
                    report(BusEvent::RetryFailed { error: &error, retry_in: wait });
                }
            }
        };
    }
}

/// Keeps the nodes running without a bus for `time` (their frames are discarded: the group is
/// cut off together). Returns false if `stop` was set meanwhile.
fn idle(nodes: &mut [&mut dyn AnyNode], clock: &dyn Clock, stop: &AtomicBool, time: Duration) -> bool {
    let until = Instant::now() + time;
    loop {
        if stop.load(Ordering::Relaxed) {
            return false;
        }
        let now = Instant::now();
        if now >= until {
            return true;
        }
        let mut next = MAX_WAIT;
        for node in nodes.iter_mut() {
            node.poll(clock.now(), &mut |_| {});
            next = next.min(Duration::from_micros(node.next_deadline().saturating_sub(clock.now())));
        }
        std::thread::sleep(next.min(until - now).max(Duration::from_micros(200)));
    }
}
