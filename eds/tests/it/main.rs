//! The integration tests of `eds`, one module per former test file, linked into one
//! binary: `cargo test -p eds --test it` runs them all, `... --test it -- MODULE::` one module.

mod corpus;
mod corpus_canopen;
mod diagnostics;
mod features;
mod hostile;
mod lossless;
mod python_interop;
mod reader;
mod write_common;
mod write_corpus;
mod write_format;
mod write_roundtrip;
