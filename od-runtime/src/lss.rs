//! Layer setting services (CiA 305): how a master gives a device its node-ID and bit rate over
//! the bus, and finds devices that have none.
//!
//! Both sides share this module's constants: the two COB-IDs ([`MASTER_COB`] 7E5h, the
//! master's requests; [`SLAVE_COB`] 7E4h, the answers), the command specifiers ([`cs`]) and the
//! bit timing table ([`BIT_RATES`]). [`LssSlave`] is the device's machine; the
//! [`Device`](crate::Device) runs it when od-runtime's `lss` feature is on and either the
//! dictionary says so ([`ObjectDictionary::LSS`](crate::od::ObjectDictionary::LSS), from the
//! EDS's `LSS_Supported=1`) or the application turned it on
//! ([`Device::enable_lss`](crate::Device::enable_lss)). The master's machine is
//! [`master::lss`](crate::master::lss).
//!
//! Every request is one 8-byte frame on 7E5h whose first byte is the command specifier;
//! answers are 8-byte frames on 7E4h with the same specifier (or 44h, 4Fh, 50h for the
//! switch, identify and non-configured answers). Unused bytes are zero.
//!
//! ```
//! use od_runtime::lss::{Identity, LssAction, LssSlave, Mode};
//!
//! let id = Identity { vendor: 0x1234, product: 2, revision: 3, serial: 7 };
//! let mut slave = LssSlave::new(0xFF); // no node-ID yet
//! // Switch state global: configuration.
//! assert_eq!(slave.on_request(&[0x04, 1, 0, 0, 0, 0, 0, 0], &id), LssAction::None);
//! assert_eq!(slave.mode(), Mode::Configuration);
//! // Configure node-ID 5: answered with error code 0.
//! slave.on_request(&[0x11, 5, 0, 0, 0, 0, 0, 0], &id);
//! assert_eq!(slave.take_reply(), Some([0x11, 0, 0, 0, 0, 0, 0, 0]));
//! // Back to waiting: a device without a node-ID starts with the new one.
//! assert_eq!(slave.on_request(&[0x04, 0, 0, 0, 0, 0, 0, 0], &id), LssAction::ApplyNodeId(5));
//! ```

/// The COB-ID of the master's requests.
pub const MASTER_COB: u16 = 0x7E5;
/// The COB-ID of the slaves' answers.
pub const SLAVE_COB: u16 = 0x7E4;
/// The node-ID of a device that has none ("not configured").
pub const UNCONFIGURED: u8 = 0xFF;

