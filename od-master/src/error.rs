//! What goes wrong, each error naming the node and the object it is about.
//!
//! Display and Debug say the same facts: Debug (what `main() -> Result<(), Error>` prints)
//! is the variant's name and the Display text, with indices in hex and abort codes named, not
//! the nested structs with decimal numbers.

use std::fmt;
use std::time::Duration;

use od_bus::TransportError;
use od_runtime::cia402::State;
use od_runtime::master::{PdoError, TransferError};

/// Why a call of the master failed.
#[derive(thiserror::Error)]
pub enum Error {
    /// An SDO transfer failed: the server's abort or this client's (timeout, wrong toggle bit,
    /// CRC, ...), named with its CiA 301 text, with the node and the object. `attempts` is the
    /// number of times the transfer was started (more than 1 when it was retried); `context`
    /// what the bus knew beside it (the link was down, the node was never heard from).
    #[error("{}", SdoText { error, attempts: *attempts, context: context.as_ref() })]
    Sdo {
        /// The node, the object, the direction and the abort code.
        error: TransferError,
        /// Transfers started, the first one included.
        attempts: u8,
        /// What explains a client-side failure, when the bus knows.
        context: Option<SdoContext>,
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
        error: crate::unit_error::UnitError,
    },
    /// An LSS request failed (CiA 305): the step, why, and the device it was meant for.
    #[error("{error}{}", device.map(|d| format!(" (device {d})")).unwrap_or_default())]
    Lss {
        /// The step and why.
        error: od_runtime::master::lss::LssError,
        /// The device selected (switch state selective, fastscan) when the step failed.
        device: Option<od_runtime::lss::Identity>,
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

impl Error {
    fn variant(&self) -> &'static str {
        match self {
            Error::Sdo { .. } => "Sdo",
            Error::Length { .. } => "Length",
            Error::TooLong { .. } => "TooLong",
            Error::Closed => "Closed",
            Error::Transport(_) => "Transport",
            Error::Pdo { .. } => "Pdo",
            Error::SyncCounter(_) => "SyncCounter",
            Error::NodeId(_) => "NodeId",
            Error::Refused { .. } => "Refused",
            Error::Unit { .. } => "Unit",
            Error::Lss { .. } => "Lss",
            Error::Rebooted { .. } => "Rebooted",
            Error::Axis(_) => "Axis",
        }
    }
}

/// `Sdo: node 4, upload of 6401h sub 1: aborted by the server: 0x06020000 (object does not
/// exist in the object dictionary)`: the variant and the Display text.
impl fmt::Debug for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {self}", self.variant())
    }
}

/// What the bus knew about a node and its link when one of its transfers failed.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum SdoContext {
    /// The bus's link was down (a socketcand server gone): the transfer could not go out, and
    /// the link did not come back within the node's
    /// [`SdoOptions::link_wait`](crate::SdoOptions::link_wait).
    LinkDown {
        /// Why the link went down, or why the last attempt to restore it failed.
        reason: String,
        /// How long it had been down when the transfer gave up.
        down_for: Duration,
    },
    /// Nothing (no heartbeat, boot-up, EMCY, PDO or SDO answer) was received from the node
    /// since the bus was opened: most likely it is not on this bus.
    NeverHeard,
}

/// The text of [`Error::Sdo`].
struct SdoText<'a> {
    error: &'a TransferError,
    attempts: u8,
    context: Option<&'a SdoContext>,
}

impl fmt::Display for SdoText<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let e = self.error;
        let attempts = if self.attempts > 1 { format!(" (after {} attempts)", self.attempts) } else { String::new() };
        match self.context {
            None => write!(f, "{e}{attempts}"),
            Some(SdoContext::LinkDown { reason, down_for }) => {
                let dir = match e.direction {
                    od_runtime::master::Direction::Upload => "upload of",
                    od_runtime::master::Direction::Download => "download to",
                };
                write!(
                    f,
                    "node {}, {dir} {:04X}h sub {}: the link to the bus is down ({reason}) and has been for {}; \
                     it did not come back within SdoOptions::link_wait (last outcome: {}{attempts})",
                    e.node,
                    e.index,
                    e.sub,
                    human(*down_for),
                    e.error
                )
            }
            Some(SdoContext::NeverHeard) => write!(
                f,
                "{e}{attempts}; nothing has been received from node {} since the bus was opened: is it on this bus \
                 (its node id, bit rate, power and wiring)?",
                e.node
            ),
        }
    }
}

