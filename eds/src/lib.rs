#![doc = include_str!("../README.md")]
//! # Pipeline
//!
//! Bytes → [`source::SourceFile`] (UTF-8, Windows-1252 fallback) → [`lex`] →
//! [`ast::Document`] (lossless: every byte, comment, key spelling and order kept) → [`lower`] →
//! [`model::Model`] (typed) + [`diag::Diagnostic`]s → [`mod@write`] (canonical EDS/DCF text).
#![deny(missing_docs)]

pub mod ast;
pub mod codes;
pub mod concise;
pub mod diag;
pub mod encoding;
pub mod lex;
pub mod lower;
pub mod model;
pub mod name;
pub mod source;
pub mod value;
pub mod write;

pub use diag::{Code, Diagnostic, Severity};
pub use model::*;
pub use name::Name;

/// How strictly a file is judged.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum Strictness {
    /// Loads what real vendor files contain; CiA 306 deviations are warnings.
    #[default]
    Lenient,
    /// Every CiA 306 deviation is an error.
    Strict,
}

/// Options for [`parse`].
#[derive(Clone, Debug)]
pub struct Options {
    /// Lenient or strict.
    pub strictness: Strictness,
    /// The least severe diagnostics kept (see [`Options::keep_from`]).
    least_kept: Severity,
}

impl Default for Options {
    fn default() -> Self {
        Options { strictness: Strictness::default(), least_kept: Severity::Note }
    }
}

impl Options {
    /// Lenient options.
    pub fn lenient() -> Self {
        Options { strictness: Strictness::Lenient, ..Options::default() }
    }

    /// Strict options.
    pub fn strict() -> Self {
        Options { strictness: Strictness::Strict, ..Options::default() }
    }

    /// Keeps only diagnostics at least as severe as `least` (at the options' strictness); the
    /// others are counted in [`Parsed::not_kept`] and not made, which saves their text and
    /// memory: a tool that shows errors and warnings (`odgen check` does by default) need not
    /// build the notes it only counts. By default every diagnostic is kept. (The diagnostics
    /// not kept do not count against the bounds on how many a file keeps, `lower::MAX_KEPT`
    /// and `lower::MAX_PER_CODE`, so a file with more than that keeps the severe ones it
    /// would otherwise have kept, or more.)
    pub fn keep_from(mut self, least: Severity) -> Self {
        self.least_kept = least;
        self
    }

    /// The least severe diagnostics kept ([`Options::keep_from`]; [`Severity::Note`] unless set).
    pub fn least_kept(&self) -> Severity {
        self.least_kept
    }
}

/// How many diagnostics were found but not kept because [`Options::keep_from`] asked for more
/// severe ones only (errors are always kept).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct NotKept {
    /// Warnings not kept.
    pub warnings: usize,
    /// Notes not kept.
    pub notes: usize,
}

/// The result of reading one file: the lossless document, the typed model (always built, as far
/// as the file allows), and every diagnostic found.
#[derive(Clone, Debug)]
pub struct Parsed {
    /// The lossless syntax tree (write it back with [`ast::Document::write_lossless`]).
    pub document: ast::Document,
    /// The typed model.
    pub model: Model,
    /// Every diagnostic kept ([`Options::keep_from`]; by default all of them), in file order.
    pub diagnostics: Vec<Diagnostic>,
    /// The diagnostics found but not kept, by severity (none unless [`Options::keep_from`] was
    /// set).
    pub not_kept: NotKept,
}

impl Parsed {
    /// Whether any diagnostic is an error.
    pub fn has_errors(&self) -> bool {
        self.diagnostics.iter().any(|d| d.severity == Severity::Error)
    }

    /// The diagnostics that are errors.
    pub fn errors(&self) -> impl Iterator<Item = &Diagnostic> {
        self.diagnostics.iter().filter(|d| d.severity == Severity::Error)
    }
}

/// Reads an EDS or DCF from bytes. `name` is used in diagnostics. Never panics.
pub fn parse(name: &str, bytes: &[u8], options: &Options) -> Parsed {
    let source = source::SourceFile::decode(name, bytes);
    // Lowering lexes the lines as it reads them; the document lexes them again only if asked.
    let document = ast::Document::new(source);
    let (model, diagnostics, not_kept) = lower::lower_counting(&document, options);
    Parsed { document, model, diagnostics, not_kept }
}