/// The CiA 305 command specifiers (first byte of every LSS frame).
pub mod cs {
    /// Switch state global (byte 1: 0 = waiting, 1 = configuration). No answer.
    pub const SWITCH_GLOBAL: u8 = 0x04;
    /// Configure node-ID (byte 1: 1..=127 or FFh). Answer: error code, specific error.
    pub const CONFIGURE_NODE_ID: u8 = 0x11;
    /// Configure bit timing (byte 1: table selector, 0 = CiA; byte 2: table index).
    pub const CONFIGURE_BIT_TIMING: u8 = 0x13;
    /// Activate bit timing (bytes 1..2: switch delay in ms). No answer.
    pub const ACTIVATE_BIT_TIMING: u8 = 0x15;
    /// Store configuration. Answer: error code, specific error.
    pub const STORE: u8 = 0x17;
    /// Switch state selective: vendor-ID (bytes 1..4).
    pub const SWITCH_VENDOR: u8 = 0x40;
    /// Switch state selective: product code.
    pub const SWITCH_PRODUCT: u8 = 0x41;
    /// Switch state selective: revision number.
    pub const SWITCH_REVISION: u8 = 0x42;
    /// Switch state selective: serial number (the last of the four).
    pub const SWITCH_SERIAL: u8 = 0x43;
    /// The answer of the device whose identity matched all four.
    pub const SWITCH_RESPONSE: u8 = 0x44;
    /// Identify remote slave: vendor-ID.
    pub const IDENTIFY_VENDOR: u8 = 0x46;
    /// Identify remote slave: product code.
    pub const IDENTIFY_PRODUCT: u8 = 0x47;
    /// Identify remote slave: revision number, low bound.
    pub const IDENTIFY_REVISION_LOW: u8 = 0x48;
    /// Identify remote slave: revision number, high bound.
    pub const IDENTIFY_REVISION_HIGH: u8 = 0x49;
    /// Identify remote slave: serial number, low bound.
    pub const IDENTIFY_SERIAL_LOW: u8 = 0x4A;
    /// Identify remote slave: serial number, high bound (the last of the six).
    pub const IDENTIFY_SERIAL_HIGH: u8 = 0x4B;
    /// Identify non-configured remote slave.
    pub const IDENTIFY_NON_CONFIGURED: u8 = 0x4C;
    /// The answer of an identified slave (identify remote slave, fastscan).
    pub const IDENTIFY_RESPONSE: u8 = 0x4F;
    /// The answer of a non-configured slave.
    pub const NON_CONFIGURED_RESPONSE: u8 = 0x50;
    /// Fastscan (bytes 1..4: ID number, 5: bit checked, 6: LSS sub, 7: LSS next).
    pub const FASTSCAN: u8 = 0x51;
    /// Inquire identity: vendor-ID.
    pub const INQUIRE_VENDOR: u8 = 0x5A;
    /// Inquire identity: product code.
    pub const INQUIRE_PRODUCT: u8 = 0x5B;
    /// Inquire identity: revision number.
    pub const INQUIRE_REVISION: u8 = 0x5C;
    /// Inquire identity: serial number.
    pub const INQUIRE_SERIAL: u8 = 0x5D;
    /// Inquire node-ID.
    pub const INQUIRE_NODE_ID: u8 = 0x5E;
}

/// The fastscan "bit checked" value that restarts a scan (every non-configured slave answers).
pub const FASTSCAN_CONFIRM: u8 = 0x80;

/// The CiA 305 bit timing table (selector 0): the bit rate in kbit/s of each index, `None` for
/// the reserved index 5 and for 9 (automatic bit rate detection), which this stack does not
/// offer.
pub const BIT_RATES: [Option<u16>; 10] =
    [Some(1000), Some(800), Some(500), Some(250), Some(125), None, Some(50), Some(20), Some(10), None];

/// The table index of a bit rate in kbit/s, `None` when the CiA 305 table has no such rate.
pub fn bit_rate_index(kbit: u32) -> Option<u8> {
    BIT_RATES.iter().position(|r| r.map(u32::from) == Some(kbit)).map(|i| i as u8)
}

/// The bit rate in kbit/s of a table index, `None` for an index the table does not define.
pub fn bit_rate_kbit(index: u8) -> Option<u16> {
    BIT_RATES.get(usize::from(index)).copied().flatten()
}

/// A device's LSS address: its identity object 1018h, sub-indices 1 to 4.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Identity {
    /// 1018h:1.
    pub vendor: u32,
    /// 1018h:2.
    pub product: u32,
    /// 1018h:3.
    pub revision: u32,
    /// 1018h:4.
    pub serial: u32,
}

impl Identity {
    /// Part `n` (0 = vendor .. 3 = serial), as fastscan's LSS sub numbers them.
    pub const fn part(&self, n: u8) -> u32 {
        match n {
            0 => self.vendor,
            1 => self.product,
            2 => self.revision,
            _ => self.serial,
        }
    }

    /// The four parts in fastscan's order.
    pub const fn parts(&self) -> [u32; 4] {
        [self.vendor, self.product, self.revision, self.serial]
    }
}

impl core::fmt::Display for Identity {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        write!(
            f,
            "vendor {:08X}h, product {:08X}h, revision {:08X}h, serial {:08X}h",
            self.vendor, self.product, self.revision, self.serial
        )
    }
}

