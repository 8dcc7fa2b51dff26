//! One module per subcommand.

pub mod bench_read;
pub mod check;
pub mod dcf;
pub mod diff;
pub mod dump;
pub mod fmt;
pub mod generate;
pub mod names;
pub mod sarif;
pub mod sidecar;

use std::path::{Path, PathBuf};

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

/// `f(i, &items[i])` for every item on `jobs` threads, each result handed to `emit` on the
/// calling thread in the items' order as soon as it and those before it are ready.
///
/// The threads take the items in `order`, a permutation of their indices (e.g. the largest
/// first, so that the last ones taken are small and the threads finish together; anything
/// else is taken as the items' own order): each thread takes the next unclaimed item. The
/// calling thread is one of them, and hands out what is ready between its own items, so that
/// results are written and freed as the run goes rather than all held to the end. A panic in
/// `f` or `emit` reaches the caller once every thread has stopped.
pub fn par_each<T: Sync, R: Send>(
    jobs: usize,
    items: &[T],
    order: Vec<usize>,
    f: impl Fn(usize, &T) -> R + Sync,
    mut emit: impl FnMut(&T, R),
) {
    use std::sync::atomic::{AtomicUsize, Ordering};
    use std::sync::{Condvar, Mutex};
    let order = permutation_or_identity(order, items.len());
    let next = AtomicUsize::new(0);
    // The next item to work on (`None` when all are taken).
    let claim = || order.get(next.fetch_add(1, Ordering::Relaxed)).map(|&i| (i, &items[i]));
    // The results not yet emitted, and whether a worker stopped on a panic (its item never
    // comes: the calling thread stops waiting, and the scope passes the panic on).
    let slots: Mutex<(Vec<Option<R>>, bool)> = Mutex::new((items.iter().map(|_| None).collect(), false));
    let filled = Condvar::new();
    let put = |i: usize, r: R| {
        slots.lock().unwrap_or_else(|e| e.into_inner()).0[i] = Some(r);
        filled.notify_one();
    };
    // Tells the calling thread, when a worker unwinds, that it is to wait no more.
    struct Stopped<'a, R>(&'a Mutex<(Vec<Option<R>>, bool)>, &'a Condvar);
    impl<R> Drop for Stopped<'_, R> {
        fn drop(&mut self) {
            if std::thread::panicking() {
                self.0.lock().unwrap_or_else(|e| e.into_inner()).1 = true;
                self.1.notify_one();
            }
        }
    }
    // Hands `emit` every result ready in the items' order from `done` on; with `wait`, waits
    // for the rest (until a worker stops on a panic).
    let emit_ready = |wait: bool, done: &mut usize, emit: &mut dyn FnMut(&T, R)| {
        let mut s = slots.lock().unwrap_or_else(|e| e.into_inner());
        while *done < items.len() {
            match s.0[*done].take() {
                Some(r) => {
                    // (Emitted without the lock: writing may take a while.)
                    drop(s);
                    emit(&items[*done], r);
                    *done += 1;
                    s = slots.lock().unwrap_or_else(|e| e.into_inner());
                }
                None if s.1 || !wait => break,
                None => s = filled.wait(s).unwrap_or_else(|e| e.into_inner()),
            }
        }
    };
    std::thread::scope(|scope| {
        for _ in 1..jobs.min(items.len()) {
            let spawned = std::thread::Builder::new().spawn_scoped(scope, || {
                let _stopped = Stopped(&slots, &filled);
                while let Some((i, item)) = claim() {
                    put(i, f(i, item));
                }
            });
            // (The calling thread and the workers started take every item all the same.)
            if spawned.is_err() {
                break;
            }
        }
        // The first result not yet handed to `emit`.
        let mut done = 0;
        while let Some((i, item)) = claim() {
            put(i, f(i, item));
            emit_ready(false, &mut done, &mut emit);
        }
        emit_ready(true, &mut done, &mut emit);
    });
}

/// `order` if it is a permutation of `0..n` (every index once), otherwise `0..n`: an order that
/// missed an item would leave the calling thread waiting for it for ever.
fn permutation_or_identity(order: Vec<usize>, n: usize) -> Vec<usize> {
    let mut seen = vec![false; n];
    let ok = order.len() == n && order.iter().all(|&i| i < n && !std::mem::replace(&mut seen[i], true));
    if ok { order } else { (0..n).collect() }
}

/// How a file of [`expand_folders`] was found.
#[derive(Debug)]
pub enum Found {
    /// Given as such: what `std::fs::metadata` said of it (through symbolic links) when it was
    /// asked whether it is a folder; [`eds::probe_with`] probes it with that answer, without
    /// asking again.
    Given(std::io::Result<std::fs::Metadata>),
    /// Listed in a folder (not yet probed).
    Listed,
    /// A folder that could not be listed, standing for its files: why.
    Unlisted(std::io::Error),
}

