//! The integration tests of `generated`, one module per former test file, linked into one
//! binary: `cargo test -p generated --test it` runs them all, `... --test it -- MODULE::` one module.

mod devices;
mod fixture_mini;
mod units;