/// Reads an EDS or DCF file from disk (see [`read_bytes`] for what is refused).
pub fn read_file(path: impl AsRef<std::path::Path>, options: &Options) -> std::io::Result<Parsed> {
    let path = path.as_ref();
    let bytes = read_bytes(path)?;
    Ok(parse_owned(&path.display().to_string(), bytes, options))
}

/// [`parse`] of bytes the caller gives away (no copy of a UTF-8 file's text).
pub fn parse_owned(name: &str, bytes: Vec<u8>, options: &Options) -> Parsed {
    let source = source::SourceFile::decode_owned(name, bytes);
    let document = ast::Document::new(source);
    let (model, diagnostics, not_kept) = lower::lower_counting(&document, options);
    Parsed { document, model, diagnostics, not_kept }
}

/// Reads files one after another, each into the memory the one before it used.
///
/// A program that reads many files ([`read_file`] on each) allocates each file's buffers anew:
/// its text, its line index and the lists lowering builds, together several times the file's
/// size. In a short-lived process every allocation that is not served from memory freed before
/// touches fresh pages, each a page fault, which costs as much as reading the bytes on it. A
/// `Reader` keeps those buffers: give each file back with [`Reader::recycle`] when done with it,
/// and the next [`Reader::read_file`] reuses them. The results are those of [`read_file`]. The
/// buffers are kept while the reader lives: about seven bytes of address space per byte of the
/// largest file read (or of its room, whichever is larger), of which memory only as far as they
/// were written. [`Reader::new`] makes them with room for files of [`Reader::ROOM`] bytes from
/// the start, so that they are not replaced (by fresh memory) each time a file is larger than
/// those before it; a caller that gives the largest file first sizes them by that file
/// ([`Reader::with_room`]`(0)`).
pub struct Reader {
    /// The text of the last file given back: the next file is read into it.
    bytes: Vec<u8>,
    scratch: lower::Scratch,
}

impl Default for Reader {
    fn default() -> Self {
        Self::new()
    }
}

impl Reader {
    /// The size of file the buffers have room for from the start (a large vendor EDS; the
    /// largest of the 61 real files we test with has 142 KB).
    pub const ROOM: usize = 256 * 1024;

    /// A reader with no buffers yet, which makes them with room for files of [`Reader::ROOM`]
    /// bytes: for files in any order.
    pub fn new() -> Self {
        Self::with_room(Self::ROOM)
    }

    /// A reader with no buffers yet, which makes them with room for files of `bytes` bytes, or
    /// for the file read if it is larger. `0` sizes them by the first file read: for a caller
    /// that gives its files largest first, whose buffers are then made once and are no larger
    /// than that file needs. (Room never written costs only address space where the allocator
    /// takes fresh pages from the system as they are touched; an allocator that packs blocks
    /// densely fills its memory with it.)
    pub fn with_room(bytes: usize) -> Self {
        let mut scratch = lower::Scratch::default();
        scratch.pass1.room_for = bytes;
        Reader { bytes: Vec::new(), scratch }
    }

    /// [`read_file`], reusing the buffers of the files given back.
    pub fn read_file(&mut self, path: impl AsRef<std::path::Path>, options: &Options) -> std::io::Result<Parsed> {
        self.read_probed(&probe(path.as_ref())?, options)
    }

    /// [`Reader::read_file`] of a file [`probe`] has accepted (it is not probed again).
    pub fn read_probed(&mut self, probed: &Probed<'_>, options: &Options) -> std::io::Result<Parsed> {
        let path = probed.path;
        let bytes = read_bytes_into(probed, std::mem::take(&mut self.bytes), self.scratch.pass1.room_for)?;
        let source = source::SourceFile::decode_owned(path.display().to_string(), bytes);
        let document = ast::Document::new(source);
        let (model, diagnostics, not_kept) = lower::lower_reusing(&document, options, &mut self.scratch);
        Ok(Parsed { document, model, diagnostics, not_kept })
    }

