//! Running a node in real time on an endpoint.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use od_runtime::Micros;

use super::AnyNode;
use crate::transport::{Endpoint, TransportError};

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
    let mut out = Vec::with_capacity(16);
    loop {
        if stop.load(Ordering::Relaxed) {
            return Ok(stats);
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
