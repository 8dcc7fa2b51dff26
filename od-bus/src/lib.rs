//! CAN buses for the simulated devices and for masters, each opened from one address string.
//!
//! | address | bus | blocking | async (feature `tokio`) |
//! |---|---|---|---|
//! | `mem://NAME` | an in-memory bus of this process, shared by name ([`MemoryBus::named`]) | [`LocalEndpoint`] | `tokio::Bus` on the same bus |
//! | `socketcand://HOST:PORT/CHANNEL` (alias `tcp://`) | a channel of a socketcand server over TCP: a [`Hub`] (ours) or a real socketcand | [`SocketcandClient`] | `tokio::Bus`, reconnecting |
//! | `socketcan://IFACE` (Linux) | a kernel CAN interface (`can0`, `vcan0`): PEAK, Kvaser, candleLight, ... | `socketcan::SocketCan` | `tokio::Bus` |
//! | `slcan://PORT?bitrate=500000` | an slcan serial adapter (CANable, USBtin, Lawicel) on Linux, Windows, macOS | [`slcan::SlcanPort`] | `tokio::Bus`, reopening the port |
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
//! `client`, `hub`; `slcan` (the protocol, sans I/O, and a blocking endpoint); `addr`; then
//! `socketcan` (Linux) and the feature-gated `tokio`.
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

/// The README's example, compiled and run as a doc test.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeDoctests;

mod addr;
mod bus;
mod client;
mod controller;
mod endpoint;
mod error;
mod frame;
mod hub;
mod queue;
mod sink;
pub mod slcan;
#[cfg(target_os = "linux")]
pub mod socketcan;
pub mod socketcand;
mod timestamp;
#[cfg(feature = "tokio")]
pub mod tokio;
pub mod wire;

pub use addr::{BusAddr, DEFAULT_CHANNEL, open};
pub use bus::{LocalEndpoint, MemoryBus};
pub use client::SocketcandClient;
pub use controller::ControllerState;
pub use endpoint::Endpoint;
pub use error::{BusAddrError, TransportError};
pub use frame::{CanFrame, FrameError};
pub use hub::{Hub, HubConfig, HubEvent, HubObserver};
pub use timestamp::Timestamp;
