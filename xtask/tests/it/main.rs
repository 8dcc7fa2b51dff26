//! The integration tests of `xtask`, one module per former test file, linked into one
//! binary: `cargo test -p xtask --test it` runs them all, `... --test it -- MODULE::` one module.

mod gen_reports;
mod generated_fresh;
