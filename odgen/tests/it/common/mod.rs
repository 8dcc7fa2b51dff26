//! Helpers shared by odgen's integration tests.

use std::process::Command;

/// `odgen`, to be given its arguments, run with `limit_kib` KiB of address space
/// (`ulimit -v`): an allocation beyond it fails, which aborts the process.
pub fn odgen_under_limit(limit_kib: u64) -> Command {
    let mut c = Command::new("sh");
    c.arg("-c").arg(format!("ulimit -v {limit_kib} && exec \"$0\" \"$@\"")).arg(env!("CARGO_BIN_EXE_odgen"));
    c
}
