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
///
/// The model is written as it is serialised: JSON straight into the output stream; YAML by a
/// second thread serialising JSON into a pipe that [`crate::yaml::convert`] reads as it goes.
/// Neither builds the document in memory.
pub fn run(args: Args) -> ExitCode {
    let options = if args.strict { eds::Options::strict() } else { eds::Options::lenient() };
    let Some(parsed) = super::read_or_report(&args.file, &options) else {
        return ExitCode::from(EXIT_TROUBLE);
    };
    let mut out = super::Stream::stdout();
    let written = match args.format {
        Format::Json => serde_json::to_writer_pretty(&mut out, &parsed.model)
            .map_err(|e| format!("cannot serialise the model: {e}"))
            .map(|()| out.push("\n")),
        Format::Yaml => yaml(&parsed.model, &mut out),
    };
    out.finish();
    if let Err(e) = written {
        eprintln!("error: {e}");
        return ExitCode::from(EXIT_TROUBLE);
    }
    let mut errors = 0;
    for d in parsed.errors() {
        eprintln!("{}", eds::diag::render(d, &parsed.document.source));
        errors += 1;
    }
    if errors > 0 { ExitCode::from(EXIT_FAILURE) } else { ExitCode::SUCCESS }
}

/// The model as YAML into `out`, converted from JSON as a second thread serialises it.
fn yaml(model: &eds::Model, out: &mut super::Stream) -> Result<(), String> {
    let (reader, writer) = std::io::pipe().map_err(|e| format!("cannot make a pipe: {e}"))?;
    std::thread::scope(|scope| {
        let serialiser = scope.spawn(move || {
            let mut w = std::io::BufWriter::with_capacity(1 << 16, writer);
            // (A failed write means the converter stopped; it reports why.)
            let _ = serde_json::to_writer(&mut w, model);
            let _ = std::io::Write::flush(&mut w);
        });
        let converted = crate::yaml::convert(std::io::BufReader::with_capacity(1 << 16, reader), out)
            .map_err(|e| format!("cannot convert the model to YAML: {e}"));
        let _ = serialiser.join();
        converted
    })
}
