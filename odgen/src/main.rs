//! `odgen`: check, format, dump, compare and configure CANopen device descriptions (EDS/DCF).
//!
//! Each subcommand lives in its own module under `cmd/` with an `Args` struct (its flags) and a
//! `run` function returning the process exit code, so new subcommands are one file and one enum
//! variant each.

use std::process::ExitCode;

use clap::Parser;

mod alloc;
mod arena;
mod cmd;
mod yaml;

/// The allocator of the `odgen` binary: the arena where it is open, the system's allocator
/// otherwise (see [`alloc`]).
#[global_allocator]
static GLOBAL: alloc::Allocator = alloc::Allocator;

/// The name of [`GLOBAL`]'s allocator, as `odgen bench-read` reports it beside its figures
/// (`bench-read` does not open the arena).
pub(crate) const ALLOCATOR: &str = "system";

/// CANopen device descriptions (CiA 306 EDS and DCF files): check, format, dump, compare, configure.
#[derive(Parser, Debug)]
#[command(name = "odgen", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// The subcommands. Each one's arguments are defined only when it is the one invoked (or its
/// help is asked for): `clap` builds a `Command` for every argument of every subcommand, a few
/// hundred small allocations and a few dozen fresh pages before anything is parsed, where only
/// one subcommand's are needed (a tenth of `odgen --version`'s time went there).
#[derive(Debug)]
enum Command {
    /// `odgen check` (what each subcommand does is said in `subcommands!` below).
    Check(cmd::check::Args),
    /// `odgen fmt`.
    Fmt(cmd::fmt::Args),
    /// `odgen dump`.
    Dump(cmd::dump::Args),
    /// `odgen dcf`.
    Dcf(cmd::dcf::Args),
    /// `odgen diff`.
    Diff(cmd::diff::Args),
    /// `odgen gen`.
    Gen(cmd::generate::Args),
    /// `odgen bench-read` (hidden).
    BenchRead(cmd::bench_read::Args),
}

/// A subcommand's arguments, defined when clap first needs them (`UPDATE`: for
/// `update_from_arg_matches`), with the subcommand's own description kept: `A`'s derive would
/// put its struct's description in its place.
fn deferred<A: clap::Args, const UPDATE: bool>(cmd: clap::Command) -> clap::Command {
    let about = cmd.get_about().cloned();
    let cmd = if UPDATE { A::augment_args_for_update(cmd) } else { A::augment_args(cmd) };
    match about {
        Some(about) => cmd.about(about),
        None => cmd,
    }
    .long_about(None)
}

/// Each subcommand: its name, its `Args`, what `odgen --help` says of it, and whether it is
/// hidden; its arguments are deferred ([`deferred`]).
macro_rules! subcommands {
    ($( $variant:ident, $name:literal, $args:ty, $about:literal, $hide:literal; )*) => {
        impl Command {
            /// `cmd` with every subcommand, each one's arguments deferred ([`deferred`]).
            fn with_subcommands(cmd: clap::Command, update: bool) -> clap::Command {
                cmd$(.subcommand(
                    clap::Command::new($name).about($about).long_about(None).hide($hide).defer(if update {
                        deferred::<$args, true>
                    } else {
                        deferred::<$args, false>
                    }),
                ))*
            }
        }

        impl clap::Subcommand for Command {
            fn augment_subcommands(cmd: clap::Command) -> clap::Command {
                Command::with_subcommands(cmd, false)
            }

            fn augment_subcommands_for_update(cmd: clap::Command) -> clap::Command {
                Command::with_subcommands(cmd, true)
            }

            fn has_subcommand(name: &str) -> bool {
                matches!(name, $($name)|*)
            }
        }

        impl clap::FromArgMatches for Command {
            fn from_arg_matches(matches: &clap::ArgMatches) -> Result<Self, clap::Error> {
                Self::from_arg_matches_mut(&mut matches.clone())
            }

            fn from_arg_matches_mut(matches: &mut clap::ArgMatches) -> Result<Self, clap::Error> {
                match matches.remove_subcommand() {
                    $(Some((name, mut sub)) if name == $name => {
                        Ok(Command::$variant(<$args as clap::FromArgMatches>::from_arg_matches_mut(&mut sub)?))
                    })*
                    Some((name, _)) => Err(clap::Error::raw(
                        clap::error::ErrorKind::InvalidSubcommand,
                        format!("the subcommand '{name}' wasn't recognized"),
                    )),
                    None => Err(clap::Error::raw(
                        clap::error::ErrorKind::MissingSubcommand,
                        "a subcommand is required but one was not provided",
                    )),
                }
            }

            fn update_from_arg_matches(&mut self, matches: &clap::ArgMatches) -> Result<(), clap::Error> {
                self.update_from_arg_matches_mut(&mut matches.clone())
            }

            fn update_from_arg_matches_mut(&mut self, matches: &mut clap::ArgMatches) -> Result<(), clap::Error> {
                *self = Self::from_arg_matches_mut(matches)?;
                Ok(())
            }
        }
    };
}

