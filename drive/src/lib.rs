//! Simulated CANopen drives; the buses they are reached through are the `od-bus` crate's.
#![deny(missing_docs)]

pub mod drives;
pub mod motion;
pub mod node;
pub mod slcan;
pub mod storage;
pub mod trace;
