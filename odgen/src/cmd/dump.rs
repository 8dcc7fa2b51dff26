//! `odgen dump`: print the typed model of a file (the serde form of `eds::Model`).

use std::path::PathBuf;
use std::process::ExitCode;

use super::{EXIT_FAILURE, EXIT_TROUBLE};

/// Output format.
#[derive(clap::ValueEnum, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Format {
    /// YAML (block style, fields in model order).
    #[default]
    Yaml,
    /// Pretty-printed JSON.
    Json,
}

/// `odgen dump [--format yaml|json] [--strict] FILE`
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Output format.
    #[arg(long, value_enum, default_value_t = Format::Yaml)]
    pub format: Format,
    /// Validate strictly (only changes which diagnostics count as errors).
    #[arg(long)]
    pub strict: bool,
    /// The EDS or DCF file.
    pub file: PathBuf,
}

/// Runs the subcommand: the model goes to stdout; errors found while reading go to stderr and
/// make the exit code 1 (the model is still printed, as far as the file allowed).
pub fn run(args: Args) -> ExitCode {
    let options = if args.strict { eds::Options::strict() } else { eds::Options::lenient() };
    let Some(parsed) = super::read_or_report(&args.file, &options) else {
        return ExitCode::from(EXIT_TROUBLE);
    };
    let json = match serde_json::to_string_pretty(&parsed.model) {
        Ok(j) => j,
        Err(e) => {
            eprintln!("error: cannot serialise the model: {e}");
            return ExitCode::from(EXIT_TROUBLE);
        }
    };
    match args.format {
        Format::Json => super::outln!("{json}"),
        Format::Yaml => match crate::yaml::from_json(&json) {
            Ok(y) => super::write_stdout(&y),
            Err(e) => {
                eprintln!("error: cannot convert the model to YAML: {e}");
                return ExitCode::from(EXIT_TROUBLE);
            }
        },
    }
    let mut errors = 0;
    for d in parsed.errors() {
        eprintln!("{}", eds::diag::render(d, &parsed.document.source));
        errors += 1;
    }
    if errors > 0 { ExitCode::from(EXIT_FAILURE) } else { ExitCode::SUCCESS }
}
