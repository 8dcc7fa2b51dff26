//! The CAN controller's own state (error-active, warning, error-passive, bus-off), as a
//! controller reports its changes: SocketCAN in error frames (`linux/can/error.h`), an slcan
//! adapter in its status flags.

use std::fmt;

/// A change of the CAN controller's state.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum ControllerState {
    /// Error-active again: both error counters are below 128 (after warning or passive).
    ErrorActive,
    /// An error counter passed the warning level (96).
    ErrorWarning,
    /// Error-passive: an error counter passed 127; the controller only signals errors
    /// recessively and waits longer before it sends.
    ErrorPassive,
    /// Bus-off: the transmit error counter passed 255; the controller neither sends nor
    /// receives until it is restarted.
    BusOff,
    /// The controller was restarted after bus-off (by the driver's `restart-ms`, by hand, or by
    /// an slcan session closing and opening its channel).
    Restarted,
}

/// `linux/can/error.h`: the classes in an error frame's identifier and the controller's
/// problem bits in its data byte 1.
mod can_err {
    /// The error frame flag of a SocketCAN identifier (`CAN_ERR_FLAG`).
    pub const FLAG: u32 = 0x2000_0000;
    pub const CRTL: u32 = 0x0000_0004;
    pub const BUSOFF: u32 = 0x0000_0040;
    pub const RESTARTED: u32 = 0x0000_0100;
    pub const CRTL_RX_WARNING: u8 = 0x04;
    pub const CRTL_TX_WARNING: u8 = 0x08;
    pub const CRTL_RX_PASSIVE: u8 = 0x10;
    pub const CRTL_TX_PASSIVE: u8 = 0x20;
    pub const CRTL_ACTIVE: u8 = 0x40;
}

/// The error classes a bus that reports its controller's state subscribes to: controller
/// problems (the warning, passive and active changes), bus-off and restarted. Not the bus
/// errors, arbitration and protocol errors, which come one per damaged frame and say nothing
/// about the state.
#[cfg(all(target_os = "linux", feature = "tokio"))]
pub(crate) const STATE_ERROR_CLASSES: u32 = can_err::CRTL | can_err::BUSOFF | can_err::RESTARTED;

impl ControllerState {
    /// The state change a SocketCAN error frame reports (its identifier, with or without the
    /// error flag, and its data), if it reports one. Bus-off and restarted come first, then the
    /// controller's problem bits in data byte 1: passive (rx or tx), else warning, else back to
    /// active. Other errors (a lost arbitration, a protocol error, an overflow alone) are not a
    /// change of state: `None`.
    pub fn from_error_frame(id: u32, data: &[u8]) -> Option<Self> {
        let class = id & !can_err::FLAG;
        if class & can_err::BUSOFF != 0 {
            return Some(Self::BusOff);
        }
        if class & can_err::RESTARTED != 0 {
            return Some(Self::Restarted);
        }
        if class & can_err::CRTL != 0 {
            let crtl = data.get(1).copied().unwrap_or(0);
            if crtl & (can_err::CRTL_RX_PASSIVE | can_err::CRTL_TX_PASSIVE) != 0 {
                return Some(Self::ErrorPassive);
            }
            if crtl & (can_err::CRTL_RX_WARNING | can_err::CRTL_TX_WARNING) != 0 {
                return Some(Self::ErrorWarning);
            }
            if crtl & can_err::CRTL_ACTIVE != 0 {
                return Some(Self::ErrorActive);
            }
        }
        None
    }
}

impl fmt::Display for ControllerState {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::ErrorActive => "error-active",
            Self::ErrorWarning => "error warning",
            Self::ErrorPassive => "error-passive",
            Self::BusOff => "bus-off",
            Self::Restarted => "restarted after bus-off",
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Error frames as the kernel's `can_change_state`, `can_bus_off` and `can_restart`
    /// (drivers/net/can/dev) send them.
    #[test]
    fn error_frames_as_the_kernel_sends_them() {
        let table: &[(u32, &[u8], Option<ControllerState>)] = &[
            // can_bus_off: CAN_ERR_BUSOFF (with CAN_ERR_CNT on newer kernels).
            (0x2000_0040, &[0; 8], Some(ControllerState::BusOff)),
            (0x2000_0240, &[0, 0, 0, 0, 0, 0, 0xF8, 0], Some(ControllerState::BusOff)),
            // can_restart: CAN_ERR_RESTARTED.
            (0x2000_0100, &[0; 8], Some(ControllerState::Restarted)),
            // can_change_state: CAN_ERR_CRTL | CAN_ERR_CNT, data[1] the tx and rx state bits.
            (0x2000_0204, &[0, 0x0C, 0, 0, 0, 0, 97, 0], Some(ControllerState::ErrorWarning)),
            (0x2000_0204, &[0, 0x08, 0, 0, 0, 0, 97, 0], Some(ControllerState::ErrorWarning)),
            (0x2000_0204, &[0, 0x04, 0, 0, 0, 0, 0, 97], Some(ControllerState::ErrorWarning)),
            (0x2000_0204, &[0, 0x30, 0, 0, 0, 0, 128, 128], Some(ControllerState::ErrorPassive)),
            (0x2000_0204, &[0, 0x20, 0, 0, 0, 0, 128, 0], Some(ControllerState::ErrorPassive)),
            (0x2000_0204, &[0, 0x10, 0, 0, 0, 0, 0, 128], Some(ControllerState::ErrorPassive)),
            (0x2000_0204, &[0, 0x40, 0, 0, 0, 0, 0, 0], Some(ControllerState::ErrorActive)),
            (0x0000_0004, &[0, 0x40], Some(ControllerState::ErrorActive)),
            // Not a change of state: protocol errors, bus errors, lost arbitration, an
            // overflow alone, an unspecified controller problem, no data.
            (0x2000_0088, &[0, 0, 0x04, 0x0A, 0, 0, 0, 0], None),
            (0x2000_0002, &[7, 0, 0, 0, 0, 0, 0, 0], None),
            (0x2000_0004, &[0, 0x01, 0, 0, 0, 0, 0, 0], None),
            (0x2000_0004, &[0, 0, 0, 0, 0, 0, 0, 0], None),
            (0x2000_0004, &[], None),
        ];
        for (id, data, want) in table {
            assert_eq!(ControllerState::from_error_frame(*id, data), *want, "{id:08X} {data:02X?}");
        }
    }
}
