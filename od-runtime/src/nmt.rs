//! NMT states and commands (CiA 301 §7.3.2).

/// The NMT state of the device.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum NmtState {
    /// Before the boot-up message (and during a reset).
    Initialising,
    /// SDO, SYNC, EMCY, NMT and error control; no PDOs.
    PreOperational,
    /// Every service.
    Operational,
    /// NMT and error control (heartbeat, node guarding) only.
    Stopped,
}

impl NmtState {
    /// The state byte of heartbeat and node guarding messages (0 = boot-up).
    pub const fn code(self) -> u8 {
        match self {
            NmtState::Initialising => 0x00,
            NmtState::PreOperational => 0x7F,
            NmtState::Operational => 0x05,
            NmtState::Stopped => 0x04,
        }
    }

    /// The state a heartbeat or node guarding state byte reports (bit 7, the guarding toggle,
    /// ignored); `None` for a value CiA 301 does not define.
    pub const fn from_code(code: u8) -> Option<Self> {
        match code & 0x7F {
            0x00 => Some(NmtState::Initialising),
            0x7F => Some(NmtState::PreOperational),
            0x05 => Some(NmtState::Operational),
            0x04 => Some(NmtState::Stopped),
            _ => None,
        }
    }

    /// Whether SDO transfers are served.
    pub const fn sdo_allowed(self) -> bool {
        matches!(self, NmtState::PreOperational | NmtState::Operational)
    }

    /// Whether EMCY messages are sent and SYNC messages processed.
    pub const fn emcy_sync_allowed(self) -> bool {
        matches!(self, NmtState::PreOperational | NmtState::Operational)
    }

    /// Whether PDOs are sent and received.
    pub const fn pdo_allowed(self) -> bool {
        matches!(self, NmtState::Operational)
    }
}

/// An NMT node control command (first byte of a frame on COB-ID 0).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum NmtCommand {
    /// 0x01: enter Operational.
    Start,
    /// 0x02: enter Stopped.
    Stop,
    /// 0x80: enter Pre-operational.
    EnterPreOperational,
    /// 0x81: reset the whole node (every area to its default or stored value).
    ResetNode,
    /// 0x82: reset the communication area (1000h..1FFFh).
    ResetCommunication,
}

impl NmtCommand {
    /// The command specifier (first byte of the NMT frame).
    pub const fn code(self) -> u8 {
        match self {
            NmtCommand::Start => 0x01,
            NmtCommand::Stop => 0x02,
            NmtCommand::EnterPreOperational => 0x80,
            NmtCommand::ResetNode => 0x81,
            NmtCommand::ResetCommunication => 0x82,
        }
    }

    /// Decodes a command specifier.
    pub const fn from_byte(cs: u8) -> Option<Self> {
        match cs {
            0x01 => Some(NmtCommand::Start),
            0x02 => Some(NmtCommand::Stop),
            0x80 => Some(NmtCommand::EnterPreOperational),
            0x81 => Some(NmtCommand::ResetNode),
            0x82 => Some(NmtCommand::ResetCommunication),
            _ => None,
        }
    }
}
