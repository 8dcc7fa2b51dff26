//! Running a node in real time on an endpoint.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use od_runtime::Micros;

use super::AnyNode;
use od_bus::{Endpoint, TransportError};

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
    let mut stats = RunStats::default();
    run_counting(node, bus, clock, stop, &mut stats).map(|()| stats)
}

fn run_counting(
    node: &mut dyn AnyNode,
    bus: &mut dyn Endpoint,
    clock: &dyn Clock,
    stop: &AtomicBool,
    stats: &mut RunStats,
) -> Result<(), TransportError> {
    let mut out = Vec::with_capacity(16);
    loop {
        if stop.load(Ordering::Relaxed) {
            return Ok(());
        }
        let now = clock.now();
        let deadline = node.next_deadline();
        if now < deadline {
            let wait = Duration::from_micros(deadline - now).min(MAX_WAIT);
            if let Some(frame) = bus.recv_timeout(wait)? {
                stats.received += 1;
                node.handle(&frame, clock.now());
            } else {
                continue;
            }
        }
        node.poll(clock.now(), &mut |f| out.push(f));
        stats.polls += 1;
        for frame in out.drain(..) {
            bus.send(frame)?;
            stats.sent += 1;
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
        let result = run_counting(node, &mut *bus, clock, stop, &mut stats);
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
            if !idle(node, clock, stop, wait) {
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

/// Keeps `node` running without a bus for `time` (its frames are discarded). Returns false if
/// `stop` was set meanwhile.
fn idle(node: &mut dyn AnyNode, clock: &dyn Clock, stop: &AtomicBool, time: Duration) -> bool {
    let until = Instant::now() + time;
    loop {
        if stop.load(Ordering::Relaxed) {
            return false;
        }
        let now = Instant::now();
        if now >= until {
            return true;
        }
        node.poll(clock.now(), &mut |_| {});
        let next = Duration::from_micros(node.next_deadline().saturating_sub(clock.now()));
        std::thread::sleep(next.min(MAX_WAIT).min(until - now).max(Duration::from_micros(200)));
    }
}
