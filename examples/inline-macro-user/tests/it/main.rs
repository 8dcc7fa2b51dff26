//! The integration tests of `inline-macro-user`, one module per former test file, linked into one
//! binary: `cargo test -p inline-macro-user --test it` runs them all, `... --test it -- MODULE::` one module.

mod bus;
mod eds;
