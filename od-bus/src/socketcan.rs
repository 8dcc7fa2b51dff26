//! SocketCAN: a raw CAN socket on a Linux network interface (`can0`, `vcan0`), for running a
//! simulated device against real CAN hardware or a virtual CAN interface, through the
//! `socketcan` crate.
//!
//! Linux only. Classic CAN only: CAN FD frames are not requested from the kernel. The blocking
//! [`SocketCan`] endpoint does not subscribe to error frames (one that arrives all the same is
//! skipped); the async bus (`tokio::Bus`, feature `tokio`) subscribes to those that report the
//! controller's state and reports its changes ([`controller_state`]).
//!
//! ```no_run
//! use od_bus::{CanFrame, Endpoint, socketcan::SocketCan};
//! let mut bus = SocketCan::open("vcan0").unwrap();
//! bus.send(CanFrame::standard(0x080, &[]).unwrap()).unwrap();
//! ```

use std::fmt;
use std::io;
use std::os::fd::AsRawFd;
use std::time::{Duration, Instant};

use socketcan::{EmbeddedFrame, ExtendedId, Frame as _, Socket, StandardId};

use crate::controller::ControllerState;
use crate::endpoint::Endpoint;
use crate::error::TransportError;
use crate::frame::{CanFrame, FrameError};

/// An [`Endpoint`] on a Linux CAN interface.
///
/// Like every endpoint it does not receive its own frames (the kernel's default for raw
/// sockets, `CAN_RAW_RECV_OWN_MSGS` off); other sockets on the same interface do.
pub struct SocketCan {
    socket: socketcan::CanSocket,
    interface: String,
}

impl SocketCan {
    /// Opens a raw CAN socket bound to `interface`.
    pub fn open(interface: &str) -> Result<Self, TransportError> {
        let socket = socketcan::CanSocket::open(interface).map_err(|e| open_error(interface, e))?;
        Ok(Self { socket, interface: interface.to_owned() })
    }

    /// The interface name.
    pub fn interface(&self) -> &str {
        &self.interface
    }
}

/// Why `interface` could not be opened, naming it.
pub(crate) fn open_error(interface: &str, error: io::Error) -> TransportError {
    TransportError::io(format!("cannot open CAN interface {interface:?} (does it exist and is it up?)"), error)
}

/// The `socketcan` crate's frame for `frame`.
pub fn to_socketcan(frame: &CanFrame) -> socketcan::CanFrame {
    // A CanFrame's id always fits its format and its length is at most 8, so neither the id
    // nor the frame constructor can refuse; the fallbacks are never taken.
    let id: socketcan::Id = if frame.is_extended() {
        ExtendedId::new(frame.id()).map_or(socketcan::Id::Extended(ExtendedId::ZERO), socketcan::Id::Extended)
    } else {
        StandardId::new(frame.id() as u16).map_or(socketcan::Id::Standard(StandardId::ZERO), socketcan::Id::Standard)
    };
    let built = if frame.is_remote() {
        socketcan::CanFrame::new_remote(id, usize::from(frame.dlc()))
    } else {
        socketcan::CanFrame::new(id, frame.data())
    };
    built.unwrap_or_default()
}

/// A frame from the `socketcan` crate's; error frames are refused.
pub fn from_socketcan(frame: &socketcan::CanFrame) -> Result<CanFrame, FrameError> {
    if frame.is_error_frame() {
        return Err(FrameError::Notation("an error frame is not a data or remote frame"));
    }
    let dlc = u8::try_from(frame.dlc()).map_err(|_| FrameError::TooLong(frame.dlc()))?;
    let mut data = [0u8; 8];
    let bytes = frame.data();
    data[..bytes.len().min(8)].copy_from_slice(&bytes[..bytes.len().min(8)]);
    CanFrame::from_parts(frame.raw_id(), frame.is_extended(), frame.is_remote_frame(), dlc, data)
}

/// The controller state change an error frame from the kernel reports (bus-off, restarted,
/// error warning, error-passive, back to error-active), `None` for a data or remote frame and
/// for an error that is not a change of state (see [`ControllerState::from_error_frame`]).
pub fn controller_state(frame: &socketcan::CanFrame) -> Option<ControllerState> {
    match frame {
        socketcan::CanFrame::Error(error) => ControllerState::from_error_frame(error.error_bits(), error.data()),
        _ => None,
    }
}

/// Subscribes `socket` to the error frames that report the controller's state changes (the
/// async bus reports them: `tokio::Controller`).
#[cfg(feature = "tokio")]
pub(crate) fn subscribe_state_errors(socket: &impl socketcan::SocketOptions) -> io::Result<()> {
    socket.set_error_filter(crate::controller::STATE_ERROR_CLASSES)
}

impl Endpoint for SocketCan {
    fn send(&mut self, frame: CanFrame) -> Result<(), TransportError> {
        let raw = to_socketcan(&frame);
        // The interface's transmit queue can be momentarily full (ENOBUFS); retry for a while
        // as a CAN controller waits for bus access, then report it.
        let deadline = Instant::now() + Duration::from_millis(100);
        loop {
            let error = match self.socket.write_frame(&raw) {
                Ok(()) => return Ok(()),
                Err(error) => error,
            };
            let retry = error.raw_os_error() == Some(libc::ENOBUFS) || error.kind() == io::ErrorKind::Interrupted;
            if !retry || Instant::now() >= deadline {
                return Err(TransportError::io(format!("cannot send on {}", self.interface), error));
            }
            std::thread::sleep(Duration::from_millis(1));
        }
    }