/// A duration for people: `850 ms`, `1.5 s`, `2 min 5 s`.
pub(crate) fn human(d: Duration) -> String {
    let ms = d.as_millis();
    if ms < 1000 {
        format!("{ms} ms")
    } else if ms < 60_000 {
        let tenths = (ms + 50) / 100;
        if tenths.is_multiple_of(10) {
            format!("{} s", tenths / 10)
        } else {
            format!("{}.{} s", tenths / 10, tenths % 10)
        }
    } else {
        format!("{} min {} s", ms / 60_000, ms % 60_000 / 1000)
    }
}

/// A failed CiA 402 operation: which drive, the last statusword seen (with its age and its bits
/// in words), on which object, and what.
#[derive(thiserror::Error)]
#[error("drive {node} ({}), {index:04X}h sub {sub}: {kind}{}", describe_state(*state, *statusword, *seen), register_text(register.as_ref()))]
pub struct AxisError {
    /// The drive's node id.
    pub node: u8,
    /// The CiA 402 state of the last statusword seen, if one was read.
    pub state: Option<State>,
    /// The last statusword seen, if any.
    pub statusword: Option<u16>,
    /// How long before the error that statusword was read.
    pub seen: Option<Duration>,
    /// The object the operation was about (6041h while waiting for a state).
    pub index: u16,
    /// Its sub-index.
    pub sub: u8,
    /// What went wrong.
    pub kind: AxisErrorKind,
    /// The drive's own warning or status register, read when the operation failed (where the
    /// axis was given one: [`Axis::with_register`](crate::Axis::with_register)).
    pub register: Option<RegisterReading>,
}

/// Same text as Display.
impl fmt::Debug for AxisError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "AxisError: {self}")
    }
}

/// A vendor's warning or status register read after a failure, with the texts of its bits
/// that are set (from the device's sidecar).
#[derive(Clone, PartialEq, Eq)]
pub struct RegisterReading {
    /// The register's index.
    pub index: u16,
    /// Its sub-index.
    pub sub: u8,
    /// Its value.
    pub value: u32,
    /// The texts of the bits set that the sidecar names, lowest bit first.
    pub bits: Vec<String>,
}

impl fmt::Display for RegisterReading {
    /// `2006h = 0800h: Command refused`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:04X}h", self.index)?;
        if self.sub != 0 {
            write!(f, " sub {}", self.sub)?;
        }
        if self.value > 0xFFFF {
            write!(f, " = {:08X}h", self.value)?
        } else {
            write!(f, " = {:04X}h", self.value)?
        }
        if self.bits.is_empty() { Ok(()) } else { write!(f, ": {}", self.bits.join(", ")) }
    }
}

impl fmt::Debug for RegisterReading {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        fmt::Display::fmt(self, f)
    }
}

fn register_text(r: Option<&RegisterReading>) -> String {
    r.map(|r| format!("; the drive's register {r}")).unwrap_or_default()
}

/// What went wrong in a CiA 402 operation.
#[derive(thiserror::Error)]
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
    /// Checked before starting: the operation cannot succeed as the drive is set up.
    #[error("{0}")]
    Impossible(Impossible),
    /// Stopped waiting: the drive says the operation cannot end well.
    #[error("stopped waiting for {what}: {why}")]
    Stopped {
        /// What was waited for ("target reached", "homing attained", ...).
        what: String,
        /// What the drive said.
        why: StopReason,
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

/// Same text as Display.
impl fmt::Debug for AxisErrorKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{self}")
    }
}

