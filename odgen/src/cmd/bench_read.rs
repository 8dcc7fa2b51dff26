//! `odgen bench-read` (hidden): read+validate throughput, for `scripts/bench-read.sh`.
//!
//! All files are loaded into memory first, then parsed (decode, lex, lower, validate) `N` times
//! in a row; only the parsing is timed. Prints one JSON line:
//! `{"files":61,"bytes":1500000,"iterations":20,"seconds":0.8,"mb_per_s":37.5,"ms_per_pass":40,
//! "cpu_seconds":0.7,"cpu_ms_per_pass":35}` (the CPU figures are `null` where Linux's
//! `/proc/thread-self/schedstat` is missing).

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use super::EXIT_TROUBLE;

/// CPU time this thread has run, from Linux's `/proc/thread-self/schedstat` (nanoseconds on the
/// CPU come first). On a shared machine CPU time is steadier than wall time. `None` elsewhere.
fn thread_cpu_seconds() -> Option<f64> {
    let text = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    let ns: f64 = text.split_whitespace().next()?.parse().ok()?;
    Some(ns / 1e9)
}

/// `odgen bench-read [--iterations N] [--strict] PATH...` (files, or directories whose
/// `*.eds`/`*.dcf` files are read).
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Passes over all files.
    #[arg(long, default_value_t = 20)]
    pub iterations: u32,
    /// Strict validation.
    #[arg(long)]
    pub strict: bool,
    /// Files or directories.
    #[arg(required = true)]
    pub paths: Vec<PathBuf>,
}

/// Runs the subcommand.
pub fn run(args: Args) -> ExitCode {
    let mut files: Vec<(String, Vec<u8>)> = Vec::new();
    for path in &args.paths {
        let mut paths = Vec::new();
        if path.is_dir() {
            match std::fs::read_dir(path) {
                Ok(rd) => {
                    for e in rd.flatten() {
                        let p = e.path();
                        let ext = p.extension().and_then(|e| e.to_str()).map(|e| e.to_ascii_lowercase());
                        if matches!(ext.as_deref(), Some("eds" | "dcf")) {
                            paths.push(p);
                        }
                    }
                }
                Err(e) => {
                    eprintln!("error: cannot list {}: {e}", path.display());
                    return ExitCode::from(EXIT_TROUBLE);
                }
            }
            paths.sort();
        } else {
            paths.push(path.clone());
        }
        for p in paths {
            match std::fs::read(&p) {
                Ok(b) => files.push((p.display().to_string(), b)),
                Err(e) => {
                    eprintln!("error: cannot read {}: {e}", p.display());
                    return ExitCode::from(EXIT_TROUBLE);
                }
            }
        }
    }
    let options = if args.strict { eds::Options::strict() } else { eds::Options::lenient() };
    let bytes: usize = files.iter().map(|(_, b)| b.len()).sum();
    let iterations = args.iterations.max(1);
    let mut objects = 0usize;
    let cpu_start = thread_cpu_seconds();
    let start = Instant::now();
    for _ in 0..iterations {
        for (name, b) in &files {
            let parsed = eds::parse(name, b, &options);
            objects += std::hint::black_box(parsed.model.objects.len());
        }
    }
    let seconds = start.elapsed().as_secs_f64();
    let cpu_seconds = match (cpu_start, thread_cpu_seconds()) {
        (Some(a), Some(b)) => Some(b - a),
        _ => None,
    };
    let mb = (bytes as f64 * iterations as f64) / 1e6;
    super::outln!(
        "{}",
        serde_json::json!({
            "files": files.len(),
            "bytes": bytes,
            "objects_per_pass": objects / iterations as usize,
            "iterations": iterations,
            "seconds": seconds,
            "mb_per_s": if seconds > 0.0 { mb / seconds } else { 0.0 },
            "ms_per_pass": seconds * 1e3 / iterations as f64,
            "cpu_seconds": cpu_seconds,
            "cpu_ms_per_pass": cpu_seconds.map(|c| c * 1e3 / iterations as f64),
        })
    );
    ExitCode::SUCCESS
}