    fn recv_timeout(&mut self, timeout: Duration) -> Result<Option<CanFrame>, TransportError> {
        let deadline = Instant::now().checked_add(timeout);
        loop {
            let remaining = deadline.map_or(Duration::MAX, |d| d.saturating_duration_since(Instant::now()));
            // A zero wait polls; a short one rounds up to a millisecond in poll(2), never down
            // to a busy loop.
            let read = if remaining.is_zero() {
                self.socket.set_nonblocking(true).and_then(|()| {
                    let read = self.socket.read_frame();
                    self.socket.set_nonblocking(false)?;
                    read
                })
            } else {
                self.socket.read_frame_timeout(remaining.max(Duration::from_millis(1)))
            };
            match read {
                // Not a frame an endpoint reports (an error frame): read on.
                Ok(frame) => {
                    if let Ok(frame) = from_socketcan(&frame) {
                        return Ok(Some(frame));
                    }
                }
                Err(error) if matches!(error.kind(), io::ErrorKind::WouldBlock | io::ErrorKind::TimedOut) => {}
                Err(error) if error.kind() == io::ErrorKind::Interrupted => {}
                Err(error) => {
                    return Err(TransportError::io(format!("cannot read from {}", self.interface), error));
                }
            }
            if deadline.is_some_and(|d| Instant::now() >= d) {
                return Ok(None);
            }
        }
    }
}

impl fmt::Debug for SocketCan {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("SocketCan").field("interface", &self.interface).field("fd", &self.socket.as_raw_fd()).finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_convert_to_the_socketcan_crate_and_back() {
        for frame in [
            CanFrame::standard(0x601, &[0x40, 0x41, 0x60, 0, 0, 0, 0, 0]).unwrap(),
            CanFrame::standard(0x080, &[]).unwrap(),
            CanFrame::standard(0x7FF, &[0xFF; 8]).unwrap(),
            CanFrame::extended(0x1ABC_DEF0, &[1, 2, 3]).unwrap(),
            CanFrame::extended(0x10, &[]).unwrap(),
            CanFrame::remote(0x705, false, 1).unwrap(),
            CanFrame::remote(0x1234_5678, true, 8).unwrap(),
        ] {
            let theirs = to_socketcan(&frame);
            assert_eq!(theirs.is_extended(), frame.is_extended());
            assert_eq!(theirs.raw_id(), frame.id());
            assert_eq!(from_socketcan(&theirs), Ok(frame));
        }
    }

    #[test]
    fn error_frames_are_refused() {
        let error = socketcan::CanErrorFrame::new_error(0x004, &[0; 8]).unwrap();
        assert!(from_socketcan(&socketcan::CanFrame::Error(error)).is_err());
    }

    /// The kernel's error frames (drivers/net/can/dev: `can_change_state`, `can_bus_off`,
    /// `can_restart`) in the `socketcan` crate's type, as a socket reads them.
    #[test]
    fn error_frames_from_the_kernel_are_controller_states() {
        let error = |class: u32, data: &[u8]| {
            socketcan::CanFrame::Error(socketcan::CanErrorFrame::new_error(class, data).unwrap())
        };
        let table = [
            // CAN_ERR_CRTL | CAN_ERR_CNT, data[1] = CAN_ERR_CRTL_{RX,TX}_WARNING, counters 6..7.
            (error(0x204, &[0, 0x0C, 0, 0, 0, 0, 96, 0]), Some(ControllerState::ErrorWarning)),
            (error(0x204, &[0, 0x30, 0, 0, 0, 0, 128, 3]), Some(ControllerState::ErrorPassive)),
            (error(0x004, &[0, 0x20]), Some(ControllerState::ErrorPassive)),
            (error(0x204, &[0, 0x40, 0, 0, 0, 0, 0, 0]), Some(ControllerState::ErrorActive)),
            (error(0x040, &[]), Some(ControllerState::BusOff)),
            (error(0x240, &[0, 0, 0, 0, 0, 0, 255, 0]), Some(ControllerState::BusOff)),
            (error(0x100, &[]), Some(ControllerState::Restarted)),
            // A bus error with a protocol violation (stuff error in the data field), a lost
            // arbitration, an rx overflow: no change of state.
            (error(0x088, &[0, 0, 0x04, 0x0A]), None),
            (error(0x002, &[5]), None),
            (error(0x004, &[0, 0x01]), None),
            // Data and remote frames are not error frames.
            (to_socketcan(&CanFrame::standard(0x080, &[]).unwrap()), None),
            (to_socketcan(&CanFrame::remote(0x705, false, 1).unwrap()), None),
        ];
        for (frame, want) in table {
            assert_eq!(controller_state(&frame), want, "{frame:?}");
            // The error flag is on in what the socket reads; the frame is never a data frame.
            if want.is_some() {
                assert_eq!(frame.id_word() & 0x2000_0000, 0x2000_0000, "{frame:?}");
                assert!(from_socketcan(&frame).is_err());
            }
        }
    }

    #[test]
    fn opening_a_missing_interface_names_it() {
        let err = SocketCan::open("nosuchcan7").unwrap_err().to_string();
        assert!(err.contains("nosuchcan7"), "{err}");
        let err = SocketCan::open("bad\0name").unwrap_err().to_string();
        assert!(err.contains("bad"), "{err}");
    }
}
