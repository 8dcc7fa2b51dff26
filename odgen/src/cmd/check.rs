//! `odgen check`: read and validate files, print their diagnostics and a summary.
//!
//! Each file's part of the output is rendered by the thread that read it (which then drops the
//! file's text and model, so its memory serves the next file), and the parts go out in the
//! order of the files through one buffer ([`super::Stream`]): with one thread, straight into
//! that buffer; with several, into a string per file that the writer takes in order. JSON and SARIF are
//! written directly, not through a value tree per diagnostic.

use std::path::PathBuf;

use eds::{Diagnostic, Severity};

use super::{EXIT_FAILURE, EXIT_TROUBLE, Stream};

/// How diagnostics are printed.
#[derive(clap::ValueEnum, Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Format {
    /// rustc-style text with the offending line quoted.
    #[default]
    Human,
    /// One JSON document: `{"files": [{"file", "diagnostics"}], "errors", "warnings", "notes",
    /// "unreadable", "unreadable_files": [{"file", "reason"}]}`.
    Json,
    /// SARIF 2.1.0 (the format code-scanning services read): one run, one result per diagnostic.
    Sarif,
}

/// The least severe diagnostics printed.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Level {
    /// Errors only.
    Error,
    /// Errors and warnings (the default for human output).
    Warning,
    /// Everything, notes too (the default for JSON and SARIF).
    Note,
}

impl Level {
    /// The least severe diagnostics shown.
    fn least(self) -> Severity {
        match self {
            Level::Error => Severity::Error,
            Level::Warning => Severity::Warning,
            Level::Note => Severity::Note,
        }
    }

    fn shows(self, s: Severity) -> bool {
        s >= self.least()
    }
}

/// `odgen check [--strict] [--format human|json|sarif] [--level L | --notes] FILE...`
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Treat every CiA 306 deviation as an error (default: lenient, deviations are warnings).
    #[arg(long)]
    pub strict: bool,
    /// Output format.
    #[arg(long, value_enum, default_value_t = Format::Human)]
    pub format: Format,
    /// The least severe diagnostics to print (default: `warning` for human output, where notes
    /// are only counted in the summary; `note` for JSON and SARIF, which keep everything).
    #[arg(long, value_enum)]
    pub level: Option<Level>,
    /// Print notes too (the same as `--level note`).
    #[arg(long, conflicts_with = "level")]
    pub notes: bool,
    /// Threads reading files at once (default: one per core); the output is in the order of
    /// the files whatever the number.
    #[arg(long, short = 'j')]
    pub jobs: Option<usize>,
    /// Silences a diagnostic code (`--allow G0104 --allow E0301`): its warnings and notes are
    /// neither printed nor counted; errors still are (as `od_codegen::Builder::allow`).
    #[arg(long = "allow", value_name = "CODE")]
    pub allow: Vec<String>,
    /// Only the reader's diagnostics, not the code generator's (which `odgen check` adds by
    /// default, as a build with `od_codegen::Builder` reports them).
    #[arg(long)]
    pub no_codegen: bool,
    /// EDS or DCF files, or folders: a folder stands for the `.eds` and `.dcf` files in it and
    /// in its subfolders.
    #[arg(required = true)]
    pub files: Vec<PathBuf>,
}

impl Args {
    /// The least severe diagnostics printed: `--level`, or `--notes`, or the format's default.
    fn level(&self) -> Level {
        match (self.level, self.notes, self.format) {
            (Some(l), _, _) => l,
            (None, true, _) => Level::Note,
            (None, false, Format::Human) => Level::Warning,
            (None, false, _) => Level::Note,
        }
    }
}

/// What is kept of a file once it is read: its part of the output, rendered by the thread that
/// read it, and its counts. The file's text, model and diagnostics are dropped there and then,
/// so that the thread's next file reuses their memory, and rendering runs on every thread.
struct Report {
    text: String,
    /// Whether the part has anything in it ([`writes_anything`]).
    writes: bool,
    counts: Counts,
}

/// The largest file one thread's reader is first made for (four times what `eds::Reader::new`
/// makes room for; a larger file makes its own buffers as it is read).
const ROOM_AT_MOST: usize = 4 * eds::Reader::ROOM;

/// Where a report is rendered: a string handed to the writer, or the output itself.
trait Sink {
    /// The buffer to append the next piece (a diagnostic, at most a few KiB) to.
    fn text(&mut self) -> &mut String;
}

impl Sink for String {
    fn text(&mut self) -> &mut String {
        self
    }
}

impl Sink for Stream {
    fn text(&mut self) -> &mut String {
        self.room()
    }
}