/// What makes an operation impossible before it starts.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum Impossible {
    /// Homing method 0 (6098h): no homing method; the drive would never attain home.
    #[error(
        "homing method 0 (6098h) is no homing method: the drive would never attain home; give a method of the \
         drive's manual (Homing::method, `axis home --method N`)"
    )]
    NoHomingMethod,
    /// Profile velocity 0 (6081h): a profile-position move would never start.
    #[error(
        "profile velocity 6081h is 0: the move would never start; give a velocity (Move::velocity, \
         `axis move --velocity`) or write 6081h"
    )]
    NoProfileVelocity,
    /// The drive's supported drive modes (6502h) lack the mode, and so does its sidecar's
    /// list of the modes it runs though 6502h leaves them out (`not_in_6502h`).
    #[error("the drive does not support mode {mode} ({}): its supported drive modes 6502h = {supported:08X}h ({}){}", mode_name(*mode), supported_modes(*supported), added_modes(*added))]
    Mode {
        /// The mode of operation asked for (6060h).
        mode: i8,
        /// 6502h.
        supported: u32,
        /// The 6502h bits the device's sidecar adds (`[[mode]] not_in_6502h = true`: modes the
        /// drive runs though its 6502h leaves them out, as the AKD's cyclic synchronous position).
        added: u32,
    },
    /// The drive has no 6502h (supported drive modes) and its sidecar's `[[mode]]` list lacks
    /// the mode.
    #[error("the drive does not support mode {mode} ({}): it has no 6502h (supported drive modes) and its sidecar lists the modes {}", mode_name(*mode), mode_list(listed))]
    ModeNotListed {
        /// The mode of operation asked for (6060h).
        mode: i8,
        /// The modes the sidecar lists (6060h values).
        listed: Vec<i8>,
    },
    /// The drive is at a position limit (statusword bit 11, internal limit active) and the
    /// move goes further into it; a move the other way is allowed.
    #[error("the drive is limited by its {limit} and {what} goes further into it; a move the other way is allowed")]
    IntoLimit {
        /// Which limit, and what says so.
        limit: Limit,
        /// The move refused (`a move to 100000 from 65536`, `a velocity of 1000`).
        what: String,
    },
}

/// A position limit a drive is at: which side, and what says so.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Limit {
    /// The positive or the negative limit.
    pub side: od_sidecar::LimitSide,
    /// What says the drive is at it.
    pub by: LimitSource,
}

/// What tells which limit is active (statusword bit 11 alone does not).
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum LimitSource {
    /// A limit switch input of 60FDh (digital inputs: bit 0 negative, bit 1 positive limit
    /// switch).
    Switch {
        /// 60FDh as read.
        inputs: u32,
    },
    /// A software position limit (607Dh sub 1 minimum, sub 2 maximum) the position is at or
    /// the target is beyond.
    Software {
        /// The limit (607Dh sub 1 or sub 2).
        value: i32,
    },
    /// A bit of the drive's own register that its sidecar names as a limit (`[[warning]]
    /// limit = "positive"`).
    Register {
        /// The register.
        index: u16,
        /// Its sub-index.
        sub: u8,
        /// The bit.
        bit: u8,
        /// The sidecar's text for it.
        text: String,
    },
}

fn side_name(side: od_sidecar::LimitSide) -> &'static str {
    match side {
        od_sidecar::LimitSide::Positive => "positive",
        od_sidecar::LimitSide::Negative => "negative",
    }
}

impl fmt::Display for Limit {
    /// `positive limit switch (60FDh = 00000002h: bit 1 set)`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let side = side_name(self.side);
        match &self.by {
            LimitSource::Switch { inputs } => {
                let bit = if self.side == od_sidecar::LimitSide::Positive { 1 } else { 0 };
                write!(f, "{side} limit switch (digital inputs 60FDh = {inputs:08X}h: bit {bit} set)")
            }
            LimitSource::Software { value } => {
                let sub = if self.side == od_sidecar::LimitSide::Positive { 2 } else { 1 };
                write!(f, "{side} software position limit (607Dh sub {sub} = {value})")
            }
            LimitSource::Register { index, sub, bit, text } => {
                let sub = if *sub == 0 { String::new() } else { format!(" sub {sub}") };
                write!(f, "{side} limit (the drive's register {index:04X}h{sub} bit {bit}: {text})")
            }
        }
    }
}