/// The LSS state of a slave.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Mode {
    /// LSS waiting: only switch, identify and fastscan requests are served.
    Waiting,
    /// LSS configuration: the configure, store and inquire services too.
    Configuration,
}

/// What the device does after a request, beyond the answer ([`LssSlave::take_reply`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum LssAction {
    /// Nothing.
    None,
    /// A device without a node-ID went back to waiting with one pending: it starts with it
    /// (NMT reset communication, boot-up).
    ApplyNodeId(u8),
    /// Store configuration: the device stores the pending node-ID and bit timing index (if
    /// one was configured) and answers with [`LssSlave::stored`].
    Store {
        /// The pending node-ID.
        node_id: u8,
        /// The pending bit timing table index.
        bit_rate: Option<u8>,
    },
    /// Activate bit timing: switch to the configured rate after `delay_ms`, wait as long
    /// again before sending.
    ActivateBitTiming {
        /// The table index to switch to.
        index: u8,
        /// The switch delay in ms.
        delay_ms: u16,
    },
}

/// The error codes of the configure and store answers (byte 1).
pub mod error {
    /// Done.
    pub const OK: u8 = 0;
    /// Configure node-ID: out of range. Configure bit timing: not supported. Store: not
    /// supported.
    pub const UNSUPPORTED: u8 = 1;
    /// Store: storage media access error.
    pub const STORAGE: u8 = 2;
}

/// Progress through a sequence of requests that must come in order (switch selective,
/// identify remote slave): how many matched so far.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Sequence {
    step: u8,
    ok: bool,
}

impl Sequence {
    const START: Self = Self { step: 0, ok: true };

    /// Advances with request number `n` (0-based) whose match is `hit`; a request out of order
    /// restarts the sequence, or starts it when it is the first. Whether `n` was the last
    /// (`last`) and everything matched.
    fn step(&mut self, n: u8, hit: bool, last: u8) -> bool {
        if n == 0 {
            *self = Self { step: 1, ok: hit };
        } else if n == self.step {
            self.step += 1;
            self.ok &= hit;
        } else {
            *self = Self { step: 0, ok: false };
            return false;
        }
        if n == last {
            let done = self.ok;
            *self = Self::START;
            return done;
        }
        false
    }
}

/// The device's LSS machine: state, pending node-ID and bit rate, the progress of switch
/// selective, identify remote slave and fastscan, and the one answer due.
///
/// Sans-IO, as the rest of the device: [`LssSlave::on_request`] takes a request's data and the
/// device's identity, [`LssSlave::take_reply`] gives the answer to send on [`SLAVE_COB`].
#[derive(Clone, Copy, Debug)]
pub struct LssSlave {
    mode: Mode,
    active: u8,
    pending: u8,
    bit_rate: Option<u8>,
    pending_bit_rate: Option<u8>,
    selective: Sequence,
    remote: Sequence,
    revision_low: u32,
    serial_low: u32,
    fastscan_pos: u8,
    reply: Option<[u8; 8]>,
}

impl LssSlave {
    /// A slave in LSS waiting whose active node-ID is `node_id` ([`UNCONFIGURED`] for none).
    pub const fn new(node_id: u8) -> Self {
        let node_id = if node_id >= 1 && node_id <= 127 { node_id } else { UNCONFIGURED };
        Self {
            mode: Mode::Waiting,
            active: node_id,
            pending: node_id,
            bit_rate: None,
            pending_bit_rate: None,
            selective: Sequence::START,
            remote: Sequence::START,
            revision_low: 0,
            serial_low: 0,
            fastscan_pos: 0,
            reply: None,
        }
    }

    /// The LSS state.
    pub const fn mode(&self) -> Mode {
        self.mode
    }

    /// The node-ID in use ([`UNCONFIGURED`] for none).
    pub const fn active_node_id(&self) -> u8 {
        self.active
    }