    /// Takes a file back, for its memory to serve the next one (the model and diagnostics are
    /// dropped; the text, the line index and the model's list of objects are kept).
    pub fn recycle(&mut self, parsed: Parsed) {
        let Parsed { document, model, mut diagnostics, .. } = parsed;
        self.scratch.pool.take_back(model);
        diagnostics.clear();
        if diagnostics.capacity() > self.scratch.pass1.diags.capacity() {
            self.scratch.pass1.diags = diagnostics;
        }
        let (text, line_starts) = document.source.into_buffers();
        if text.capacity() > self.bytes.capacity() {
            self.bytes = text.into_bytes();
        }
        if let Some(starts) = line_starts
            && starts.capacity() > self.scratch.pass1.line_starts.capacity()
        {
            self.scratch.pass1.line_starts = starts;
        }
    }
}

/// The bytes of a regular file (through symbolic links). Anything else, such as a FIFO (whose
/// read would wait for a writer), a device (`/dev/urandom` never ends) or a directory, is refused
/// with an [`std::io::ErrorKind::InvalidInput`] error naming what it is, before it is opened.
pub fn read_bytes(path: &std::path::Path) -> std::io::Result<Vec<u8>> {
    read_bytes_into(&probe(path)?, Vec::new(), 0)
}

/// A path that [`probe`] found to be a regular file (through symbolic links), and its size then:
/// what [`Reader::read_probed`] reads. A program that reads many files can probe them all
/// first, to read the largest first or to spread them over threads by size, at no extra cost:
/// the file is not probed again when it is read.
#[derive(Clone, Debug)]
pub struct Probed<'a> {
    path: &'a std::path::Path,
    len: u64,
}

impl<'a> Probed<'a> {
    /// The path.
    pub fn path(&self) -> &'a std::path::Path {
        self.path
    }

    /// The file's size in bytes when it was probed.
    pub fn len(&self) -> u64 {
        self.len
    }

    /// Whether the file was empty when it was probed.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
}

/// Checks, without opening it, that `path` is a regular file (through symbolic links), and
/// gives its size. A FIFO (whose opening or reading would wait for a writer), a device
/// (`/dev/urandom` never ends; opening some devices has effects of its own), a socket or a
/// directory is refused with an [`std::io::ErrorKind::InvalidInput`] error naming what it is.
pub fn probe(path: &std::path::Path) -> std::io::Result<Probed<'_>> {
    probe_with(path, &std::fs::metadata(path)?)
}

/// [`probe`] of a path whose metadata the caller has already asked for (`std::fs::metadata`,
/// which follows symbolic links): no second system call for it. A program that must know
/// whether each path it is given is a folder asks once, and probes the files with the answer.
/// (Metadata of the link itself, from `std::fs::symlink_metadata`, is refused as not a regular
/// file.)
pub fn probe_with<'a>(path: &'a std::path::Path, metadata: &std::fs::Metadata) -> std::io::Result<Probed<'a>> {
    if !metadata.is_file() {
        return Err(not_regular(metadata));
    }
    Ok(Probed { path, len: metadata.len() })
}

/// The error for a path that is not a regular file.
fn not_regular(m: &std::fs::Metadata) -> std::io::Error {
    let what = if m.is_dir() { "a directory" } else { "not a regular file (a FIFO, device or socket)" };
    std::io::Error::new(std::io::ErrorKind::InvalidInput, format!("it is {what}"))
}

