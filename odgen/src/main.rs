//! `odgen`: check, format, dump, compare and configure CANopen device descriptions (EDS/DCF).
//!
//! Each subcommand lives in its own module under `cmd/` with an `Args` struct (its flags) and a
//! `run` function returning the process exit code, so new subcommands are one file and one enum
//! variant each.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod alloc;
mod cmd;
mod yaml;

/// The allocator of the `odgen` binary: mimalloc (see [`alloc`]).
#[global_allocator]
static GLOBAL: alloc::Mimalloc = alloc::Mimalloc;

/// The name of [`GLOBAL`]'s allocator, as `odgen bench-read` reports it beside its figures.
pub(crate) const ALLOCATOR: &str = "mimalloc";

/// CANopen device descriptions (CiA 306 EDS and DCF files): check, format, dump, compare, configure.
#[derive(Parser, Debug)]
#[command(name = "odgen", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Read and validate files; print every diagnostic and a summary (exit 1 on errors).
    Check(cmd::check::Args),
    /// Rewrite files in the canonical form (`--check`: only report files that are not).
    Fmt(cmd::fmt::Args),
    /// Print the typed model of a file as YAML or JSON.
    Dump(cmd::dump::Args),
    /// Configure an EDS for one node and write the DCF, or every node of a network (`--network`).
    Dcf(cmd::dcf::Args),
    /// Show what changed between two descriptions (exit 0: same, 1: different, 2: error).
    Diff(cmd::diff::Args),
    /// Generate the typed Rust object dictionary of a file, as od_codegen::Builder does.
    Gen(cmd::generate::Args),
    /// Measure read+validate throughput (used by scripts/bench-read.sh).
    #[command(hide = true)]
    BenchRead(cmd::bench_read::Args),
}

fn main() -> ExitCode {
    alloc::tune();
    let cli = Cli::parse();
    match cli.command {
        Command::Check(args) => cmd::check::run(args),
        Command::Fmt(args) => cmd::fmt::run(args),
        Command::Dump(args) => cmd::dump::run(args),
        Command::Dcf(args) => cmd::dcf::run(args),
        Command::Diff(args) => cmd::diff::run(args),
        Command::Gen(args) => cmd::generate::run(args),
        Command::BenchRead(args) => cmd::bench_read::run(args),
    }
}