    /// The node-ID configured, which a reset (or, without an active one, the switch back to
    /// waiting) makes active.
    pub const fn pending_node_id(&self) -> u8 {
        self.pending
    }

    /// Whether the device has no node-ID.
    pub const fn is_unconfigured(&self) -> bool {
        self.active == UNCONFIGURED
    }

    /// The bit timing table index in use, when known (stored, or activated over LSS).
    pub const fn bit_rate(&self) -> Option<u8> {
        self.bit_rate
    }

    /// Sets the bit timing table index in use (the one the device started with).
    pub fn set_bit_rate(&mut self, index: Option<u8>) {
        self.bit_rate = index;
    }

    /// Makes the pending node-ID the active one (the device's NMT reset communication and
    /// reset node do this) and returns it.
    pub fn activate_pending(&mut self) -> u8 {
        self.active = self.pending;
        self.active
    }

    /// Sets both node-IDs (a node-ID loaded from storage at start-up, or set by the application).
    pub fn set_node_id(&mut self, node_id: u8) {
        let id = if (1..=127).contains(&node_id) { node_id } else { UNCONFIGURED };
        self.active = id;
        self.pending = id;
    }

    /// The answer due, if any (data of a frame on [`SLAVE_COB`]).
    pub fn take_reply(&mut self) -> Option<[u8; 8]> {
        self.reply.take()
    }

    /// The answer to a [`LssAction::Store`], once the device has stored (or failed to).
    pub fn stored(&mut self, ok: Result<(), u8>) {
        self.reply = Some(answer(cs::STORE, &[ok.err().unwrap_or(error::OK)]));
    }

    /// Serves one request (the data of a frame on [`MASTER_COB`]). Frames of another length
    /// than 8 and unknown specifiers are ignored, as CiA 305 asks.
    pub fn on_request(&mut self, data: &[u8], identity: &Identity) -> LssAction {
        let Ok(d) = <[u8; 8]>::try_from(data) else { return LssAction::None };
        let value = u32::from_le_bytes([d[1], d[2], d[3], d[4]]);
        let config = self.mode == Mode::Configuration;
        match d[0] {
            cs::SWITCH_GLOBAL => match d[1] {
                0 => return self.enter_waiting(),
                1 => {
                    self.mode = Mode::Configuration;
                    self.selective = Sequence::START;
                }
                _ => {}
            },
            c @ cs::SWITCH_VENDOR..=cs::SWITCH_SERIAL => {
                let n = c - cs::SWITCH_VENDOR;
                if self.mode == Mode::Waiting && self.selective.step(n, value == identity.part(n), 3) {
                    self.mode = Mode::Configuration;
                    self.reply = Some(answer(cs::SWITCH_RESPONSE, &[]));
                }
            }
            cs::CONFIGURE_NODE_ID if config => {
                let id = d[1];
                let ok = (1..=127).contains(&id) || id == UNCONFIGURED;
                if ok {
                    self.pending = id;
                }
                self.reply = Some(answer(cs::CONFIGURE_NODE_ID, &[if ok { error::OK } else { error::UNSUPPORTED }]));
            }
            cs::CONFIGURE_BIT_TIMING if config => {
                let ok = d[1] == 0 && bit_rate_kbit(d[2]).is_some();
                if ok {
                    self.pending_bit_rate = Some(d[2]);
                }
                self.reply = Some(answer(cs::CONFIGURE_BIT_TIMING, &[if ok { error::OK } else { error::UNSUPPORTED }]));
            }
            cs::ACTIVATE_BIT_TIMING if config => {
                if let Some(index) = self.pending_bit_rate {
                    self.bit_rate = Some(index);
                    return LssAction::ActivateBitTiming { index, delay_ms: u16::from_le_bytes([d[1], d[2]]) };
                }
            }
            cs::STORE if config => {
                return LssAction::Store { node_id: self.pending, bit_rate: self.pending_bit_rate.or(self.bit_rate) };
            }
            c @ cs::INQUIRE_VENDOR..=cs::INQUIRE_SERIAL if config => {
                let v = identity.part(c - cs::INQUIRE_VENDOR).to_le_bytes();
                self.reply = Some(answer(c, &v));
            }
            cs::INQUIRE_NODE_ID if config => self.reply = Some(answer(cs::INQUIRE_NODE_ID, &[self.active])),
            c @ cs::IDENTIFY_VENDOR..=cs::IDENTIFY_SERIAL_HIGH => {
                let n = c - cs::IDENTIFY_VENDOR;
                let hit = match c {
                    cs::IDENTIFY_VENDOR => value == identity.vendor,
                    cs::IDENTIFY_PRODUCT => value == identity.product,
                    cs::IDENTIFY_REVISION_LOW => {
                        self.revision_low = value;
                        true
                    }
                    cs::IDENTIFY_REVISION_HIGH => (self.revision_low..=value).contains(&identity.revision),
                    cs::IDENTIFY_SERIAL_LOW => {
                        self.serial_low = value;
                        true
                    }
                    _ => (self.serial_low..=value).contains(&identity.serial),
                };
                if self.remote.step(n, hit, 5) {
                    self.reply = Some(answer(cs::IDENTIFY_RESPONSE, &[]));
                }
            }
            cs::IDENTIFY_NON_CONFIGURED if self.pending == UNCONFIGURED && self.active == UNCONFIGURED => {
                self.reply = Some(answer(cs::NON_CONFIGURED_RESPONSE, &[]));
            }
            cs::FASTSCAN => self.fastscan(value, d[5], d[6], d[7], identity),
            _ => {}
        }
        LssAction::None
    }

