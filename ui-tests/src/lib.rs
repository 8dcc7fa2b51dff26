//! The workspace's compile tests live in `tests/ui.rs`; this library is empty.
#![no_std]