/// Counts by severity.
#[derive(Default)]
struct Counts {
    errors: usize,
    warnings: usize,
    notes: usize,
}

impl Counts {
    fn add_counts(&mut self, other: &Counts) {
        self.errors += other.errors;
        self.warnings += other.warnings;
        self.notes += other.notes;
    }

    fn add(&mut self, diagnostics: &[Diagnostic]) {
        for d in diagnostics {
            match d.severity {
                Severity::Error => self.errors += 1,
                Severity::Warning => self.warnings += 1,
                Severity::Note => self.notes += 1,
            }
        }
    }
}

/// Runs the subcommand. Exit code 0 when no file has an error, 1 when one has, 2 when a file
/// could not be read at all. Everything is written when it returns.
pub fn run(args: Args) -> u8 {
    let level = args.level();
    let options = if args.strict { eds::Options::strict() } else { eds::Options::lenient() };
    // Diagnostics below the level are counted, not made (the reader builds no text for them).
    let check = Check {
        options: options.keep_from(level.least()),
        format: args.format,
        level,
        allowed: args.allow.clone(),
        codegen: !args.no_codegen,
        strict: args.strict,
    };
    let (files, found) = super::expand_folders(&args.files);
    // Every file is probed (for its size) once, before any is read: several threads take the
    // largest first, one thread makes its reader for the largest.
    let probed: Vec<_> = files.iter().zip(&found).map(|(path, found)| found.probe(path)).collect();
    let jobs = super::jobs(args.jobs).min(files.len().max(1));
    let mut out = Stream::stdout();
    check.open(&mut out);
    let tally = if jobs == 1 {
        check.on_one_thread(&files, &probed, &mut out)
    } else {
        check.on_threads(jobs, &files, &probed, &mut out)
    };
    check.close(&tally, files.len(), &mut out);
    out.finish();
    tally.exit_code()
}

/// What a run checks with: the reader's options, and what is printed how.
struct Check {
    options: eds::Options,
    format: Format,
    level: Level,
    /// Codes not shown (`--allow`).
    allowed: Vec<String>,
    /// Whether the generator's diagnostics are added.
    codegen: bool,
    strict: bool,
}

/// What a run found so far: the counts, the files that could not be read (name and why), and
/// whether a JSON file object or a SARIF result was written (the next one needs a comma).
#[derive(Default)]
struct Tally {
    counts: Counts,
    unreadable: Vec<(String, String)>,
    any: bool,
}

impl Tally {
    /// A file that could not be read: said at once on standard error in human output, listed
    /// in the JSON and SARIF documents.
    fn cannot_read(&mut self, path: &std::path::Path, e: std::io::Error, format: Format) {
        let name = path.display().to_string();
        if format == Format::Human {
            eprintln!("error: cannot read {name}: {e}");
        }
        self.unreadable.push((name, e.to_string()));
    }

    /// The exit code: 2 when a file could not be read, 1 when one has an error, 0 otherwise.
    fn exit_code(&self) -> u8 {
        if !self.unreadable.is_empty() {
            EXIT_TROUBLE
        } else if self.counts.errors > 0 {
            EXIT_FAILURE
        } else {
            0
        }
    }
}

impl Check {
    /// The start of the output (JSON and SARIF open their document).
    fn open(&self, out: &mut Stream) {
        match self.format {
            Format::Human => {}
            Format::Json => out.push("{\"files\":["),
            Format::Sarif => super::sarif::start(out),
        }
    }

