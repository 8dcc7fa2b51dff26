//! The blocking attachment point to a bus that every transport provides.

use std::time::Duration;

use crate::error::TransportError;
use crate::frame::CanFrame;

/// One attachment point to a CAN bus: what a simulated device (or a test's master) talks
/// through.
///
/// Implementations broadcast like CAN: a sent frame reaches every other endpoint on the bus,
/// not the sender itself. Frames are received in the order they were sent on the bus.
pub trait Endpoint: Send {
    /// Puts a frame on the bus. In-process endpoints never block; socket endpoints block only
    /// as long as the OS send buffer is full.
    fn send(&mut self, frame: CanFrame) -> Result<(), TransportError>;

    /// Waits up to `timeout` for the next frame sent by another endpoint. `Ok(None)` means the
    /// time ran out; `Duration::ZERO` polls without waiting.
    fn recv_timeout(&mut self, timeout: Duration) -> Result<Option<CanFrame>, TransportError>;

    /// Takes the next frame if one is already there, without waiting.
    fn try_recv(&mut self) -> Result<Option<CanFrame>, TransportError> {
        self.recv_timeout(Duration::ZERO)
    }

    /// Puts several frames on the bus, in order. A socket endpoint writes them with one system
    /// call, so a device answering several requests at once wakes its peer once.
    fn send_all(&mut self, frames: &[CanFrame]) -> Result<(), TransportError> {
        frames.iter().try_for_each(|frame| self.send(*frame))
    }

    /// Frames this endpoint has already received and holds, which [`try_recv`] hands out
    /// without asking the OS: a loop can take every request that came in one read before it
    /// answers any. 0 where the transport holds none itself (there may still be frames to
    /// read).
    ///
    /// [`try_recv`]: Endpoint::try_recv
    fn buffered(&self) -> usize {
        0
    }

    /// Frames lost on the way to this endpoint so far: its receive queue overflowed, or the
    /// hub dropped them because this endpoint read more slowly than the bus ran. 0 where the
    /// transport cannot tell.
    fn lost(&self) -> u64 {
        0
    }
}

impl<E: Endpoint + ?Sized> Endpoint for Box<E> {
    fn send(&mut self, frame: CanFrame) -> Result<(), TransportError> {
        (**self).send(frame)
    }

    fn recv_timeout(&mut self, timeout: Duration) -> Result<Option<CanFrame>, TransportError> {
        (**self).recv_timeout(timeout)
    }

    fn try_recv(&mut self) -> Result<Option<CanFrame>, TransportError> {
        (**self).try_recv()
    }

    fn send_all(&mut self, frames: &[CanFrame]) -> Result<(), TransportError> {
        (**self).send_all(frames)
    }

    fn buffered(&self) -> usize {
        (**self).buffered()
    }

    fn lost(&self) -> u64 {
        (**self).lost()
    }
}

impl<E: Endpoint + ?Sized> Endpoint for &mut E {
    fn send(&mut self, frame: CanFrame) -> Result<(), TransportError> {
        (**self).send(frame)
    }

    fn recv_timeout(&mut self, timeout: Duration) -> Result<Option<CanFrame>, TransportError> {
        (**self).recv_timeout(timeout)
    }

    fn try_recv(&mut self) -> Result<Option<CanFrame>, TransportError> {
        (**self).try_recv()
    }

    fn send_all(&mut self, frames: &[CanFrame]) -> Result<(), TransportError> {
        (**self).send_all(frames)
    }

    fn buffered(&self) -> usize {
        (**self).buffered()
    }

    fn lost(&self) -> u64 {
        (**self).lost()
    }
}
