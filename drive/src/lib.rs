//! Simulated CANopen drives and the buses they are reached through.
#![deny(missing_docs)]

pub mod drives;
pub mod motion;
pub mod node;
pub mod storage;
pub mod trace;
pub mod transport;
