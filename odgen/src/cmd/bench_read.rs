//! `odgen bench-read` (hidden): read+validate throughput, for `scripts/bench-read.sh`.
//!
//! All files are loaded into memory first, then parsed (decode, lex, lower, validate) `N` times
//! in a row; only the parsing is timed. With `--jobs J` (default 1) each pass is spread over `J`
//! threads as `odgen check` spreads its files. Prints one JSON line:
//! `{"files":61,"bytes":1500000,"jobs":1,"iterations":20,"seconds":0.8,"mb_per_s":37.5,
//! "ms_per_pass":40,"cpu_seconds":0.7,"cpu_ms_per_pass":35}`: `seconds` and `ms_per_pass` are
//! wall time, the CPU figures are summed over the threads (`null` where Linux's
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
    /// Threads per pass (0: one per core).
    #[arg(long, default_value_t = 1)]
    pub jobs: usize,
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
    // Folders as `odgen check` takes them (their `.eds`/`.dcf` files and their subfolders').
    let (paths, found) = super::expand_folders(&args.paths);
    if let Some((path, super::Found::Unlisted(e))) =
        paths.iter().zip(&found).find(|(_, f)| matches!(f, super::Found::Unlisted(_)))
    {
        eprintln!("error: cannot list {}: {e}", path.display());
        return ExitCode::from(EXIT_TROUBLE);
    }
    for p in paths {
        // (Read as the reader reads files: FIFOs and devices refused, not waited on.)
        match eds::read_bytes(&p) {
            Ok(b) => files.push((p.display().to_string(), b)),
            Err(e) => {
                eprintln!("error: cannot read {}: {e}", p.display());
                return ExitCode::from(EXIT_TROUBLE);
            }
        }
    }
    let options = if args.strict { eds::Options::strict() } else { eds::Options::lenient() };
    let bytes: usize = files.iter().map(|(_, b)| b.len()).sum();
    let iterations = args.iterations.max(1);
    let jobs = super::jobs(if args.jobs == 0 { None } else { Some(args.jobs) }).min(files.len().max(1));
    // The files are dealt to the threads once, largest first to the least loaded, and each
    // thread makes every pass over its share: the threads run side by side for the whole
    // measurement, and each measures its own CPU time once.
    let mut order: Vec<usize> = (0..files.len()).collect();
    order.sort_by_key(|&i| std::cmp::Reverse(files[i].1.len()));
    let mut shares: Vec<(usize, Vec<usize>)> = vec![(0, Vec::new()); jobs];
    for i in order {
        if let Some(least) = shares.iter_mut().min_by_key(|(load, _)| *load) {
            least.0 += files[i].1.len();
            least.1.push(i);
        }
    }
    let work = |share: &[usize]| {
        let before = thread_cpu_seconds();
        let mut objects = 0usize;
        for _ in 0..iterations {
            for &i in share {
                let (name, b) = &files[i];
                objects += std::hint::black_box(eds::parse(name, b, &options).model.objects.len());
            }
        }
        (objects, before.zip(thread_cpu_seconds()).map(|(a, b)| b - a))
    };
    let start = Instant::now();
    let runs: Vec<(usize, Option<f64>)> = if jobs == 1 {
        vec![work(&shares[0].1)]
    } else {
        std::thread::scope(|scope| {
            let workers: Vec<_> = shares.iter().map(|(_, share)| scope.spawn(|| work(share))).collect();
            workers.into_iter().map(|w| w.join().unwrap_or_else(|e| std::panic::resume_unwind(e))).collect()
        })
    };
    let objects: usize = runs.iter().map(|(n, _)| n).sum();
    let cpu_seconds = runs.iter().try_fold(0.0, |sum, (_, cpu)| cpu.map(|c| sum + c));
    let seconds = start.elapsed().as_secs_f64();
    let mb = (bytes as f64 * iterations as f64) / 1e6;
    super::outln!(
        "{}",
        serde_json::json!({
            "files": files.len(),
            "bytes": bytes,
            "jobs": jobs,
            // (The standard one: `odgen` sets no global allocator.)
            "allocator": "system",
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
