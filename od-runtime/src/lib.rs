//! `od-runtime`: a `#![no_std]`, allocation-free CANopen device core that generated object
//! dictionaries plug into.
#![no_std]
#![deny(missing_docs)]

pub mod od;