impl Found {
    /// [`eds::probe`] of the file found at `path`, from the metadata already known when it was
    /// given as such (a folder that could not be listed is refused with why).
    pub fn probe<'a>(&self, path: &'a Path) -> std::io::Result<eds::Probed<'a>> {
        match self {
            Found::Given(Ok(m)) => eds::probe_with(path, m),
            Found::Given(Err(e)) => Err(std::io::Error::new(e.kind(), e.to_string())),
            Found::Listed => eds::probe(path),
            Found::Unlisted(e) => Err(std::io::Error::new(e.kind(), format!("cannot list the folder: {e}"))),
        }
    }
}

/// The files a command is given: each path that is not a folder, and for each folder, the files
/// in it and in its subfolders whose names end in `.eds` or `.dcf` (in any case), in the order
/// of their paths. Symbolic links to files are taken; links to folders are not followed, so a
/// link that loops ends the walk there. With each file, how it was found ([`Found`]: a path
/// given keeps the metadata asked for it, which probes it; a folder that could not be listed
/// stands in the list for its files, with why).
pub fn expand_folders(paths: &[PathBuf]) -> (Vec<PathBuf>, Vec<Found>) {
    let mut files = Vec::with_capacity(paths.len());
    let mut found = Vec::with_capacity(paths.len());
    for path in paths {
        match std::fs::metadata(path) {
            Ok(m) if m.is_dir() => walk(path, &mut files, &mut found),
            m => {
                files.push(path.clone());
                found.push(Found::Given(m));
            }
        }
    }
    (files, found)
}

/// [`expand_folders`] of one folder.
fn walk(dir: &std::path::Path, files: &mut Vec<PathBuf>, found: &mut Vec<Found>) {
    let listed = std::fs::read_dir(dir).and_then(|entries| entries.collect::<std::io::Result<Vec<_>>>());
    let mut entries = match listed {
        Ok(entries) => entries,
        Err(e) => {
            files.push(dir.to_path_buf());
            found.push(Found::Unlisted(e));
            return;
        }
    };
    entries.sort_by_key(|e| e.file_name());
    for entry in entries {
        let path = entry.path();
        // (The entry's own type: a link to a folder is a link, not a folder.)
        let Ok(kind) = entry.file_type() else { continue };
        if kind.is_dir() {
            walk(&path, files, found);
        } else {
            let ext = path.extension().and_then(|e| e.to_str()).unwrap_or("");
            if ext.eq_ignore_ascii_case("eds") || ext.eq_ignore_ascii_case("dcf") {
                files.push(path);
                found.push(Found::Listed);
            }
        }
    }
}

