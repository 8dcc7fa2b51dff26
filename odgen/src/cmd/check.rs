//! `odgen check`: read and validate files, print every diagnostic and a summary.

use std::path::PathBuf;
use std::process::ExitCode;

use eds::{Diagnostic, Severity};

use super::{EXIT_FAILURE, EXIT_TROUBLE};

/// How diagnostics are printed.
#[derive(clap::ValueEnum, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Format {
    /// rustc-style text with the offending line quoted.
    #[default]
    Human,
    /// One JSON document: `{"files": [{"file", "diagnostics"}], "errors", "warnings", "notes"}`.
    Json,
}

/// `odgen check [--strict] [--format human|json] FILE...`
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Treat every CiA 306 deviation as an error (default: lenient, deviations are warnings).
    #[arg(long)]
    pub strict: bool,
    /// Output format.
    #[arg(long, value_enum, default_value_t = Format::Human)]
    pub format: Format,
    /// Threads reading files at once (default: one per core); the output is in the order of
    /// the files whatever the number.
    #[arg(long, short = 'j')]
    pub jobs: Option<usize>,
    /// EDS or DCF files.
    #[arg(required = true)]
    pub files: Vec<PathBuf>,
}

/// Runs the subcommand. Exit code 0 when no file has an error, 1 when one has, 2 when a file
/// could not be read at all.
pub fn run(args: Args) -> ExitCode {
    let options = if args.strict { eds::Options::strict() } else { eds::Options::lenient() };
    let mut all: Vec<Diagnostic> = Vec::new();
    let mut json_files = Vec::new();
    let mut unreadable = 0usize;
    let read = super::par_map(&args.files, super::jobs(args.jobs), |path| eds::read_file(path, &options));
    for (path, parsed) in args.files.iter().zip(read) {
        let parsed = match parsed {
            Ok(p) => p,
            Err(e) => {
                eprintln!("error: cannot read {}: {e}", path.display());
                unreadable += 1;
                continue;
            }
        };
        match args.format {
            Format::Human => {
                for d in &parsed.diagnostics {
                    super::outln!("{}", eds::diag::render(d, &parsed.document.source));
                }
            }
            Format::Json => {
                let diagnostics: serde_json::Value =
                    serde_json::from_str(&eds::diag::to_json(&parsed.diagnostics)).unwrap_or_default();
                json_files.push(serde_json::json!({ "file": path.display().to_string(), "diagnostics": diagnostics }));
            }
        }
        all.extend(parsed.diagnostics);
    }
    let count = |s: Severity| all.iter().filter(|d| d.severity == s).count();
    let errors = count(Severity::Error);
    match args.format {
        Format::Human => {
            let files = args.files.len();
            let mut line =
                format!("checked {files} file{}: {}", if files == 1 { "" } else { "s" }, eds::diag::summary(&all));
            if unreadable > 0 {
                line.push_str(&format!(", {unreadable} unreadable"));
            }
            super::outln!("{line}");
        }
        Format::Json => {
            let doc = serde_json::json!({
                "files": json_files,
                "errors": errors,
                "warnings": count(Severity::Warning),
                "notes": count(Severity::Note),
                "unreadable": unreadable,
            });
            super::outln!("{}", serde_json::to_string_pretty(&doc).unwrap_or_default());
        }
    }
    if unreadable > 0 {
        ExitCode::from(EXIT_TROUBLE)
    } else if errors > 0 {
        ExitCode::from(EXIT_FAILURE)
    } else {
        ExitCode::SUCCESS
    }
}
