//! The `od-master` program end to end against the simulated drives on a socketcand hub over
//! TCP: its commands, their text and `--json` output, and the exit codes.

mod boot_cli;
mod cli;