/// Why a wait stopped before its timeout.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum StopReason {
    /// Statusword bit 11, internal limit active, went up (a limit switch, a software limit, a
    /// torque or velocity limit).
    #[error("statusword bit 11 (internal limit active) went up: the drive is at a limit")]
    InternalLimit,
    /// Statusword bit 7, warning, went up.
    #[error("statusword bit 7 (warning) went up")]
    Warning,
    /// The drive left Operation enabled (its power stage went off).
    #[error("the drive left Operation enabled{}", .0.map(|s| format!(" for {}", state_name(s))).unwrap_or_else(|| " (statusword shows no CiA 402 state)".into()))]
    LeftOperationEnabled(Option<State>),
    /// Statusword bit 11 (internal limit active) is set and the limit is the one the move
    /// heads for.
    #[error("the drive is limited by its {0}, in the direction of the move")]
    AtLimit(Limit),
    /// The drive sent an emergency message.
    #[error("the drive sent EMCY {code:04X}h{}", .text.as_ref().map(|t| format!(" ({t})")).unwrap_or_default())]
    Emergency {
        /// The EMCY's error code.
        code: u16,
        /// Its text from the device's sidecar, where known.
        text: Option<String>,
    },
}

/// A CiA 402 state in the standard's words: `Operation enabled`.
pub fn state_name(state: State) -> &'static str {
    state.name()
}

/// Statusword bits 7..=15 that are set, in CiA 402's words (bits 0..=6 are the state): `warning,
/// remote, internal limit active`.
pub fn statusword_bits(sw: u16) -> Vec<&'static str> {
    const NAMES: [(u16, &str); 9] = [
        (7, "warning"),
        (8, "bit 8 (manufacturer-specific)"),
        (9, "remote"),
        (10, "target reached"),
        (11, "internal limit active"),
        (12, "bit 12 (set-point acknowledge / homing attained / speed 0)"),
        (13, "bit 13 (following error / homing error)"),
        (14, "bit 14 (manufacturer-specific)"),
        (15, "bit 15 (manufacturer-specific)"),
    ];
    NAMES.iter().filter(|(bit, _)| sw & (1 << bit) != 0).map(|(_, name)| *name).collect()
}

/// A mode of operation (6060h) by name.
pub fn mode_name(mode: i8) -> &'static str {
    match mode {
        0 => "no mode",
        1 => "profile position",
        2 => "velocity",
        3 => "profile velocity",
        4 => "profile torque",
        6 => "homing",
        7 => "interpolated position",
        8 => "cyclic synchronous position",
        9 => "cyclic synchronous velocity",
        10 => "cyclic synchronous torque",
        m if m < 0 => "manufacturer-specific",
        _ => "reserved",
    }
}

/// The bit of 6502h for a mode of operation (CiA 402: bit n − 1 for modes 1..=10), `None` for
/// modes it has no bit for.
pub fn supported_mode_bit(mode: i8) -> Option<u32> {
    (1..=10).contains(&mode).then(|| 1 << (mode - 1))
}

fn supported_modes(supported: u32) -> String {
    let names: Vec<&str> =
        (1..=10).filter(|&m| supported_mode_bit(m).is_some_and(|b| supported & b != 0)).map(mode_name).collect();
    if names.is_empty() { "none of CiA 402's".into() } else { names.join(", ") }
}

fn added_modes(added: u32) -> String {
    if added == 0 {
        return String::new();
    }
    let names: Vec<&str> =
        (1..=10).filter(|&m| supported_mode_bit(m).is_some_and(|b| added & b != 0)).map(mode_name).collect();
    format!(", with {} taken from its sidecar (not_in_6502h)", names.join(", "))
}

fn mode_list(listed: &[i8]) -> String {
    if listed.is_empty() {
        return "none".into();
    }
    listed.iter().map(|m| format!("{m} ({})", mode_name(*m))).collect::<Vec<_>>().join(", ")
}

fn describe_state(state: Option<State>, statusword: Option<u16>, seen: Option<Duration>) -> String {
    let Some(sw) = statusword else { return "no statusword read yet".to_owned() };
    let state = state.map_or("no CiA 402 state", state_name);
    let age = seen.map(|d| format!(" {} ago", human(d))).unwrap_or_default();
    let bits = statusword_bits(sw);
    let bits = if bits.is_empty() { String::new() } else { format!("; {}", bits.join(", ")) };
    format!("last statusword seen {sw:04X}h{age}: {state}{bits}")
}
