//! The buses a simulated device is reached through.
//!
//! Everything a device needs from a bus is the [`Endpoint`] trait: put a frame on the bus, wait
//! for the next frame somebody else put there. The implementations:
//!
//! | type | bus | use |
//! |---|---|---|
//! | [`LocalEndpoint`] from [`MemoryBus`] | in memory, no threads needed | unit and integration tests, deterministic simulations |
//! | [`LocalEndpoint`] from [`Hub::attach`] | a channel of a socketcand hub in this process | `drive-sim` devices served to real masters |
//! | [`SocketcandClient`] | a channel of a socketcand server over TCP (our hub or a real socketcand) | a device joining a hub run elsewhere (`--bus tcp://HOST:PORT/CHANNEL`) |
//! | `socketcan::SocketCan` (feature `socketcan`, Linux) | a kernel CAN interface (`can0`, `vcan0`) | real hardware |
//!
//! Like CAN itself, every bus here broadcasts: a frame reaches every other endpoint of the bus,
//! never its sender, in the order it was sent.
//!
//! # Writing a device loop
//!
//! A device owns one `Box<dyn Endpoint>` (or a generic `E: Endpoint`) and alternates between
//! handling received frames and its periodic work. [`BusSpec`] turns a command-line string into
//! an endpoint:
//!
//! ```
//! use std::time::{Duration, Instant};
//! use drive::transport::{CanFrame, Endpoint, MemoryBus, TransportError};
//!
//! /// Answers every NMT "start" (0x000 [01 id]) with a boot-up message: a stand-in for a device.
//! fn run(bus: &mut dyn Endpoint, node: u8, until: Instant) -> Result<(), TransportError> {
//!     while Instant::now() < until {
//!         // Wait at most one tick, so periodic work (heartbeat, motion) keeps its pace.
//!         if let Some(frame) = bus.recv_timeout(Duration::from_millis(1))? {
//!             if frame.id() == 0 && frame.data() == [0x01, node] {
//!                 bus.send(CanFrame::standard(0x700 + u32::from(node), &[0x00]).unwrap())?;
//!             }
//!         }
//!         // ... periodic work here ...
//!     }
//!     Ok(())
//! }
//!
//! let bus = MemoryBus::new();
//! let mut master = bus.endpoint();
//! let mut device = bus.endpoint();
//! master.send(CanFrame::standard(0x000, &[0x01, 5]).unwrap()).unwrap();
//! run(&mut device, 5, Instant::now() + Duration::from_millis(5)).unwrap();
//! assert_eq!(master.try_recv().unwrap().unwrap().id(), 0x705);
//! ```
//!
//! Errors: [`TransportError::Closed`] means the bus is gone for good (the hub stopped, the
//! server closed the connection) and the loop should end; other errors are I/O failures of the
//! underlying socket.

mod bus;
mod client;
mod frame;
mod hub;
mod queue;
#[cfg(all(feature = "socketcan", target_os = "linux"))]
pub mod socketcan;
pub mod socketcand;
mod spec;
pub mod wire;

use std::time::Duration;

pub use bus::{LocalEndpoint, MemoryBus};
pub use client::SocketcandClient;
pub use frame::{CanFrame, FrameError};
pub use hub::{Hub, HubConfig, HubEvent, HubObserver};
pub use spec::{BusSpec, BusSpecError, DEFAULT_CHANNEL};

/// What can go wrong on a bus.
#[derive(Debug, thiserror::Error)]
pub enum TransportError {
    /// The bus is gone for good: the hub stopped, or the server closed the connection.
    #[error("the bus was closed")]
    Closed,
    /// The underlying socket failed.
    #[error("{context}: {source}")]
    Io {
        /// What was being done.
        context: String,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// The server broke the protocol or refused a request (socketcand handshake).
    #[error("protocol error: {0}")]
    Protocol(String),
    /// A frame received from the OS or a peer that is not a valid CAN frame.
    #[error("invalid frame: {0}")]
    Frame(#[from] FrameError),
    /// The requested transport is not compiled in or not available on this platform.
    #[error("{0}")]
    Unavailable(String),
}

impl TransportError {
    pub(crate) fn io(context: impl Into<String>, source: std::io::Error) -> Self {
        Self::Io { context: context.into(), source }
    }
}

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