/// Opens `path` for reading without waiting: had the path become a FIFO since it was probed,
/// a plain open would wait for a writer, for ever. With `O_NONBLOCK` (on Linux, where its value
/// is known for each architecture) the open returns at once, and the check on the open file
/// refuses it; a regular file reads the same either way.
fn open_without_waiting(path: &std::path::Path) -> std::io::Result<std::fs::File> {
    // (`libc::O_NONBLOCK`, by architecture; where it is not known here, opened as before.)
    const O_NONBLOCK: Option<i32> = if !cfg!(target_os = "linux") {
        None
    } else if cfg!(any(target_arch = "mips", target_arch = "mips64")) {
        Some(0x80)
    } else if cfg!(any(target_arch = "sparc", target_arch = "sparc64")) {
        Some(0x4000)
    } else if cfg!(any(
        target_arch = "x86",
        target_arch = "x86_64",
        target_arch = "arm",
        target_arch = "aarch64",
        target_arch = "riscv32",
        target_arch = "riscv64",
        target_arch = "powerpc",
        target_arch = "powerpc64",
        target_arch = "s390x",
        target_arch = "loongarch64"
    )) {
        Some(0o4000)
    } else {
        None
    };
    let mut options = std::fs::OpenOptions::new();
    options.read(true);
    #[cfg(unix)]
    if let Some(flag) = O_NONBLOCK {
        use std::os::unix::fs::OpenOptionsExt as _;
        options.custom_flags(flag);
    }
    options.open(path)
}

/// The bytes of a probed file, read into `bytes`, whose allocation is used if large enough; a
/// new one has room for at least `room` bytes.
///
/// A regular file is read with one `read` (the size is known from the open file), so that
/// each file costs four system calls: `openat`, `statx`, `read` and `close` (the probe, before,
/// is the caller's). A file whose size is given as 0, as files of `/proc` are, is read to its
/// end as it comes.
/// The largest file [`read_file`] and [`Reader`] read (4 GiB less a byte): positions in a text
/// are `u32` ([`source::Span`]); a larger file is refused before it is read.
pub const MAX_FILE: u64 = u32::MAX as u64;

fn read_bytes_into(probed: &Probed<'_>, bytes: Vec<u8>, room: usize) -> std::io::Result<Vec<u8>> {
    let mut file = open_without_waiting(probed.path)?;
    // (Checked again on the open file, in case the path changed since it was probed.)
    let m = file.metadata()?;
    if !m.is_file() {
        return Err(not_regular(&m));
    }
    if m.len() > MAX_FILE {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!(
                "the file is {} bytes; positions in a description are 32-bit, so at most {MAX_FILE} are read",
                m.len()
            ),
        ));
    }
    let len = usize::try_from(m.len()).unwrap_or(0);
    let need = len.max(room).saturating_add(1);
    // (A buffer too small is replaced, not grown: growing would copy bytes that mean nothing.
    // A new one is asked for zeroed, and is all initialised for `read_up_to`: memory fresh from
    // the system is zero already, and the allocator need not write it.)
    let bytes = if bytes.capacity() < need { vec![0; need] } else { bytes };
    read_up_to(&mut file, bytes, len)
}

