//! The SYNC producer (CiA 301 §7.2.5) with the optional counter of 1019h.

use crate::frame::{Frame, Micros};

/// The SYNC COB-ID by default (1005h).
pub const DEFAULT_COB_ID: u16 = 0x080;

/// A counter overflow value 1019h does not allow (1 and 241..=255 are reserved).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct InvalidOverflow(pub u8);

/// Sends SYNC every period, with a counter when 1019h asks for one.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SyncProducer {
    cob_id: u16,
    period: Micros,
    overflow: u8,
    counter: u8,
    next: Option<Micros>,
}

impl SyncProducer {
    /// A producer on COB-ID 080h every `period` (the communication cycle period, 1006h),
    /// without counter, stopped.
    pub const fn new(period: Micros) -> Self {
        Self { cob_id: DEFAULT_COB_ID, period, overflow: 0, counter: 1, next: None }
    }

    /// Sets the COB-ID (1005h bits 0..=10).
    pub const fn with_cob_id(mut self, cob_id: u16) -> Self {
        self.cob_id = cob_id & 0x7FF;
        self
    }

    /// Sets the synchronous counter overflow value (1019h): 0 sends SYNC without data, 2..=240
    /// sends a one-byte counter running 1, 2, ..., `overflow`, 1, ...
    pub const fn with_counter(mut self, overflow: u8) -> Result<Self, InvalidOverflow> {
        if overflow == 1 || overflow > 240 {
            return Err(InvalidOverflow(overflow));
        }
        self.overflow = overflow;
        self.counter = 1;
        Ok(self)
    }

    /// Starts sending: the first SYNC goes out at `now`, and the counter restarts at 1.
    pub fn start(&mut self, now: Micros) {
        self.counter = 1;
        self.next = if self.period == 0 { None } else { Some(now) };
    }

    /// Stops sending.
    pub fn stop(&mut self) {
        self.next = None;
    }

    /// Whether the producer is running.
    pub const fn is_running(&self) -> bool {
        self.next.is_some()
    }

    /// The SYNC frame to send now, advancing the counter: for a caller sending SYNC on its own
    /// schedule (or once, by hand).
    pub fn frame(&mut self) -> Frame {
        if self.overflow == 0 {
            return Frame::short(self.cob_id, [0; 8], 0);
        }
        let c = self.counter;
        self.counter = if c >= self.overflow { 1 } else { c + 1 };
        Frame::short(self.cob_id, [c, 0, 0, 0, 0, 0, 0, 0], 1)
    }

    /// Sends SYNC when it is due. SYNCs stay on the grid `start + k × period`: a late poll
    /// sends one frame and skips the periods that passed, so a stalled caller never sends a
    /// burst.
    pub fn poll(&mut self, now: Micros, mut emit: impl FnMut(Frame)) {
        let Some(next) = self.next else { return };
        if now < next {
            return;
        }
        let f = self.frame();
        emit(f);
        let missed = (now - next) / self.period;
        self.next = Some(next.saturating_add((missed + 1).saturating_mul(self.period)));
    }

    /// When the next SYNC is due (`None` when stopped).
    pub const fn deadline(&self) -> Option<Micros> {
        self.next
    }
}
