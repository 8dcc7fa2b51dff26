//! SocketCAN: a raw CAN socket on a Linux network interface (`can0`, `vcan0`), for running a
//! simulated device against real CAN hardware or a virtual CAN interface.
//!
//! Enabled by the `socketcan` cargo feature, Linux only. Classic CAN only: CAN FD frames are not
//! requested from the kernel, and error frames are not subscribed to.
//!
//! ```no_run
//! use drive::transport::{CanFrame, Endpoint, socketcan::SocketCan};
//! let mut bus = SocketCan::open("vcan0").unwrap();
//! bus.send(CanFrame::standard(0x080, &[]).unwrap()).unwrap();
//! ```

use std::ffi::CString;
use std::fmt;
use std::io;
use std::mem;
use std::os::fd::{AsRawFd, FromRawFd, OwnedFd};
use std::time::{Duration, Instant};

use super::{CanFrame, Endpoint, FrameError, TransportError};

/// An [`Endpoint`] on a Linux CAN interface.
///
/// Like every endpoint it does not receive its own frames (the kernel's default for raw
/// sockets, `CAN_RAW_RECV_OWN_MSGS` off); other sockets on the same interface do.
pub struct SocketCan {
    fd: OwnedFd,
    interface: String,
}

impl SocketCan {
    /// Opens a raw CAN socket bound to `interface`.
    pub fn open(interface: &str) -> Result<Self, TransportError> {
        let name = CString::new(interface)
            .map_err(|_| TransportError::Unavailable(format!("bad CAN interface name {interface:?}")))?;
        // SAFETY: `name` is a valid NUL-terminated string that outlives the call.
        let index = unsafe { libc::if_nametoindex(name.as_ptr()) };
        if index == 0 {
            return Err(TransportError::io(
                format!("no network interface named {interface}"),
                io::Error::last_os_error(),
            ));
        }
        // SAFETY: plain system call with constant arguments.
        let raw = unsafe { libc::socket(libc::AF_CAN, libc::SOCK_RAW | libc::SOCK_CLOEXEC, libc::CAN_RAW) };
        if raw < 0 {
            return Err(TransportError::io(
                "cannot create a CAN socket (is the can_raw module loaded?)",
                io::Error::last_os_error(),
            ));
        }
        // SAFETY: `raw` is a descriptor we just opened and nobody else owns.
        let fd = unsafe { OwnedFd::from_raw_fd(raw) };
        // SAFETY: sockaddr_can is plain old data; all-zero is a valid value.
        let mut addr: libc::sockaddr_can = unsafe { mem::zeroed() };
        addr.can_family = libc::AF_CAN as libc::sa_family_t;
        addr.can_ifindex = libc::c_int::try_from(index)
            .map_err(|_| TransportError::Unavailable(format!("interface index of {interface} out of range")))?;
        // SAFETY: `addr` is a valid sockaddr_can and the length passed is its size.
        let bound = unsafe {
            libc::bind(
                fd.as_raw_fd(),
                (&raw const addr).cast::<libc::sockaddr>(),
                mem::size_of::<libc::sockaddr_can>() as libc::socklen_t,
            )
        };
        if bound < 0 {
            return Err(TransportError::io(format!("cannot bind to {interface}"), io::Error::last_os_error()));
        }
        Ok(Self { fd, interface: interface.to_owned() })
    }

    /// The interface name.
    pub fn interface(&self) -> &str {
        &self.interface
    }

    /// Waits until the socket is readable or `timeout` passed; true when readable.
    fn wait_readable(&self, timeout: Duration) -> Result<bool, TransportError> {
        let mut pollfd = libc::pollfd { fd: self.fd.as_raw_fd(), events: libc::POLLIN, revents: 0 };
        // Round up so a short wait does not become a busy poll of 0 ms.
        let millis = libc::c_int::try_from(timeout.as_micros().div_ceil(1000)).unwrap_or(libc::c_int::MAX);
        // SAFETY: `pollfd` is valid for the duration of the call and we pass a count of 1.
        let ready = unsafe { libc::poll(&raw mut pollfd, 1, millis) };
        match ready {
            n if n > 0 => Ok(true),
            0 => Ok(false),
            _ => {
                let error = io::Error::last_os_error();
                if error.kind() == io::ErrorKind::Interrupted {
                    Ok(false)
                } else {
                    Err(TransportError::io(format!("cannot wait on {}", self.interface), error))
                }
            }
        }
    }

    /// Reads one frame without blocking (the socket was reported readable).
    fn read_frame(&self) -> Result<Option<libc::can_frame>, TransportError> {
        // SAFETY: can_frame is plain old data; all-zero is a valid value.
        let mut raw: libc::can_frame = unsafe { mem::zeroed() };
        // SAFETY: we pass a buffer of exactly size_of::<can_frame>() bytes that we own.
        let n = unsafe {
            libc::recv(
                self.fd.as_raw_fd(),
                (&raw mut raw).cast::<libc::c_void>(),
                mem::size_of::<libc::can_frame>(),
                libc::MSG_DONTWAIT,
            )
        };
        if n < 0 {
            let error = io::Error::last_os_error();
            return match error.kind() {
                io::ErrorKind::WouldBlock | io::ErrorKind::Interrupted => Ok(None),
                _ => Err(TransportError::io(format!("cannot read from {}", self.interface), error)),
            };
        }
        // Anything but a whole classic frame (cannot happen without CAN_RAW_FD_FRAMES) is skipped.
        Ok((n as usize == mem::size_of::<libc::can_frame>()).then_some(raw))
    }
}

