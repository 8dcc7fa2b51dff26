//! `odgen dcf`: configure an EDS for one node and write the DCF.
//!
//! `--set 0x6060sub0=1` gives entry 0x6060 sub-index 0 the `ParameterValue` 1. The index is hex
//! (with or without `0x`), the sub-index after `sub` is hex as in EDS section names
//! (`0x1A00sub1A` is sub-index 26); the value is read by the entry's data type exactly as a value
//! in an EDS file is (`0x10`, `$NODEID+0x180`, `1.5`, text, hex bytes).

use std::path::PathBuf;
use std::process::ExitCode;

use eds::model::{Index, SubIndex, Value};
use eds::write::ConfigProblem;

use super::{EXIT_FAILURE, EXIT_TROUBLE};

/// `odgen dcf --node-id N [--baud KBIT] [--set 0x6060sub0=1 ...] EDS [-o OUT.dcf]`, or
/// `odgen dcf --network NET.toml -o DIR` (one DCF per node; see `odgen::network`).
#[derive(clap::Args, Debug)]
pub struct Args {
    /// A network description (TOML): writes one DCF per node into the `-o` directory.
    #[arg(long, value_name = "NET.toml", conflicts_with_all = ["node_id", "baud", "set", "eds"], requires = "output")]
    pub network: Option<PathBuf>,
    /// Node id, 1..=127 (decimal or 0x hex).
    #[arg(long, value_parser = parse_node_id, required_unless_present = "network")]
    pub node_id: Option<u8>,
    /// Bit rate in kbit/s (10, 20, 50, 125, 250, 500, 800 or 1000).
    #[arg(long)]
    pub baud: Option<u16>,
    /// A configured value: `INDEXsubSUB=VALUE`, e.g. `0x6060sub0=1` (repeatable).
    #[arg(long = "set", value_name = "INDEXsubSUB=VALUE")]
    pub set: Vec<String>,
    /// The device description to configure.
    #[arg(required_unless_present = "network")]
    pub eds: Option<PathBuf>,
    /// Where to write the DCF (default, or `-`: standard output), through a symbolic link to its
    /// target, keeping an existing file's mode and owner (devices and read-only files are
    /// refused); with `--network`, the directory for the DCFs (created if missing).
    #[arg(short = 'o', long = "output")]
    pub output: Option<PathBuf>,
}

fn parse_node_id(s: &str) -> Result<u8, String> {
    let v = match s.strip_prefix("0x").or_else(|| s.strip_prefix("0X")) {
        Some(h) => u8::from_str_radix(h, 16),
        None => s.parse::<u8>(),
    }
    .map_err(|_| format!("`{s}` is not a node id"))?;
    if (1..=127).contains(&v) { Ok(v) } else { Err(format!("node id {v} is outside 1..=127")) }
}

/// Splits `0x6060sub0=1` into `(0x6060, 0, "1")`.
pub fn parse_set(s: &str) -> Result<(u16, u8, &str), String> {
    let (key, value) =
        s.split_once('=').ok_or_else(|| format!("`{s}`: expected INDEXsubSUB=VALUE, e.g. 0x6060sub0=1"))?;
    let key = key.trim();
    let lower = key.to_ascii_lowercase();
    let (index, sub) = lower
        .split_once("sub")
        .ok_or_else(|| format!("`{key}`: expected INDEXsubSUB, e.g. 0x6060sub0 (sub-index in hex)"))?;
    let index = index.strip_prefix("0x").unwrap_or(index);
    let sub = sub.strip_prefix("0x").unwrap_or(sub);
    let index = u16::from_str_radix(index, 16).map_err(|_| format!("`{key}`: `{index}` is not a hex index"))?;
    let sub = u8::from_str_radix(sub, 16).map_err(|_| format!("`{key}`: `{sub}` is not a hex sub-index (0..FF)"))?;
    Ok((index, sub, value.trim()))
}

