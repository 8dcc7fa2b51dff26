//! od-bus's integration tests, one binary: the in-memory bus, the socketcand protocol, the hub
//! over TCP, bus addresses, and (feature `tokio`) the async buses and their interplay with the
//! blocking ones.

mod addr;
#[cfg(feature = "tokio")]
mod async_memory;
#[cfg(feature = "tokio")]
mod async_socketcand;
mod hub;
mod memory;
mod slcan;
mod socketcan;
mod socketcand;