/// Reads `r` into `bytes` (whose contents are replaced): `len` bytes, or fewer if it ends
/// before, or, when `len` is 0, everything to its end.
///
/// Safe code reads only into initialised bytes, so the buffer is zeroed as far as it is read
/// into; but `bytes` keeps its length from the last file (the bytes of the text that was in it
/// are initialised already), and only the part beyond it is zeroed. A `Reader` thus zeroes, over
/// a whole run, about the size of its largest file: less than the system calls it saves cost.
/// (`Read::read_to_end`, which reads into the buffer's room without zeroing it, reads in steps
/// of 8, 16, 32 KiB... when it is not told the size, as through `Read::take`: three `read`s for
/// a 44 KB file; `File::read_to_end` asks the size and position again, a `statx` and an `lseek`,
/// and reads once more to find the end.)
///
/// A file that grows after its size was taken is read as it was then (`len` bytes; a file
/// growing without end cannot keep the reader reading); one that shrinks is read to its new
/// end. A file of size 0 grows the buffer as it is read, doubling from 8 KiB.
fn read_up_to(r: &mut impl std::io::Read, mut bytes: Vec<u8>, len: usize) -> std::io::Result<Vec<u8>> {
    let to_end = len == 0;
    let start = if to_end { bytes.len().max(8 * 1024) } else { len };
    bytes.resize(start, 0);
    let mut filled = 0;
    loop {
        if filled == bytes.len() {
            if !to_end {
                break;
            }
            let more = bytes.len().max(8 * 1024);
            bytes.resize(bytes.len().saturating_add(more), 0);
        }
        match r.read(&mut bytes[filled..]) {
            Ok(0) => break,
            Ok(n) => filled += n,
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    bytes.truncate(filled);
    Ok(bytes)
}

/// A small pseudo-random sequence for the tests of this crate (xorshift64): each call gives a
/// number below its argument (0 for an argument of 0), the same sequence for the same seed.
#[cfg(test)]
pub(crate) fn test_rng(mut seed: u64) -> impl FnMut(u64) -> u64 {
    move |n| {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        seed % n.max(1)
    }
}

#[cfg(test)]
mod tests {
    use super::read_up_to;

    /// A reader over `data` that hands out at most `step` bytes a call, counts its calls, and
    /// is interrupted (`ErrorKind::Interrupted`) before every `interrupt`-th one.
    struct Chunks {
        data: Vec<u8>,
        at: usize,
        step: usize,
        calls: usize,
        interrupt: usize,
    }

    impl Chunks {
        fn new(data: Vec<u8>, step: usize) -> Self {
            Chunks { data, at: 0, step, calls: 0, interrupt: 0 }
        }
    }

    impl std::io::Read for Chunks {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            self.calls += 1;
            if self.interrupt > 0 && self.calls.is_multiple_of(self.interrupt) {
                return Err(std::io::ErrorKind::Interrupted.into());
            }
            let n = buf.len().min(self.step).min(self.data.len() - self.at);
            buf[..n].copy_from_slice(&self.data[self.at..self.at + n]);
            self.at += n;
            Ok(n)
        }
    }

    fn data(n: usize, seed: u8) -> Vec<u8> {
        (0..n).map(|i| (i as u8).wrapping_mul(31).wrapping_add(seed) | 1).collect()
    }

    /// A file that gives its whole size in one `read` is read with exactly one call (no call
    /// to find the end), into a buffer whatever it held before.
    #[test]
    fn a_file_of_known_size_is_read_with_one_call() {
        for n in [1usize, 7, 4096, 44_000, 142_040] {
            for old in [Vec::new(), vec![0xAA; n / 2], vec![0xBB; n + 100], Vec::with_capacity(n + 1)] {
                let mut r = Chunks::new(data(n, 3), usize::MAX);
                let got = read_up_to(&mut r, old, n).expect("read");
                assert_eq!(got, data(n, 3), "n {n}");
                assert_eq!(r.calls, 1, "n {n}");
            }
        }
    }

    /// Whatever the pieces the bytes come in, however often a call is interrupted, and whether
    /// the file is as long as its size said, longer (it grew: read as it was) or shorter (it
    /// shrank: read to its end), the bytes read are the file's first `len` bytes, or all of a
    /// file of size 0; and no stale byte of the buffer's last contents is left in them.
    #[test]
    fn every_way_of_delivering_gives_the_same_bytes() {
        let mut rng = crate::test_rng(0x9E37_79B9_7F4A_7C15);
        let mut next = move |m: usize| rng(m as u64) as usize;
        for _ in 0..400 {
            let actual = next(40_000);
            let len = match next(4) {
                0 => actual,
                1 => actual + 1 + next(5000),
                2 => actual.saturating_sub(1 + next(5000)),
                _ => 0,
            };
            let step = 1 + next(20_000);
            // (Every call but one interrupted at most: a reader interrupted for ever never ends.)
            let interrupt = [0, 2, 3, 7][next(4)];
            let old = vec![0xEEu8; next(50_000)];
            let mut r = Chunks::new(data(actual, 9), step);
            r.interrupt = interrupt;
            let got = read_up_to(&mut r, old, len).expect("read");
            let want = if len == 0 { actual } else { len.min(actual) };
            assert_eq!(got, data(want, 9), "actual {actual} len {len} step {step}");
        }
    }

    /// An error other than an interruption is given back.
    #[test]
    fn read_errors_are_given_back() {
        struct Failing;
        impl std::io::Read for Failing {
            fn read(&mut self, _: &mut [u8]) -> std::io::Result<usize> {
                Err(std::io::Error::other("disk on fire"))
            }
        }
        for len in [0usize, 10] {
            let e = read_up_to(&mut Failing, Vec::new(), len).expect_err("an error");
            assert_eq!(e.to_string(), "disk on fire");
        }
    }
}
