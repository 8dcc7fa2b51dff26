#![doc = include_str!("../README.md")]
//! # Services
//!
//! A [`Device`] wraps one [`ObjectDictionary`](od::ObjectDictionary) (generated from an EDS by
//! `od-codegen`, or written by hand) and implements the CiA 301 slave services on top of it:
//!
//! | service | objects | module |
//! |---|---|---|
//! | NMT slave, boot-up | — | [`nmt`] |
//! | SDO server: expedited, segmented, block (CRC) | 1200h | [`sdo`] |
//! | RPDOs / TPDOs, remapping over SDO | 1400h.., 1600h.., 1800h.., 1A00h.. | [`pdo`] |
//! | SYNC consumer/producer with counter | 1005h, 1006h, 1019h | [`Device`] |
//! | EMCY producer, error register, history | 1001h, 1003h, 1014h, 1015h | [`emcy`] |
//! | heartbeat producer/consumer, node guarding | 1016h, 1017h, 100Ch, 100Dh | [`Device`] |
//! | store / restore parameters | 1010h, 1011h | [`storage`] |
//! | CiA 402 drive state machine | 6040h, 6041h, 605Ah, 6060h, 6061h | [`cia402`] |
//!
//! Time is an argument ([`Micros`]). The application plugs in through [`App`] (a veto on
//! writes and a stream of [`Event`]s) and [`Storage`] (persisting the records that 1010h
//! saves).
//!
//! The other side of the bus is in [`master`]: the client services (SDO client, NMT master,
//! heartbeat consumer and node guarding, EMCY consumer, SYNC producer, PDO packing) as sans-IO
//! state machines on the same frame, time and abort-code types.
#![no_std]
#![deny(missing_docs)]

#[doc(hidden)]
#[path = "private_v3.rs"]
pub mod __private_v3; // support for generated code: not public API (see the module docs)
#[cfg(feature = "embedded-can")]
pub mod can;
pub mod cia402;
pub mod crc;
mod device;
pub mod emcy;
pub mod frame;
pub mod lss;
pub mod master;
pub mod nmt;
pub mod od;
pub mod pdo;
mod remapping;
pub mod sdo;
mod sdo_block;
pub mod storage;

pub use device::{App, Device, Event, MAX_HEARTBEAT_CONSUMERS, ResetKind, WriteSource};
pub use frame::{Frame, Micros, NodeId};
pub use nmt::{NmtCommand, NmtState};
pub use storage::{NoStorage, Storage};
