#![doc = include_str!("../README.md")]
//!
//! # Layout
//!
//! | piece | type | module |
//! |---|---|---|
//! | the bus task and its handle: NMT, SYNC, PDOs, events | [`Bus`] | [`bus`] |
//! | one node: SDO reads and writes with timeouts and retries | [`Node`] | [`node`] |
//! | events: boot-up, heartbeat lost/recovered, NMT state, EMCY with texts | [`Event`] | [`event`] |
//! | CiA 402 drive: enable, homing, profile position/velocity, cyclic position | [`Axis`] | [`axis`] |
//! | errors naming the node, the object and the abort code | [`Error`] | [`error`] |
//! | typed entries, PDOs and quantities for generated clients | [`remote::Object`] | [`remote`] |
//! | a network configured at boot (CiA 302-2): identity, configuration, PDOs, start | [`boot::boot`] | [`boot`] |
//! | a network kept running after boot: reboots, lost heartbeats, policies, events | [`supervisor::Supervisor`] | [`supervisor`] |
//! | a blocking facade for scripts, wrapping the async handles | [`blocking::Bus`] | [`blocking`] |
//!
//! The protocol is `od_runtime::master`'s (sans-IO state machines); the buses are `od-bus`'s.
//! This crate is the async shell between them: one task owns the bus and every machine, and
//! handles talk to it through channels.
#![deny(missing_docs)]

pub mod axis;
pub mod blocking;
pub mod boot;
pub mod bus;
pub mod error;
pub mod event;
pub mod lss;
pub mod node;
pub mod profile;
pub mod register;
pub mod remote;
mod sdo_options;
pub mod supervisor;
mod unit_error;

pub use axis::{Axis, AxisConfig, Homing, HomingMethod, Move, UnitAxis};
pub use boot::{BootError, BootOptions, Network, NodeReport};
pub use bus::{Bus, Config, CyclicPdo, Tpdo};
pub use error::{
    AxisError, AxisErrorKind, Error, Impossible, Interruption, Limit, LimitSource, RegisterReading, SdoContext,
    StopReason,
};
pub use event::{EmcyTexts, Event};
pub use node::{Node, SdoOptions, SdoValue};
pub use register::StatusRegister;

/// The protocol core's types that appear in this crate's API.
pub use od_runtime::cia402::State;
pub use od_runtime::master::nmt::Target;
pub use od_runtime::master::{Emergency, Mode, NodeEvent, PdoField, PdoMapping, PdoValue, TransferError, Watch};
pub use od_runtime::od::AbortCode;
pub use od_runtime::{NmtCommand, NmtState, NodeId};
