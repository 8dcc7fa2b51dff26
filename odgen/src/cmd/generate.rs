//! `odgen gen`: the code generator from the command line, for users who check generated code
//! in or build with something other than Cargo. The output is byte for byte what
//! `od_codegen::Builder` writes for the same file and settings.

use std::path::PathBuf;
use std::process::ExitCode;

use od_codegen::Severity;

use super::{EXIT_FAILURE, EXIT_TROUBLE};

/// `odgen gen FILE [--sidecar TOML] [--module NAME] [--strict] [--embed-eds] [--client] [-o OUT.rs]`
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The EDS or DCF file.
    pub file: PathBuf,
    /// The sidecar (units, scaling); default: `<stem>.toml` beside the file, if it exists.
    #[arg(long, value_name = "TOML")]
    pub sidecar: Option<PathBuf>,
    /// Name of the generated module; default: the file's stem in snake_case.
    #[arg(long, value_name = "NAME")]
    pub module: Option<String>,
    /// Every deviation (a default PDO mapping that breaks a rule, a limit outside its type) is
    /// an error instead of a warning.
    #[arg(long)]
    pub strict: bool,
    /// Include the description's text as `pub const EDS: &str`.
    #[arg(long)]
    pub embed_eds: bool,
    /// Also generate the master's view of the device: `pub mod remote` with a typed `Remote`
    /// on `od_master::Node` (the code then needs `od-master` and `std`).
    #[arg(long)]
    pub client: bool,
    /// Write the module to this file (only if its contents change; `-` is standard output)
    /// instead of standard output. The file is written through symbolic links, keeping its
    /// mode and owner; devices and read-only files are refused.
    #[arg(short = 'o', long = "output", value_name = "OUT.rs")]
    pub output: Option<PathBuf>,
}

/// Runs the subcommand: 0 when generated, 1 when the description has errors (nothing is
/// written), 2 when a file cannot be read or written.
pub fn run(args: Args) -> ExitCode {
    let module = match &args.module {
        Some(m) => m.clone(),
        None => {
            let stem = args.file.file_stem().and_then(|s| s.to_str()).unwrap_or("");
            od_codegen::ident::snake(stem).unwrap_or_else(|| "device".to_owned())
        }
    };
    let mut builder = od_codegen::Builder::new()
        .cargo_metadata(false)
        .embed_eds(args.embed_eds)
        .client(args.client)
        .device(module, &args.file);
    if let Some(s) = &args.sidecar {
        builder = builder.sidecar(s);
    }
    if args.strict {
        builder = builder.strict();
    }
    let output = match builder.generate_all().pop() {
        Some(Ok(o)) => o,
        Some(Err(e)) => {
            eprintln!("error: {e}");
            return ExitCode::from(EXIT_TROUBLE);
        }
        None => return ExitCode::from(EXIT_TROUBLE),
    };
    // The diagnostics as `odgen check` prints them, on standard error (the code may be on
    // standard output).
    for d in &output.diagnostics {
        eprintln!("{}", eds::diag::render(d, &output.source));
    }
    eprintln!(
        "generated {} from {}: {}",
        output.file_name,
        args.file.display(),
        eds::diag::summary(&output.diagnostics)
    );
    if output.diagnostics.iter().any(|d| d.severity == Severity::Error) {
        return ExitCode::from(EXIT_FAILURE);
    }
    match &args.output {
        // `-o -` is standard output; a file is written as `fmt` and `dcf -o` write theirs
        // (through symbolic links, mode and owner kept, devices and read-only files refused),
        // and left alone when it already holds this text (no rebuild for a build system that
        // watches it).
        Some(path) => match odgen::safe_write::Destination::from_arg(path) {
            odgen::safe_write::Destination::Stdout => super::write_stdout(&output.text),
            odgen::safe_write::Destination::File(path) => {
                let unchanged = std::fs::metadata(&path).is_ok_and(|m| m.is_file())
                    && std::fs::read(&path).is_ok_and(|old| old == output.text.as_bytes());
                if !unchanged && let Err(e) = odgen::safe_write::write(&path, output.text.as_bytes()) {
                    eprintln!("error: {e}");
                    return ExitCode::from(EXIT_TROUBLE);
                }
            }
        },
        None => super::write_stdout(&output.text),
    }
    ExitCode::SUCCESS
}
