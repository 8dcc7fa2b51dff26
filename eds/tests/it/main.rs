//! The integration tests of `eds`, one module per former test file, linked into one
//! binary: `cargo test -p canopen-eds --test it` runs them all, `... --test it -- MODULE::` one module.

// The package is `canopen-eds`; the tests call it `eds`, as the workspace does.
extern crate canopen_eds as eds;

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
