//! od-master against the simulated drives (DRVI, DRCS, AKD) on the in-memory bus in virtual
//! time, against hand-written faulty SDO servers, and over the socketcand hub on TCP.

mod axis;
mod boot;
mod client;
mod errors;
mod events;
mod faults;
mod harness;
mod hub;
mod lss;
mod readme;
mod sdo;
mod slcan;
mod supervisor;
