//! One module per subcommand.

pub mod bench_read;
pub mod check;
pub mod dcf;
pub mod diff;
pub mod dump;
pub mod fmt;
pub mod generate;
pub mod sarif;

use std::path::Path;

/// Exit code for "ran, found errors" (diagnostics with errors, files not canonical).
pub const EXIT_FAILURE: u8 = 1;
/// Exit code for "could not do what was asked" (unreadable file, bad arguments).
pub const EXIT_TROUBLE: u8 = 2;

/// Reads a file, or prints why not (`error: cannot read X: ...`) and gives `None`.
pub fn read_or_report(path: &Path, options: &eds::Options) -> Option<eds::Parsed> {
    match eds::read_file(path, options) {
        Ok(p) => Some(p),
        Err(e) => {
            eprintln!("error: cannot read {}: {e}", path.display());
            None
        }
    }
}

/// The number of threads to read files with: `--jobs` when given (at least 1), otherwise one
/// per available core.
pub fn jobs(requested: Option<usize>) -> usize {
    requested.unwrap_or_else(|| std::thread::available_parallelism().map_or(1, usize::from)).max(1)
}

/// `f(&items[i])` for every item on up to `jobs` threads, each result handed to `emit` on the
/// calling thread in the items' order as soon as it and those before it are ready. Each thread
/// takes the next unclaimed item, so one large file does not hold up the rest; the calling
/// thread is one of them (a thread fewer to start, and the one whose memory is already in use:
/// each new thread's allocations start on fresh pages, each a page fault), and it hands out
/// what is ready between its own items, so results are written and freed as the run goes
/// rather than all held to the end.
pub fn par_each<T: Sync, R: Send>(items: &[T], jobs: usize, f: impl Fn(&T) -> R + Sync, mut emit: impl FnMut(&T, R)) {
    use std::sync::atomic::{AtomicUsize, Ordering};
    use std::sync::{Condvar, Mutex};
    let jobs = jobs.clamp(1, items.len().max(1));
    if jobs == 1 {
        for item in items {
            emit(item, f(item));
        }
        return;
    }
    let next = AtomicUsize::new(0);
    let slots: Mutex<Vec<Option<R>>> = Mutex::new(items.iter().map(|_| None).collect());
    let filled = Condvar::new();
    let put = |i: usize, r: R| {
        let mut s = slots.lock().unwrap_or_else(|e| e.into_inner());
        s[i] = Some(r);
        filled.notify_one();
    };
    std::thread::scope(|scope| {
        let workers: Vec<_> = (1..jobs)
            .map(|_| {
                scope.spawn(|| {
                    loop {
                        let i = next.fetch_add(1, Ordering::Relaxed);
                        let Some(item) = items.get(i) else { break };
                        put(i, f(item));
                    }
                })
            })
            .collect();
        // The first result not yet handed to `emit`.
        let mut done = 0;
        let take_ready = |wait: bool, done: &mut usize, emit: &mut dyn FnMut(&T, R)| {
            let mut s = slots.lock().unwrap_or_else(|e| e.into_inner());
            while *done < items.len() {
                match s[*done].take() {
                    Some(r) => {
                        // (Emitted without the lock: writing may take a while.)
                        drop(s);
                        emit(&items[*done], r);
                        *done += 1;
                        s = slots.lock().unwrap_or_else(|e| e.into_inner());
                    }
                    None if wait => s = filled.wait(s).unwrap_or_else(|e| e.into_inner()),
                    None => break,
                }
            }
        };
        loop {
            let i = next.fetch_add(1, Ordering::Relaxed);
            let Some(item) = items.get(i) else { break };
            let r = f(item);
            put(i, r);
            take_ready(false, &mut done, &mut emit);
        }
        take_ready(true, &mut done, &mut emit);
        // A worker only panics if `f` does, which is a bug to surface, not an input error.
        for w in workers {
            if let Err(e) = w.join() {
                std::panic::resume_unwind(e);
            }
        }
    });
}

/// Set once standard output's reader has gone away.
static STDOUT_GONE: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Writes text to standard output. When the reader has gone away (`odgen dump x.eds | head`),
/// the rest of the output is dropped quietly and the command finishes with the exit code it
/// would have had (so `odgen diff A B | head` still says 1 for "different"), instead of
/// panicking the way `print!` does. Any other write error (a full disk) is reported and exits
/// with [`EXIT_TROUBLE`].
pub fn write_stdout(text: &str) {
    use std::io::Write as _;
    use std::sync::atomic::Ordering;
    if STDOUT_GONE.load(Ordering::Relaxed) {
        return;
    }
    let mut out = std::io::stdout().lock();
    if let Err(e) = out.write_all(text.as_bytes()).and_then(|()| out.flush()) {
        if e.kind() == std::io::ErrorKind::BrokenPipe {
            STDOUT_GONE.store(true, Ordering::Relaxed);
            return;
        }
        eprintln!("error: cannot write to standard output: {e}");
        std::process::exit(i32::from(EXIT_TROUBLE));
    }
}

/// Output to standard output, written in blocks of 64 KiB through [`write_stdout`] as it is
/// made: a command printing a great deal never holds it all.
pub struct Stream {
    buf: String,
}

impl Stream {
    /// The size at which the buffer is written out.
    const BLOCK: usize = 1 << 16;

    /// A stream to standard output.
    pub fn stdout() -> Self {
        Stream { buf: String::with_capacity(Self::BLOCK + 4096) }
    }

    /// Appends text. Text that does not fit in the buffer's room is written out with what is
    /// buffered rather than grow the buffer (a larger block would be fresh memory, and a copy).
    pub fn push(&mut self, text: &str) {
        let large = text.len() >= Self::BLOCK;
        if (large || self.buf.len() + text.len() > self.buf.capacity()) && !self.buf.is_empty() {
            write_stdout(&self.buf);
            self.buf.clear();
        }
        if large {
            write_stdout(text);
            return;
        }
        self.buf.push_str(text);
        self.write_if_full();
    }

    /// Lets `f` append to the buffer.
    pub fn with(&mut self, f: impl FnOnce(&mut String)) {
        f(&mut self.buf);
        self.write_if_full();
    }

    fn write_if_full(&mut self) {
        if self.buf.len() >= Self::BLOCK {
            write_stdout(&self.buf);
            self.buf.clear();
        }
    }

    /// Writes what is left.
    pub fn finish(mut self) {
        write_stdout(&self.buf);
        self.buf.clear();
    }
}

impl crate::yaml::Sink for Stream {
    fn push(&mut self, text: &str) {
        Stream::push(self, text);
    }
}

/// Bytes written to a [`Stream`] (serde_json's output, which is UTF-8).
impl std::io::Write for Stream {
    fn write(&mut self, bytes: &[u8]) -> std::io::Result<usize> {
        // serde_json writes whole UTF-8 sequences; anything else is a bug to hear about.
        let text = std::str::from_utf8(bytes).map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidData, e))?;
        self.push(text);
        Ok(bytes.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// `println!` through [`write_stdout`].
macro_rules! outln {
    ($($arg:tt)*) => {{
        let mut s = format!($($arg)*);
        s.push('\n');
        $crate::cmd::write_stdout(&s);
    }};
}
pub(crate) use outln;
