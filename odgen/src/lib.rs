//! `odgen` as a library: the parts of the command-line tool that other tools reuse.
//!
//! * [`network`]: DCFs for a whole network from one TOML description (`odgen dcf --network`);
//!   it lives in `od_codegen::network`, where `od-master` boots the same description.
//! * [`diff`]: what changed between two device descriptions (`odgen diff`, and `cargo xtask gen`
//!   to report what a regeneration is about).
//! * [`safe_write`]: writing a file the user named (through symbolic links, keeping mode and
//!   owner, refusing devices and read-only files; `-` for standard output).
#![deny(missing_docs)]

pub mod diff;
pub use od_codegen::network;
pub mod safe_write;
