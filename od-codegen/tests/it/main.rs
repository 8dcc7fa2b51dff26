//! The integration tests of `od-codegen`, one module per former test file, linked into one
//! binary: `cargo test -p od-codegen --test it` runs them all, `... --test it -- MODULE::` one module.

mod client;
mod common;
mod compile_all;
mod concise;
mod devices;
mod fixtures;
mod in_code;
mod names_corpus;
mod names_prop;
mod policy_corpus;
mod stale_runtime;
mod text_path;
