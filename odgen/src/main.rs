//! `odgen`: check, format, dump, compare and configure CANopen device descriptions (EDS/DCF).
//!
//! Each subcommand lives in its own module under `cmd/` with an `Args` struct (its flags) and a
//! `run` function returning the process exit code, so new subcommands are one file and one enum
//! variant each.

use std::process::ExitCode;

use clap::Parser;

mod cmd;
mod yaml;

/// CANopen device descriptions (CiA 306 EDS and DCF files): check, format, dump, compare, configure.
#[derive(Parser, Debug)]
#[command(name = "odgen", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// The subcommands (each one's description is what `odgen --help` says of it).
#[derive(clap::Subcommand, Debug)]
enum Command {
    #[command(
        about = "Read and validate files; print every diagnostic and a summary (exit 1 on errors)",
        long_about = None
    )]
    Check(cmd::check::Args),
    #[command(
        about = "Rewrite files in the canonical form (`--check`: only report files that are not)",
        long_about = None
    )]
    Fmt(cmd::fmt::Args),
    #[command(about = "Print the typed model of a file as YAML or JSON", long_about = None)]
    Dump(cmd::dump::Args),
    #[command(
        about = "Configure an EDS for one node and write the DCF, or every node of a network (`--network`)",
        long_about = None
    )]
    Dcf(cmd::dcf::Args),
    #[command(
        about = "Show what changed between two descriptions (exit 0: same, 1: different, 2: error)",
        long_about = None
    )]
    Diff(cmd::diff::Args),
    #[command(
        about = "Generate the typed Rust object dictionary of a file, as od_codegen::Builder does",
        long_about = None
    )]
    Gen(cmd::generate::Args),
    #[command(
        about = "List the names the generated code gives each entry, with index, standard name, type, access and unit",
        long_about = None
    )]
    Names(cmd::names::Args),
    #[command(
        about = "Write a starting sidecar (units, dimensions, factor group) from a file's CiA 402 objects",
        long_about = None
    )]
    Sidecar(cmd::sidecar::Args),
    #[command(
        name = "bench-read",
        about = "Measure read+validate throughput (used by scripts/bench-read.sh)",
        long_about = None,
        hide = true
    )]
    BenchRead(cmd::bench_read::Args),
}

fn main() -> ExitCode {
    match Cli::parse().command {
        Command::Check(args) => ExitCode::from(cmd::check::run(args)),
        Command::Fmt(args) => cmd::fmt::run(args),
        Command::Dump(args) => cmd::dump::run(args),
        Command::Dcf(args) => cmd::dcf::run(args),
        Command::Diff(args) => cmd::diff::run(args),
        Command::Gen(args) => cmd::generate::run(args),
        Command::Names(args) => cmd::names::run(args),
        Command::Sidecar(args) => cmd::sidecar::run(args),
        Command::BenchRead(args) => cmd::bench_read::run(args),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::CommandFactory as _;

    /// clap's own checks of the whole command line, every subcommand's arguments included
    /// (building the command for them runs each deferred definition).
    #[test]
    fn the_command_line_is_well_formed() {
        Cli::command().debug_assert();
    }

    /// Each subcommand's name gives its own arguments, and a subcommand's description stays
    /// the same once its arguments are defined.
    #[test]
    fn each_subcommand_parses_to_its_own_arguments() {
        let parse = |args: &[&str]| Cli::try_parse_from(std::iter::once("odgen").chain(args.iter().copied()));
        assert!(matches!(parse(&["check", "--notes", "a.eds"]).unwrap().command, Command::Check(a) if a.notes));
        assert!(matches!(parse(&["fmt", "--check", "a.eds"]).unwrap().command, Command::Fmt(_)));
        assert!(matches!(parse(&["dump", "a.eds"]).unwrap().command, Command::Dump(_)));
        assert!(matches!(parse(&["dcf", "--node-id", "2", "a.eds"]).unwrap().command, Command::Dcf(_)));
        assert!(matches!(parse(&["diff", "a.eds", "b.eds"]).unwrap().command, Command::Diff(_)));
        assert!(matches!(parse(&["gen", "a.eds"]).unwrap().command, Command::Gen(_)));
        assert!(matches!(parse(&["bench-read", "a.eds"]).unwrap().command, Command::BenchRead(_)));
        assert_eq!(parse(&["frob"]).unwrap_err().kind(), clap::error::ErrorKind::InvalidSubcommand);
        assert_eq!(parse(&["check", "--frob", "a.eds"]).unwrap_err().kind(), clap::error::ErrorKind::UnknownArgument);
        let mut cli = Cli::command();
        cli.build();
        for sub in cli.get_subcommands() {
            let about = sub.get_about().map(|a| a.to_string()).unwrap_or_default();
            assert!(
                !about.is_empty() && !about.ends_with('.') && !about.starts_with('`'),
                "{}: {about}",
                sub.get_name()
            );
        }
    }
}