/// The order to work on items of these sizes in: the largest first (items of the same size in
/// their own order).
pub fn largest_first(sizes: impl ExactSizeIterator<Item = u64>) -> Vec<usize> {
    let mut order: Vec<(u64, usize)> = sizes.enumerate().map(|(i, s)| (s, i)).collect();
    order.sort_by_key(|&(s, i)| (std::cmp::Reverse(s), i));
    order.into_iter().map(|(_, i)| i).collect()
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
        Stream { buf: String::new() }
    }

    /// The buffer, made at the first text.
    fn buffer(&mut self) -> &mut String {
        if self.buf.capacity() == 0 {
            self.buf.reserve_exact(Self::BLOCK + 4096);
        }
        &mut self.buf
    }

    /// Appends text. Text that does not fit in the buffer's room is written out with what is
    /// buffered rather than grow the buffer (a larger block would be fresh memory, and a copy).
    pub fn push(&mut self, text: &str) {
        let large = text.len() >= Self::BLOCK;
        if !large {
            self.buffer();
        }
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

    /// The buffer, to append a piece of at most a few KiB to (what it holds is written out
    /// first once it reaches the block size, so that it does not grow).
    pub fn room(&mut self) -> &mut String {
        self.write_if_full();
        self.buffer()
    }

    /// Lets `f` append to the buffer.
    pub fn with(&mut self, f: impl FnOnce(&mut String)) {
        f(self.buffer());
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

#[cfg(test)]
mod tests {
    use super::*;

    /// `--jobs` is taken as given (at least one); otherwise one thread per core.
    #[test]
    fn jobs_are_the_given_number_or_the_cores() {
        assert_eq!(jobs(Some(0)), 1);
        assert_eq!(jobs(Some(3)), 3);
        assert_eq!(jobs(None), std::thread::available_parallelism().map_or(1, usize::from));
    }

    /// The order is a permutation of the indices, by size from the largest, and items of one
    /// size keep their order.
    #[test]
    fn largest_first_sorts_by_size_then_position() {
        assert_eq!(largest_first([3u64, 9, 3, 0, 9, 1].into_iter()), vec![1, 4, 0, 2, 5, 3]);
        assert!(largest_first(std::iter::empty()).is_empty());
        // Every length up to 40 with sizes from a small range (many ties).
        let mut seed = 0x2545_F491_4F6C_DD1Du64;
        for n in 0..40usize {
            let sizes: Vec<u64> = (0..n)
                .map(|_| {
                    seed ^= seed << 13;
                    seed ^= seed >> 7;
                    seed ^= seed << 17;
                    seed % 5
                })
                .collect();
            let order = largest_first(sizes.iter().copied());
            let mut seen = order.clone();
            seen.sort_unstable();
            assert_eq!(seen, (0..n).collect::<Vec<_>>(), "{sizes:?}");
            for w in order.windows(2) {
                let (a, b) = (w[0], w[1]);
                assert!(sizes[a] > sizes[b] || (sizes[a] == sizes[b] && a < b), "{sizes:?} {order:?}");
            }
        }
    }

    /// Whatever the order the threads take the items in and however many threads there are,
    /// every item is worked on once and the results are emitted in the items' order.
    #[test]
    fn par_each_emits_in_item_order_whatever_the_claim_order() {
        use std::sync::atomic::{AtomicUsize, Ordering};
        for n in [0usize, 1, 2, 7, 64] {
            let items: Vec<usize> = (0..n).collect();
            let orders = [
                (0..n).collect::<Vec<_>>(),
                (0..n).rev().collect(),
                largest_first(items.iter().map(|&i| (i * 7 % 5) as u64)),
            ];
            for order in &orders {
                for jobs in [1usize, 2, 3, 8] {
                    let calls = AtomicUsize::new(0);
                    let mut emitted = Vec::new();
                    par_each(
                        jobs,
                        &items,
                        order.clone(),
                        |at, &i| {
                            assert_eq!(at, i);
                            calls.fetch_add(1, Ordering::Relaxed);
                            // Uneven work, so that results come back out of order.
                            std::thread::sleep(std::time::Duration::from_micros((i % 3) as u64 * 50));
                            i * 2
                        },
                        |&i, r| emitted.push((i, r)),
                    );
                    assert_eq!(calls.load(Ordering::Relaxed), n, "n {n} jobs {jobs}");
                    assert_eq!(emitted, items.iter().map(|&i| (i, i * 2)).collect::<Vec<_>>(), "n {n} jobs {jobs}");
                }
            }
        }
    }

    /// The threads take the items in the order given: each thread's items come in that order
    /// (one thread takes them all in it).
    #[test]
    fn par_each_takes_items_in_the_order_given() {
        let items: Vec<usize> = (0..50).collect();
        let order = largest_first(items.iter().map(|&i| (i * 37 % 11) as u64));
        let place = |i: usize| order.iter().position(|&o| o == i).unwrap();
        for jobs in [1usize, 2, 4] {
            let started = std::sync::Mutex::new(Vec::new());
            par_each(
                jobs,
                &items,
                order.clone(),
                |_, &i| started.lock().unwrap().push((std::thread::current().id(), i)),
                |_, ()| {},
            );
            let started = started.into_inner().unwrap();
            assert_eq!(started.len(), items.len());
            if jobs == 1 {
                assert_eq!(started.iter().map(|&(_, i)| i).collect::<Vec<_>>(), order);
                continue;
            }
            let threads: std::collections::HashSet<_> = started.iter().map(|&(t, _)| t).collect();
            for t in threads {
                let mine: Vec<usize> = started.iter().filter(|&&(u, _)| u == t).map(|&(_, i)| place(i)).collect();
                assert!(mine.windows(2).all(|w| w[0] < w[1]), "jobs {jobs}: places {mine:?}");
            }
        }
    }

    /// The calling thread, once it has no item left, waits for the workers' results and is
    /// woken for each: the workers are made slow, so that it waits, in many rounds. A missed
    /// wake would leave it waiting: the run is timed.
    #[test]
    fn par_each_waits_for_slow_workers_and_is_woken() {
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            for round in 0..40usize {
                let items: Vec<usize> = (0..(2 + round % 8)).collect();
                let caller = std::thread::current().id();
                for jobs in [2usize, 3] {
                    let mut emitted = Vec::new();
                    par_each(
                        jobs,
                        &items,
                        (0..items.len()).collect(),
                        |_, &i| {
                            // (The calling thread slow enough for the workers to start and
                            // take items, the workers slower still.)
                            let slow = if std::thread::current().id() == caller { 300 } else { 1500 };
                            std::thread::sleep(std::time::Duration::from_micros(slow + (i % 3) as u64 * 100));
                            i * 3
                        },
                        |&i, r| emitted.push((i, r)),
                    );
                    assert_eq!(emitted, items.iter().map(|&i| (i, i * 3)).collect::<Vec<_>>());
                }
            }
            let _ = tx.send(());
        });
        rx.recv_timeout(std::time::Duration::from_secs(60)).expect("par_each should not wait for ever");
    }

    /// An order that is no permutation of the items (an index missing, repeated or out of
    /// range) is taken as the items' own order: every item is still worked on once.
    #[test]
    fn par_each_survives_an_order_that_is_no_permutation() {
        let items: Vec<usize> = (0..9).collect();
        for bad in [vec![], vec![0, 1, 2], vec![0; 9], vec![8, 7, 6, 5, 4, 3, 2, 1, 99], (0..10).collect()] {
            for jobs in [1usize, 3] {
                let mut emitted = Vec::new();
                par_each(jobs, &items, bad.clone(), |_, &i| i + 1, |&i, r| emitted.push((i, r)));
                assert_eq!(emitted, items.iter().map(|&i| (i, i + 1)).collect::<Vec<_>>(), "{bad:?} jobs {jobs}");
            }
        }
        assert_eq!(permutation_or_identity(vec![2, 0, 1], 3), vec![2, 0, 1]);
        assert_eq!(permutation_or_identity(vec![2, 2, 1], 3), vec![0, 1, 2]);
    }

    /// A panic in `f` (on any thread) or in `emit` reaches the caller once every worker has
    /// stopped (none outlives what it borrows).
    #[test]
    fn par_each_panics_only_once_its_workers_have_stopped() {
        let items: Vec<usize> = (0..40).collect();
        let running = std::sync::atomic::AtomicUsize::new(0);
        for case in ["f", "emit"] {
            for jobs in [2usize, 4] {
                let outcome = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                    par_each(
                        jobs,
                        &items,
                        (0..40).collect(),
                        |_, &i| {
                            running.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
                            std::thread::sleep(std::time::Duration::from_micros(200));
                            running.fetch_sub(1, std::sync::atomic::Ordering::SeqCst);
                            assert!(!(case == "f" && i == 7), "f");
                            i
                        },
                        |&i, _| assert!(!(case == "emit" && i == 3), "emit"),
                    )
                }));
                assert!(outcome.is_err(), "{case} jobs {jobs}");
                assert_eq!(running.load(std::sync::atomic::Ordering::SeqCst), 0, "{case} jobs {jobs}");
            }
        }
    }

    /// A path given as a file keeps the metadata asked for it, which probes it as `eds::probe`
    /// does (its size; a missing file's error); a folder's files are listed, probed when read.
    #[test]
    fn expanded_paths_probe_as_eds_probe_does() {
        let dir = std::env::temp_dir().join(format!("odgen-expand-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("sub")).expect("temp dir");
        std::fs::write(dir.join("a.eds"), "[FileInfo]\n").expect("write");
        std::fs::write(dir.join("sub/b.DCF"), "[DeviceInfo]\nX=1\n").expect("write");
        std::fs::write(dir.join("sub/c.txt"), "not listed").expect("write");
        let given = [dir.join("a.eds"), dir.join("missing.eds"), dir.clone()];
        let (files, found) = expand_folders(&given);
        assert_eq!(files, vec![dir.join("a.eds"), dir.join("missing.eds"), dir.join("a.eds"), dir.join("sub/b.DCF")]);
        assert!(matches!(found[0], Found::Given(Ok(_))), "{found:?}");
        assert!(matches!(found[1], Found::Given(Err(_))), "{found:?}");
        assert!(matches!(found[2..], [Found::Listed, Found::Listed]), "{found:?}");
        for (path, found) in files.iter().zip(&found) {
            let direct = eds::probe(path).map(|p| p.len()).map_err(|e| (e.kind(), e.to_string()));
            let known = found.probe(path).map(|p| p.len()).map_err(|e| (e.kind(), e.to_string()));
            assert_eq!(direct, known, "{}", path.display());
        }
        let unlisted = Found::Unlisted(std::io::Error::from(std::io::ErrorKind::PermissionDenied));
        let e = unlisted.probe(&dir).expect_err("unlisted");
        assert_eq!(e.kind(), std::io::ErrorKind::PermissionDenied);
        assert!(e.to_string().starts_with("cannot list the folder: "), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
