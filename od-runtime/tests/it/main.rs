//! The integration tests of `od-runtime`, one module per former test file, linked into one
//! binary: `cargo test -p od-runtime --test it` runs them all, `... --test it -- MODULE::` one module.

#[cfg(feature = "embedded-can")]
mod can;
#[cfg(feature = "cia402")]
mod cia402;
#[cfg(not(feature = "cia402"))]
mod cia402_off;
mod common;
mod handles;
#[cfg(feature = "lss")]
mod lss;
#[cfg(feature = "lss")]
mod lss_master;
mod master;
mod nmt;
mod pdo;
mod props;
mod sdo;
mod services;
mod store;
