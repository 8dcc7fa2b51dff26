//! The integration tests of `devices`, one module per former test file, linked into one
//! binary: `cargo test -p devices --test it` runs them all, `... --test it -- MODULE::` one module.

mod akd;
mod drcs;
mod drvi;