/// Runs the subcommand: exit 0 when the DCF(s) were written, 1 when the configuration has
/// problems (nothing is written), 2 when a file cannot be read or written.
pub fn run(args: Args) -> ExitCode {
    if let Some(network) = &args.network {
        return run_network(network, args.output.as_deref());
    }
    let (Some(eds_path), Some(node_id)) = (&args.eds, args.node_id) else {
        eprintln!("error: give an EDS and --node-id, or --network NET.toml");
        return ExitCode::from(EXIT_TROUBLE);
    };
    let Some(parsed) = super::read_or_report(eds_path, &eds::Options::lenient()) else {
        return ExitCode::from(EXIT_TROUBLE);
    };
    let file = eds_path.display().to_string();
    if parsed.has_errors() {
        for d in parsed.errors() {
            eprintln!("{}", eds::diag::render(d, &parsed.document.source));
        }
        eprintln!("error: {file} has errors; fix them before configuring it");
        return ExitCode::from(EXIT_FAILURE);
    }
    let model = &parsed.model;
    let mut problems: Vec<String> = Vec::new();
    let mut values: Vec<(u16, u8, Value)> = Vec::new();
    for s in &args.set {
        let (index, sub, text) = match parse_set(s) {
            Ok(t) => t,
            Err(e) => {
                problems.push(format!("error: --set {e}"));
                continue;
            }
        };
        let Some(entry) = model.entry(index, sub) else {
            // `configure` reports a missing entry with its context; pass a placeholder.
            values.push((index, sub, Value::int(0)));
            continue;
        };
        match eds::value::parse_value(text, entry.data_type) {
            Ok(p) => match p.value {
                Some(v) => values.push((index, sub, v)),
                None => {
                    problems.push(format!("error: --set {s}: an empty value is not a {} value", entry.data_type.name()))
                }
            },
            Err(e) => {
                problems.push(format!("error: --set {s}: {e} (0x{index:04X} sub {sub} is {})", entry.data_type.name()))
            }
        }
    }
    let configured = match eds::write::configure(model, node_id, args.baud, &values) {
        Ok(m) if problems.is_empty() => Some(m),
        Ok(_) => None,
        Err(e) => {
            problems.extend(e.problems.iter().map(|p| render_problem(p, &file, &parsed.document.source)));
            None
        }
    };
    let Some(configured) = configured else {
        for p in &problems {
            eprintln!("{p}");
        }
        eprintln!("error: no DCF written ({} problem{})", problems.len(), if problems.len() == 1 { "" } else { "s" });
        return ExitCode::from(EXIT_FAILURE);
    };
    let text = eds::write::write_dcf(&configured);
    match &args.output {
        None => super::write_stdout(&text),
        Some(out) if out.as_os_str() == "-" => super::write_stdout(&text),
        Some(out) => {
            if let Err(e) = odgen::safe_write::write(out, text.as_bytes()) {
                eprintln!("error: cannot write {e}");
                return ExitCode::from(EXIT_TROUBLE);
            }
            eprintln!(
                "wrote {} (node {}, {} configured value{})",
                out.display(),
                node_id,
                values.len(),
                if values.len() == 1 { "" } else { "s" }
            );
        }
    }
    ExitCode::SUCCESS
}

/// `--network`: every node's DCF into `out_dir`, or every problem and nothing written.
fn run_network(network: &std::path::Path, out_dir: Option<&std::path::Path>) -> ExitCode {
    let Some(out_dir) = out_dir else {
        eprintln!("error: --network needs -o DIR (the directory for the DCFs)");
        return ExitCode::from(EXIT_TROUBLE);
    };
    let outcome = match odgen::network::build_file(network) {
        Ok(o) => o,
        Err(e) => {
            eprintln!("error: cannot read {}: {e}", network.display());
            return ExitCode::from(EXIT_TROUBLE);
        }
    };
    for d in &outcome.diagnostics {
        eprintln!("{}", odgen::network::render(d));
    }
    if outcome.has_errors() {
        let n = outcome.diagnostics.iter().filter(|d| d.severity == eds::Severity::Error).count();
        eprintln!("error: no DCF written ({n} problem{})", if n == 1 { "" } else { "s" });
        return ExitCode::from(EXIT_FAILURE);
    }
    if out_dir.exists() && !out_dir.is_dir() {
        eprintln!("error: {} is not a directory", out_dir.display());
        return ExitCode::from(EXIT_TROUBLE);
    }
    if let Err(e) = std::fs::create_dir_all(out_dir) {
        eprintln!("error: cannot create {}: {e}", out_dir.display());
        return ExitCode::from(EXIT_TROUBLE);
    }
    for dcf in &outcome.dcfs {
        let path = out_dir.join(&dcf.file_name);
        if let Err(e) = odgen::safe_write::write(&path, dcf.text.as_bytes()) {
            eprintln!("error: cannot write {e}");
            return ExitCode::from(EXIT_TROUBLE);
        }
        eprintln!("wrote {} (node {}, {})", path.display(), dcf.node_id, dcf.device);
    }
    ExitCode::SUCCESS
}

/// Renders a configuration problem like a diagnostic, quoting the entry's section header.
fn render_problem(p: &ConfigProblem, file: &str, source: &eds::source::SourceFile) -> String {
    let mut out = format!("error: {}\n", p.message);
    match p.at.filter(|a| a.line > 0) {
        Some(at) => {
            let gutter = " ".repeat(at.line.to_string().len());
            out.push_str(&format!("{gutter}--> {file}:{}:{}\n", at.line, at.col));
            out.push_str(&format!("{gutter} |\n{} | {}\n", at.line, source.line_text(at.line)));
            if !p.context.is_empty() {
                out.push_str(&format!("{gutter} = note: in {}\n", p.context.join(", ")));
            }
            if let Some(h) = &p.hint {
                out.push_str(&format!("{gutter} = help: {h}\n"));
            }
        }
        None => {
            out.push_str(&format!(" --> {file}\n"));
            if let Some((Index(i), SubIndex(s))) = p.target {
                out.push_str(&format!("  = note: in --set 0x{i:04X}sub{s:X}\n"));
            }
            if let Some(h) = &p.hint {
                out.push_str(&format!("  = help: {h}\n"));
            }
        }
    }
    out
}
