//! `odgen diff OLD NEW`: what changed between two device descriptions (see `odgen::diff`).

use std::path::PathBuf;
use std::process::ExitCode;

use super::{EXIT_FAILURE, EXIT_TROUBLE};

/// Output format.
#[derive(clap::ValueEnum, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Format {
    /// An aligned table and a summary line.
    #[default]
    Table,
    /// One JSON document: `{"old", "new", "identical", "summary", "changes": [...]}`.
    Json,
}

/// `odgen diff [--format table|json] OLD NEW`
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Output format.
    #[arg(long, value_enum, default_value_t = Format::Table)]
    pub format: Format,
    /// The old EDS or DCF.
    pub old: PathBuf,
    /// The new EDS or DCF.
    pub new: PathBuf,
}

/// Runs the subcommand. Exit code 0 when the two files mean the same, 1 when they differ, 2 when
/// either cannot be read or has errors (which are printed).
pub fn run(args: Args) -> ExitCode {
    let mut models = Vec::new();
    for path in [&args.old, &args.new] {
        let Some(parsed) = super::read_or_report(path, &eds::Options::lenient()) else {
            return ExitCode::from(EXIT_TROUBLE);
        };
        if parsed.has_errors() {
            for d in parsed.errors() {
                eprintln!("{}", eds::diag::render(d, &parsed.document.source));
            }
            eprintln!("error: {} has errors; fix them before comparing it", path.display());
            return ExitCode::from(EXIT_TROUBLE);
        }
        models.push(parsed.model);
    }
    let d = odgen::diff::diff(&models[0], &models[1]);
    match args.format {
        Format::Table => super::write_stdout(&odgen::diff::render_table(&d)),
        Format::Json => {
            let body: serde_json::Value = serde_json::from_str(&odgen::diff::render_json(&d)).unwrap_or_default();
            let mut doc = serde_json::json!({
                "old": args.old.display().to_string(),
                "new": args.new.display().to_string(),
            });
            if let (Some(doc), Some(body)) = (doc.as_object_mut(), body.as_object()) {
                doc.extend(body.clone());
            }
            super::outln!("{}", serde_json::to_string_pretty(&doc).unwrap_or_default());
        }
    }
    if d.is_empty() { ExitCode::SUCCESS } else { ExitCode::from(EXIT_FAILURE) }
}