    /// Switch state global waiting: a device without a node-ID that got one starts with it.
    fn enter_waiting(&mut self) -> LssAction {
        let was = self.mode;
        self.mode = Mode::Waiting;
        self.selective = Sequence::START;
        if was == Mode::Configuration && self.active == UNCONFIGURED && self.pending != UNCONFIGURED {
            return LssAction::ApplyNodeId(self.activate_pending());
        }
        LssAction::None
    }

    /// Fastscan: only a device in waiting without a node-ID takes part.
    fn fastscan(&mut self, id: u32, bit: u8, sub: u8, next: u8, identity: &Identity) {
        if self.mode != Mode::Waiting || self.active != UNCONFIGURED || self.pending != UNCONFIGURED {
            return;
        }
        if bit == FASTSCAN_CONFIRM {
            self.fastscan_pos = 0;
            self.reply = Some(answer(cs::IDENTIFY_RESPONSE, &[]));
            return;
        }
        if bit > 31 || sub > 3 || next > 3 || sub != self.fastscan_pos {
            return;
        }
        let mask = u32::MAX << bit;
        if (id ^ identity.part(sub)) & mask != 0 {
            return;
        }
        self.reply = Some(answer(cs::IDENTIFY_RESPONSE, &[]));
        if bit == 0 {
            if next < sub {
                // The whole identity matched: this device is the one found.
                self.mode = Mode::Configuration;
                self.fastscan_pos = 0;
            } else {
                self.fastscan_pos = next;
            }
        }
    }
}

/// An answer: the specifier, then `rest`, zero-filled.
fn answer(cs: u8, rest: &[u8]) -> [u8; 8] {
    let mut d = [0u8; 8];
    d[0] = cs;
    for (o, b) in d[1..].iter_mut().zip(rest) {
        *o = *b;
    }
    d
}

/// What a device stores of its LSS configuration ([`Storage::save_lss`](crate::Storage::save_lss)).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct LssConfig {
    /// The node-ID, [`UNCONFIGURED`] for none.
    pub node_id: u8,
    /// The bit timing table index ([`BIT_RATES`]), when one was configured or is known.
    pub bit_rate: Option<u8>,
}
