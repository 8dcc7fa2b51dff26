//! What goes wrong, each error naming the node and the object it is about.

use od_bus::TransportError;
use od_runtime::cia402::State;
use od_runtime::master::{PdoError, TransferError};

/// Why a call of the master failed.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// An SDO transfer failed: the server's abort or this client's (timeout, wrong toggle bit,
    /// CRC, ...), named with its CiA 301 text, with the node and the object. `attempts` is the
    /// number of times the transfer was started (more than 1 when it was retried).
    #[error("{error}{}", if *attempts > 1 { format!(" (after {attempts} attempts)") } else { String::new() })]
    Sdo {
        /// The node, the object, the direction and the abort code.
        error: TransferError,
        /// Transfers started, the first one included.
        attempts: u8,
    },
    /// A typed read got a value of another length than its type's.
    #[error("node {node}, {index:04X}h sub {sub}: {got} bytes where a {expected}-byte value was expected")]
    Length {
        /// The node.
        node: u8,
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// Bytes of the type asked for.
        expected: usize,
        /// Bytes received.
        got: usize,
    },
    /// Data longer than an SDO transfer can carry (4 GiB).
    #[error("node {node}, {index:04X}h sub {sub}: {len} bytes is more than an SDO transfer can carry")]
    TooLong {
        /// The node.
        node: u8,
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// The data's length.
        len: usize,
    },
    /// The bus task has ended: the bus was closed for good.
    #[error("the bus is closed")]
    Closed,
    /// The bus refused a frame (its link is down, it was closed, ...).
    #[error(transparent)]
    Transport(#[from] TransportError),
    /// A PDO mapping or value was refused.
    #[error("PDO {cob_id:03X}h: {error}")]
    Pdo {
        /// The PDO's COB-ID.
        cob_id: u16,
        /// What was wrong.
        error: PdoError,
    },
    /// A SYNC counter overflow value 1019h does not allow (1, 241..=255).
    #[error("SYNC counter overflow {0} is not 0 or 2..=240 (1019h)")]
    SyncCounter(u8),
    /// A node id outside 1..=127.
    #[error("node id {0} is outside 1..=127")]
    NodeId(u8),
    /// A value or a PDO mapping refused before anything was sent (a generated client's check
    /// of the EDS limits or mapping rules), with the abort code the device would answer with.
    #[error("node {node}, {index:04X}h sub {sub}: refused before sending: {code}")]
    Refused {
        /// The node.
        node: u8,
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// The abort code the device would give.
        code: od_runtime::od::AbortCode,
    },
    /// A quantity could not be converted to or from the entry's raw value.
    #[error("node {node}, {index:04X}h sub {sub}: {error}")]
    Unit {
        /// The node.
        node: u8,
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
        /// What was wrong.
        error: crate::remote::UnitError,
    },
    /// A CiA 402 operation failed.
    #[error(transparent)]
    Axis(#[from] Box<AxisError>),
    /// The node sent a boot-up message while this transfer was running or waiting: it
    /// restarted and forgot the transfer (and its configuration). Ended at once, not by its
    /// timeout.
    #[error("node {node}, {index:04X}h sub {sub}: the node rebooted (boot-up message) during the transfer")]
    Rebooted {
        /// The node.
        node: u8,
        /// Object index.
        index: u16,
        /// Sub-index.
        sub: u8,
    },
}

/// A failed CiA 402 operation: which drive, in which state, on which object, and what.
#[derive(Debug, thiserror::Error)]
#[error("drive {node} ({}), {index:04X}h sub {sub}: {kind}", describe_state(*state, *statusword))]
pub struct AxisError {
    /// The drive's node id.
    pub node: u8,
    /// Its CiA 402 state when the operation failed, if the statusword was read.
    pub state: Option<State>,
    /// The last statusword read, if any.
    pub statusword: Option<u16>,
    /// The object the operation was about (6041h while waiting for a state).
    pub index: u16,
    /// Its sub-index.
    pub sub: u8,
    /// What went wrong.
    pub kind: AxisErrorKind,
}

/// What went wrong in a CiA 402 operation.
#[derive(Debug, thiserror::Error)]
pub enum AxisErrorKind {
    /// An SDO transfer failed.
    #[error("{0}")]
    Sdo(Box<Error>),
    /// The statusword did not show what was waited for in time.
    #[error("{what} not confirmed by the statusword within {timeout_ms} ms")]
    Timeout {
        /// What was waited for ("Operation enabled", "homing attained", ...).
        what: String,
        /// How long it was waited for.
        timeout_ms: u64,
    },
    /// The drive went to Fault (or Fault reaction active) while this ran.
    #[error("the drive faulted (error code 603Fh = {error_code:04X}h)")]
    Fault {
        /// The drive's error code (603Fh), 0 if it could not be read.
        error_code: u16,
    },
    /// Statusword bit 13 (homing error, following error) went up.
    #[error("statusword bit 13 set: {0}")]
    Bit13(&'static str),
    /// 6061h does not show the mode of operation written to 6060h.
    #[error("modes of operation display shows {shown}, not {wanted}")]
    Mode {
        /// The mode written to 6060h.
        wanted: i8,
        /// What 6061h shows.
        shown: i8,
    },
    /// The drive does not acknowledge a new set-point (statusword bit 12).
    #[error("set-point not acknowledged (statusword bit 12) within {timeout_ms} ms")]
    SetPoint {
        /// How long it was waited for.
        timeout_ms: u64,
    },
    /// The operation was cut short by what happened to the drive or the bus.
    #[error("{0}")]
    Interrupted(Interruption),
}

/// What ended a CiA 402 operation at once, rather than at its timeout.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum Interruption {
    /// The drive sent a boot-up message: it restarted with its defaults (Switch on disabled,
    /// its mappings gone) and does not move until the application recovers it.
    #[error(
        "the drive rebooted (boot-up message): it is in Switch on disabled with its defaults; recover() enables it again"
    )]
    Rebooted,
    /// Its heartbeat (or guarding) was lost.
    #[error("the drive's heartbeat was lost")]
    Lost,
    /// The link to the bus went down (socketcand).
    #[error("the link to the bus went down: {0}")]
    LinkDown(String),
}

fn describe_state(state: Option<State>, statusword: Option<u16>) -> String {
    match (state, statusword) {
        (Some(s), Some(sw)) => format!("in {s:?}, statusword {sw:04X}h"),
        (None, Some(sw)) => format!("statusword {sw:04X}h, no CiA 402 state"),
        _ => "state unknown".to_owned(),
    }
}
