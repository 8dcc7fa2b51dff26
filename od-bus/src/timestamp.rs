//! When a frame was seen on a bus: the hub stamps what it relays, the socketcand protocol
//! carries the stamp (`seconds.microseconds`), and the emulated wire passes it along.
//! (Parsing it from protocol text is the protocol's business, in `socketcand`.)

use std::fmt;
use std::time::{SystemTime, UNIX_EPOCH};

/// Reception time of a frame, as `seconds.microseconds` since the Unix epoch.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct Timestamp {
    secs: u64,
    micros: u32,
}

impl Timestamp {
    /// A timestamp; `None` when `micros` is a million or more.
    pub fn new(secs: u64, micros: u32) -> Option<Self> {
        (micros < 1_000_000).then_some(Self { secs, micros })
    }

    /// The current wall-clock time (zero if the clock is before 1970).
    pub fn now() -> Self {
        let since = SystemTime::now().duration_since(UNIX_EPOCH).unwrap_or_default();
        Self { secs: since.as_secs(), micros: since.subsec_micros() }
    }

    /// Whole seconds.
    pub fn secs(&self) -> u64 {
        self.secs
    }

    /// Microseconds within the second, below 1 000 000.
    pub fn micros(&self) -> u32 {
        self.micros
    }
}

impl fmt::Display for Timestamp {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}.{:06}", self.secs, self.micros)
    }
}
