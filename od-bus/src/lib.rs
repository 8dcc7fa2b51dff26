//! CAN buses for the simulated devices and for masters, each opened from one address string.
//!
//! | address | bus | blocking | async (feature `tokio`) |
//! |---|---|---|---|
//! | `mem://NAME` | an in-memory bus of this process, shared by name ([`MemoryBus::named`]) | [`LocalEndpoint`] | `tokio::Bus` on the same bus |
//! | `socketcand://HOST:PORT/CHANNEL` (alias `tcp://`) | a channel of a socketcand server over TCP: a [`Hub`] (ours) or a real socketcand | [`SocketcandClient`] | `tokio::Bus`, reconnecting |
//! | `socketcan://IFACE` (feature `socketcan`, Linux) | a kernel CAN interface (`can0`, `vcan0`) | `socketcan::SocketCan` | `tokio::Bus` |
//!
//! [`open`] (blocking) and `tokio::Bus::open` (async) take the address; [`BusAddr`] is its
//! parsed form. Besides these: [`MemoryBus`] for a private bus of a test, [`Hub`] (a
//! socketcand-compatible TCP hub, what `drive-sim hub` runs) with [`Hub::attach`] for endpoints
//! in the hub's own process, [`socketcand`] (the protocol, sans I/O) and [`wire`] (an emulated
//! bus of a given bit rate). One frame type, [`CanFrame`], classic CAN with standard and
//! extended identifiers, goes everywhere.
//!
//! Everything a blocking device needs from a bus is the [`Endpoint`] trait: put a frame on the
//! bus, wait for the next frame somebody else put there. Like CAN itself, every bus here
//! broadcasts: a frame reaches every other endpoint of the bus, never its sender, in the order
//! it was sent.
//!
//! Layers, each using only those below it: `frame`, `timestamp`, `queue`; `sink` (the members
//! of a channel); `wire`; `bus` (channels, in-process endpoints); `socketcand` (the protocol);
//! `client`, `hub`; `addr`; then the feature-gated `socketcan` and `tokio`.
//!
//! # Writing a device loop
//!
//! A device owns one `Box<dyn Endpoint>` (or a generic `E: Endpoint`) and alternates between
//! handling received frames and its periodic work. [`open`] turns a command-line string into
//! an endpoint:
//!
//! ```
//! use std::time::{Duration, Instant};
//! use od_bus::{CanFrame, Endpoint, MemoryBus, TransportError};
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

#![deny(missing_docs)]

mod addr;
mod bus;
mod client;
mod frame;
mod hub;
mod queue;
mod sink;
#[cfg(all(feature = "socketcan", target_os = "linux"))]
pub mod socketcan;
pub mod socketcand;
mod timestamp;
#[cfg(feature = "tokio")]
pub mod tokio;
pub mod wire;

use std::time::Duration;

pub use addr::{BusAddr, BusAddrError, DEFAULT_CHANNEL, open};
pub use bus::{LocalEndpoint, MemoryBus};
pub use client::SocketcandClient;
pub use frame::{CanFrame, FrameError};
pub use hub::{Hub, HubConfig, HubEvent, HubObserver};
pub use timestamp::Timestamp;

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
    /// The address string is not one of the accepted forms.
    #[error(transparent)]
    Address(#[from] BusAddrError),
    /// The connection is down and being restored (the async socketcand client, which
    /// reconnects): this frame was not sent; sending again once the link is back works.
    #[error("the bus connection is down ({reason}); reconnecting")]
    Down {
        /// Why the link went down.
        reason: String,
    },
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