/// The kernel's frame layout for `frame`.
pub fn to_raw(frame: &CanFrame) -> libc::can_frame {
    // SAFETY: can_frame is plain old data; all-zero is a valid value.
    let mut raw: libc::can_frame = unsafe { mem::zeroed() };
    raw.can_id = frame.id()
        | if frame.is_extended() { libc::CAN_EFF_FLAG } else { 0 }
        | if frame.is_remote() { libc::CAN_RTR_FLAG } else { 0 };
    raw.can_dlc = frame.dlc();
    raw.data = frame.raw_data();
    raw
}

/// A frame from the kernel's layout; error frames (`CAN_ERR_FLAG`) are refused.
pub fn from_raw(raw: &libc::can_frame) -> Result<CanFrame, FrameError> {
    let extended = raw.can_id & libc::CAN_EFF_FLAG != 0;
    let rtr = raw.can_id & libc::CAN_RTR_FLAG != 0;
    if raw.can_id & libc::CAN_ERR_FLAG != 0 {
        return Err(FrameError::Notation("an error frame is not a data or remote frame"));
    }
    let id = raw.can_id & if extended { libc::CAN_EFF_MASK } else { libc::CAN_SFF_MASK };
    CanFrame::from_parts(id, extended, rtr, raw.can_dlc, raw.data)
}

impl Endpoint for SocketCan {
    fn send(&mut self, frame: CanFrame) -> Result<(), TransportError> {
        let raw = to_raw(&frame);
        // The interface's transmit queue can be momentarily full (ENOBUFS); retry for a while
        // as a CAN controller waits for bus access, then report it.
        let deadline = Instant::now() + Duration::from_millis(100);
        loop {
            // SAFETY: we pass the address and exact size of a can_frame we own.
            let n = unsafe {
                libc::send(
                    self.fd.as_raw_fd(),
                    (&raw const raw).cast::<libc::c_void>(),
                    mem::size_of::<libc::can_frame>(),
                    0,
                )
            };
            if n >= 0 {
                return Ok(());
            }
            let error = io::Error::last_os_error();
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
            if let Some(raw) = self.read_frame()? {
                match from_raw(&raw) {
                    Ok(frame) => return Ok(Some(frame)),
                    // Not a frame an endpoint reports (an error frame): read on.
                    Err(_) => continue,
                }
            }
            let remaining = deadline.map_or(Duration::MAX, |d| d.saturating_duration_since(Instant::now()));
            if remaining.is_zero() {
                return Ok(None);
            }
            // Readable or timed out: either way the next round reads without blocking and
            // then finds the deadline passed.
            self.wait_readable(remaining)?;
        }
    }
}

impl fmt::Debug for SocketCan {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("SocketCan").field("interface", &self.interface).field("fd", &self.fd.as_raw_fd()).finish()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kernel_layout_round_trips() {
        for frame in [
            CanFrame::standard(0x601, &[0x40, 0x41, 0x60, 0, 0, 0, 0, 0]).unwrap(),
            CanFrame::standard(0x080, &[]).unwrap(),
            CanFrame::extended(0x1ABC_DEF0, &[1, 2, 3]).unwrap(),
            CanFrame::remote(0x705, false, 1).unwrap(),
            CanFrame::remote(0x1234_5678, true, 8).unwrap(),
        ] {
            let raw = to_raw(&frame);
            assert_eq!(from_raw(&raw), Ok(frame));
        }
        let raw = to_raw(&CanFrame::extended(0x10, &[]).unwrap());
        assert_eq!(raw.can_id, 0x10 | libc::CAN_EFF_FLAG);
    }

    #[test]
    fn error_frames_and_bad_lengths_are_refused() {
        let mut raw = to_raw(&CanFrame::standard(0x10, &[]).unwrap());
        raw.can_id |= libc::CAN_ERR_FLAG;
        assert!(from_raw(&raw).is_err());
        let mut raw = to_raw(&CanFrame::standard(0x10, &[]).unwrap());
        raw.can_dlc = 9;
        assert_eq!(from_raw(&raw), Err(FrameError::TooLong(9)));
    }

    #[test]
    fn opening_a_missing_interface_names_it() {
        let err = SocketCan::open("nosuchcan7").unwrap_err().to_string();
        assert!(err.contains("nosuchcan7"), "{err}");
        let err = SocketCan::open("bad\0name").unwrap_err().to_string();
        assert!(err.contains("bad"), "{err}");
    }
}
