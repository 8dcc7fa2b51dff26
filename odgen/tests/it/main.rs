//! The integration tests of `odgen`, one module per former test file, linked into one
//! binary: `cargo test -p odgen --test it` runs them all, `... --test it -- MODULE::` one module.

mod build_once;
mod cli;
mod common;
mod diff;
mod r#gen;
mod hostile;
mod memory;
mod mutation;
mod network;
mod network_python;
mod output;