    /// The files read one after the other on this thread, each file's report rendered straight
    /// into the output, which writes it as it fills. The reader is made for the largest file
    /// (it reads them in the order given, and a buffer a later, larger file outgrew would be
    /// replaced), at most for one of `ROOM_AT_MOST`: the largest file may be one that cannot
    /// be read, and the others' buffers are not to be made for gigabytes; a larger file makes
    /// its own.
    fn on_one_thread(&self, files: &[PathBuf], probed: &[Probe<'_>], out: &mut Stream) -> Tally {
        let mut tally = Tally::default();
        let room = sizes(probed).max().unwrap_or(0).min(ROOM_AT_MOST as u64) as usize;
        for (path, probed) in files.iter().zip(probed) {
            let read = probed_file(probed).and_then(|probed| {
                self.check_file(probed, room, out, |writes, out| separate(writes, &mut tally.any, out))
            });
            match read {
                Ok(c) => tally.counts.add_counts(&c),
                Err(e) => tally.cannot_read(path, e, self.format),
            }
        }
        tally
    }

    /// The files read on `jobs` threads, largest first, each file's report rendered by the
    /// thread that read it and written in the order of the files.
    fn on_threads(&self, jobs: usize, files: &[PathBuf], probed: &[Probe<'_>], out: &mut Stream) -> Tally {
        let mut tally = Tally::default();
        let read = |i: usize, _: &PathBuf| {
            let probed = probed_file(&probed[i])?;
            let mut text = String::new();
            let mut writes = false;
            let counts = self.check_file(probed, 0, &mut text, |w, _| writes = w)?;
            Ok::<_, std::io::Error>(Report { text, writes, counts })
        };
        super::par_each(jobs, files, super::largest_first(sizes(probed)), read, |path, report| match report {
            Ok(report) => {
                tally.counts.add_counts(&report.counts);
                separate(report.writes, &mut tally.any, out);
                out.push(&report.text);
            }
            Err(e) => tally.cannot_read(path, e, self.format),
        });
        tally
    }

    /// The end of the output: the summary line, or the JSON document's counts and unreadable
    /// files, or the SARIF document's notifications.
    fn close(&self, tally: &Tally, files: usize, out: &mut Stream) {
        let Tally { counts, unreadable, .. } = tally;
        match self.format {
            Format::Human => {
                let mut line = format!(
                    "checked {files} file{}: {}",
                    if files == 1 { "" } else { "s" },
                    summary(counts, self.level)
                );
                if !unreadable.is_empty() {
                    line.push_str(&format!(", {} unreadable", unreadable.len()));
                }
                line.push('\n');
                out.push(&line);
            }
            Format::Json => out.with(|buf| {
                use std::fmt::Write as _;
                let _ = write!(
                    buf,
                    "\n],\n\"errors\":{},\"warnings\":{},\"notes\":{},\"unreadable\":{},\"unreadable_files\":[",
                    counts.errors,
                    counts.warnings,
                    counts.notes,
                    unreadable.len()
                );
                for (i, (file, reason)) in unreadable.iter().enumerate() {
                    buf.push_str(if i == 0 { "\n{\"file\":" } else { ",\n{\"file\":" });
                    eds::diag::push_json_str(buf, file);
                    buf.push_str(",\"reason\":");
                    eds::diag::push_json_str(buf, reason);
                    buf.push('}');
                }
                buf.push_str("]}\n");
            }),
            Format::Sarif => super::sarif::finish(out, unreadable),
        }
    }

    /// Reads a probed file with this thread's `Reader` and renders its part of the output into
    /// `out`, after `lead` (told whether the part has anything in it); gives the file's counts.
    /// One thread and several check a file through this alike. A thread's reader is made at its
    /// first file with room for files of `room` bytes ([`eds::Reader::with_room`]): several
    /// threads take the files largest first, so that 0 (room for the first file) does; one
    /// thread gives the largest file's size.
    fn check_file<S: Sink>(
        &self,
        probed: &eds::Probed<'_>,
        room: usize,
        out: &mut S,
        lead: impl FnOnce(bool, &mut S),
    ) -> std::io::Result<Counts> {
        READER.with_borrow_mut(|reader| {
            let reader = reader.get_or_insert_with(|| eds::Reader::with_room(room));
            let mut parsed = reader.read_probed(probed, &self.options)?;
            // The generator's diagnostics for a file the reader accepts: a build stops at the
            // reader's errors, and generating from a refused file (bounded by the reader, but
            // large) would cost memory and time for nothing.
            let mut extra = if self.codegen && !parsed.has_errors() {
                self.codegen_diagnostics(&parsed, probed.path())
            } else {
                Vec::new()
            };
            if !self.allowed.is_empty() {
                parsed.diagnostics.retain(|d| od_codegen::shown(d, &self.allowed));
                extra.retain(|d| od_codegen::shown(d, &self.allowed));
            }
            lead(writes_anything(&parsed, &extra, self.format, self.level), out);
            let counts = render(&parsed, &extra, probed.path(), self.format, self.level, out);
            reader.recycle(parsed);
            Ok(counts)
        })
    }
}

impl Check {
    /// The code generator's diagnostics for a file read (those a build reports besides the
    /// reader's), with the sidecar beside the file as the `Builder` reads it.
    fn codegen_diagnostics(&self, parsed: &eds::Parsed, path: &std::path::Path) -> Vec<Diagnostic> {
        let shown = parsed.document.source.name.clone();
        let mut options = od_codegen::Options::new("device", shown.clone());
        options.strict = self.strict;
        let mut out = Vec::new();
        let sidecar = path.with_extension("toml");
        if sidecar.is_file() {
            match od_codegen::sidecar::Sidecar::read(&sidecar) {
                Ok(sc) => options.sidecar = Some(sc),
                Err(e) => out.push(Diagnostic {
                    severity: Severity::Error,
                    code: od_codegen::diag::SIDECAR,
                    message: e.to_string(),
                    file: shown.as_str().into(),
                    span: None,
                    at: None,
                    context: Vec::new(),
                    hint: None,
                }),
            }
        }
        out.extend(od_codegen::diagnose(&parsed.model, &options));
        // All counted; `render` shows those of the level.
        out
    }
}

/// A file probed, or why it could not be.
type Probe<'a> = std::io::Result<eds::Probed<'a>>;

/// The sizes of probed files (0 for one that could not be probed).
fn sizes<'a>(probed: &'a [Probe<'_>]) -> impl ExactSizeIterator<Item = u64> + 'a {
    probed.iter().map(|p| p.as_ref().map_or(0, |p| p.len()))
}

/// A probed file, or why it could not be probed (the error repeated: an `io::Error` is not
/// `Clone`, and the probes are shared by the threads).
fn probed_file<'a, 'p>(probed: &'a Probe<'p>) -> std::io::Result<&'a eds::Probed<'p>> {
    probed.as_ref().map_err(|e| std::io::Error::new(e.kind(), e.to_string()))
}

thread_local! {
    /// Each reading thread's [`eds::Reader`] (made at its first file): a file is read into the
    /// memory the thread's last file used (given back as soon as its report is rendered).
    static READER: std::cell::RefCell<Option<eds::Reader>> = const { std::cell::RefCell::new(None) };
}

/// The separator before a file's part of the output, when it has anything in it (`any`: a
/// part was written before, which the next one follows after a comma).
fn separate(writes: bool, any: &mut bool, out: &mut Stream) {
    if writes {
        out.push(if *any { ",\n" } else { "\n" });
        *any = true;
    }
}

/// Whether a file's part of the output has anything in it (JSON and SARIF put a separator
/// before each part that has; a JSON part always has the file's name).
fn writes_anything(parsed: &eds::Parsed, extra: &[Diagnostic], format: Format, level: Level) -> bool {
    match format {
        Format::Human => false,
        Format::Json => true,
        Format::Sarif => parsed.diagnostics.iter().chain(extra).any(|d| level.shows(d.severity)),
    }
}

/// Renders a file's part of the output into `out`, and gives its counts.
fn render(
    parsed: &eds::Parsed,
    extra: &[Diagnostic],
    path: &std::path::Path,
    format: Format,
    level: Level,
    out: &mut impl Sink,
) -> Counts {
    let mut counts = Counts::default();
    counts.add(&parsed.diagnostics);
    counts.add(extra);
    counts.warnings += parsed.not_kept.warnings;
    counts.notes += parsed.not_kept.notes;
    let source = &parsed.document.source;
    let shown = parsed.diagnostics.iter().chain(extra).filter(|d| level.shows(d.severity));
    match format {
        Format::Human => {
            for d in shown {
                let text = out.text();
                eds::diag::render_to(text, d, source);
                text.push('\n');
            }
        }
        Format::Json => {
            let text = out.text();
            text.push_str("{\"file\":");
            eds::diag::push_json_str(text, &path.display().to_string());
            text.push_str(",\"diagnostics\":[");
            for (i, d) in shown.enumerate() {
                let text = out.text();
                text.push_str(if i == 0 { "\n" } else { ",\n" });
                eds::diag::push_json(text, d);
            }
            out.text().push_str("]}");
        }
        Format::Sarif => {
            for (i, d) in shown.enumerate() {
                let text = out.text();
                if i > 0 {
                    text.push_str(",\n");
                }
                super::sarif::push_result(text, d, source);
            }
        }
    }
    counts
}

/// `2 errors, 1 warning, 3 notes` (`no problems` when there are none); what was counted but
/// not printed is marked so, with the flag that prints it.
fn summary(c: &Counts, level: Level) -> String {
    let part = |n: usize, what: &str, severity: Severity, flag: &str| {
        let mut p = format!("{n} {what}{}", if n == 1 { "" } else { "s" });
        if !level.shows(severity) {
            p.push_str(&format!(" (not shown; {flag} shows them)"));
        }
        p
    };
    let mut parts = Vec::new();
    if c.errors > 0 {
        parts.push(part(c.errors, "error", Severity::Error, ""));
    }
    if c.warnings > 0 {
        parts.push(part(c.warnings, "warning", Severity::Warning, "--level warning"));
    }
    if c.notes > 0 {
        parts.push(part(c.notes, "note", Severity::Note, "--notes"));
    }
    if parts.is_empty() { "no problems".to_owned() } else { parts.join(", ") }
}
