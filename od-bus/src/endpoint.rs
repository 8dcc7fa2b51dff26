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

    fn lost(&self) -> u64 {
        (**self).lost()
    }
}