subcommands! {
    Check, "check", cmd::check::Args,
        "Read and validate files; print every diagnostic and a summary (exit 1 on errors)", false;
    Fmt, "fmt", cmd::fmt::Args,
        "Rewrite files in the canonical form (`--check`: only report files that are not)", false;
    Dump, "dump", cmd::dump::Args, "Print the typed model of a file as YAML or JSON", false;
    Dcf, "dcf", cmd::dcf::Args,
        "Configure an EDS for one node and write the DCF, or every node of a network (`--network`)", false;
    Diff, "diff", cmd::diff::Args,
        "Show what changed between two descriptions (exit 0: same, 1: different, 2: error)", false;
    Gen, "gen", cmd::generate::Args,
        "Generate the typed Rust object dictionary of a file, as od_codegen::Builder does", false;
    BenchRead, "bench-read", cmd::bench_read::Args,
        "Measure read+validate throughput (used by scripts/bench-read.sh)", true;
}

/// `odgen check PATH...` when every argument after `check` is a path (not empty, not starting
/// with `-`),
/// as clap would parse it, without clap: the commonest command line, and the one run over and
/// over by scripts and editors. clap spends about 0.2 ms of a run building its commands and
/// parsing (a twentieth of `odgen check` on the corpus); anything else (an option, `--help`,
/// no path) is clap's, which gives the same `Args` for these (tested).
fn plain_check(mut argv: impl Iterator<Item = std::ffi::OsString>) -> Option<cmd::check::Args> {
    let _program = argv.next()?;
    if argv.next()? != "check" {
        return None;
    }
    let files: Vec<std::path::PathBuf> = argv.map(std::path::PathBuf::from).collect();
    // (clap refuses an empty path, and reads one starting with `-` as an option.)
    if files.is_empty() || files.iter().any(|f| matches!(f.as_os_str().as_encoded_bytes().first(), None | Some(b'-'))) {
        return None;
    }
    Some(cmd::check::Args::files_only(files))
}

/// Ends the process with `code` at once, once a command has written everything: the C
/// runtime's exit handlers and the runtimes' clean-up (the allocator collecting its heaps, each
/// thread-local dropped) only free what the kernel frees with the process, and took about
/// 0.1 ms of `odgen check` on the corpus (400 alternating runs, mean 5.86 -> 5.75 ms).
/// Standard output is written through without a buffer left ([`cmd::write_stdout`] flushes
/// each write), standard error has none; no other thread is running.
fn exit_now(code: u8) -> ! {
    use std::io::Write as _;
    let _ = std::io::stdout().flush();
    let _ = std::io::stderr().flush();
    #[cfg(unix)]
    // SAFETY: `_exit` ends the process; nothing is left to run or to write.
    unsafe {
        libc::_exit(i32::from(code))
    }
    #[cfg(not(unix))]
    std::process::exit(i32::from(code))
}

fn main() -> ExitCode {
    alloc::tune();
    let command = match plain_check(std::env::args_os()) {
        Some(args) => Command::Check(args),
        None => Cli::parse().command,
    };
    match command {
        Command::Check(args) => exit_now(cmd::check::run(args)),
        Command::Fmt(args) => cmd::fmt::run(args),
        Command::Dump(args) => cmd::dump::run(args),
        Command::Dcf(args) => cmd::dcf::run(args),
        Command::Diff(args) => cmd::diff::run(args),
        Command::Gen(args) => cmd::generate::run(args),
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

    /// `odgen check` with paths only gives, without clap, the `Args` clap gives; anything else
    /// is left to clap.
    #[test]
    fn plain_check_lines_parse_as_clap_parses_them() {
        use std::ffi::OsString;
        let os = |args: &[&str]| args.iter().map(OsString::from).collect::<Vec<_>>();
        let mut plain: Vec<Vec<OsString>> = [
            &["odgen", "check", "a.eds"][..],
            &["odgen", "check", "a.eds", "b.dcf", "folder/", "with space.eds", "ünïcode.eds"],
            &["odgen", "check", "help"],
            &["odgen", "check", "check", "--"][..3],
            &["odgen", "check", "a-b.eds", "x=-1"],
        ]
        .iter()
        .map(|a| os(a))
        .collect();
        #[cfg(unix)]
        {
            use std::os::unix::ffi::OsStringExt as _;
            plain.push(vec!["odgen".into(), "check".into(), OsString::from_vec(vec![0x66, 0xFF, 0x2E])]);
        }
        for argv in &plain {
            let fast = plain_check(argv.iter().cloned()).expect("a plain check line");
            let Command::Check(clap) = Cli::try_parse_from(argv).expect("clap parses it").command else {
                panic!("not check: {argv:?}");
            };
            assert_eq!(format!("{fast:?}"), format!("{clap:?}"), "{argv:?}");
        }
        for argv in [
            &["odgen"][..],
            &["odgen", "check"],
            &["odgen", "check", "--notes", "a.eds"],
            &["odgen", "check", "a.eds", "-j1"],
            &["odgen", "check", "a.eds", "--"],
            &["odgen", "check", "-"],
            &["odgen", "check", "a.eds", ""],
            &["odgen", "check", "--help"],
            &["odgen", "dump", "a.eds"],
            &["odgen", "--version"],
            &["odgen", "Check", "a.eds"],
        ] {
            assert!(plain_check(os(argv).into_iter()).is_none(), "{argv:?}");
        }
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
