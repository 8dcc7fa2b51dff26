//! `eds::Reader` (files read one after another into the memory of the ones before) gives what
//! `eds::read_file` gives, whatever the files and their order: large after small, small after
//! large, duplicate sections (whose entries are regrouped), other encodings (decoded into new
//! text), and the real corpus when it is at hand.

use std::path::{Path, PathBuf};

use eds::{Options, Parsed};

fn files_in(dir: &Path) -> Vec<PathBuf> {
    let Ok(entries) = std::fs::read_dir(dir) else { return Vec::new() };
    let mut files: Vec<PathBuf> = entries
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| {
            p.extension()
                .and_then(|e| e.to_str())
                .is_some_and(|e| e.eq_ignore_ascii_case("eds") || e.eq_ignore_ascii_case("dcf"))
        })
        .collect();
    files.sort();
    files
}

/// The fixtures of every diagnostic code and feature, and the corpus if there is one.
fn inputs() -> Vec<PathBuf> {
    let here = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut files = files_in(&here.join("tests/fixtures"));
    files.extend(files_in(&here.join("tests/fixtures/diag")));
    files.extend(files_in(&here.join("tests/fixtures/features")));
    let corpus =
        std::env::var_os("EDS_CORPUS_DIR").map(PathBuf::from).unwrap_or_else(|| here.join("../../shared/eds-corpus"));
    files.extend(files_in(&corpus));
    assert!(files.len() > 50, "too few inputs: {}", files.len());
    files
}

/// Everything a caller can see of a read file, diagnostics rendered with their source lines.
fn seen(p: &Parsed) -> (String, eds::Model, Vec<eds::Diagnostic>, Vec<String>) {
    let rendered = p.diagnostics.iter().map(|d| eds::diag::render(d, &p.document.source)).collect();
    (p.document.source.text.clone(), p.model.clone(), p.diagnostics.clone(), rendered)
}

/// Files denser than the reader's estimates of lines, entries and sections per byte (which
/// size its buffers before a file is read): the buffers grow while such a file is read.
fn dense_files(dir: &Path) -> Vec<PathBuf> {
    let mut sections = String::new();
    for i in 0..3000u32 {
        // A section every 12 bytes or so, each with one short entry.
        sections.push_str(&format!("[{:X}]\nA=1\n", 0x2000 + i));
    }
    let mut lines = String::from("[DeviceInfo]\n");
    for i in 0..20000u32 {
        // A line every 4 to 6 bytes, and lines ended by a lone CR as well.
        lines.push_str(&format!("K{}={}", i % 100, if i % 3 == 0 { "\r" } else { "\n" }));
    }
    let mut paths = Vec::new();
    for (name, text) in [("sections.eds", sections), ("lines.eds", lines)] {
        let path = dir.join(name);
        std::fs::write(&path, text).expect("write");
        paths.push(path);
    }
    paths
}

#[test]
fn a_reader_reads_every_file_as_read_file_does_in_any_order() {
    let dir = std::env::temp_dir().join(format!("eds-reader-dense-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let mut files = inputs();
    files.extend(dense_files(&dir));
    let mut orders = vec![files.clone(), files.iter().rev().cloned().collect::<Vec<_>>()];
    // Largest first, then smallest first: buffers that are too large, then too small.
    let mut by_size = files.clone();
    by_size.sort_by_key(|p| std::cmp::Reverse(std::fs::metadata(p).map_or(0, |m| m.len())));
    orders.push(by_size.clone());
    orders.push(by_size.into_iter().rev().collect());
    for options in [Options::lenient(), Options::strict()] {
        let expected: Vec<_> = files.iter().map(|p| seen(&eds::read_file(p, &options).expect("readable"))).collect();
        // Readers with room for large files from the start, sized by the first file read, and
        // with room for small files only.
        for (order, room) in orders.iter().flat_map(|o| [(o, None), (o, Some(0)), (o, Some(4096))]) {
            let mut reader = room.map_or_else(eds::Reader::new, eds::Reader::with_room);
            for (i, path) in order.iter().enumerate() {
                let parsed = reader.read_file(path, &options).expect("readable");
                let at = files.iter().position(|f| f == path).expect("listed");
                assert!(seen(&parsed) == expected[at], "{} differs when read by a reader", path.display());
                // Every other file is dropped rather than given back: a reader works either way.
                if i % 2 == 0 {
                    reader.recycle(parsed);
                }
            }
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_reader_reports_unreadable_files_and_goes_on() {
    let mut reader = eds::Reader::new();
    let good = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/base.eds");
    let first = reader.read_file(&good, &Options::lenient()).expect("readable");
    reader.recycle(first);
    assert!(reader.read_file("/nonexistent/x.eds", &Options::lenient()).is_err());
    assert!(reader.read_file(Path::new(env!("CARGO_MANIFEST_DIR")), &Options::lenient()).is_err());
    let again = reader.read_file(&good, &Options::lenient()).expect("readable");
    assert!(seen(&again) == seen(&eds::read_file(&good, &Options::lenient()).expect("readable")));
}

/// `probe` gives a regular file's size and refuses anything else without opening it; a probed
/// file reads as `read_file` reads it, whole, with its size known from the probe.
#[test]
fn probed_files_read_as_read_file_does() {
    let files = inputs();
    let mut reader = eds::Reader::new();
    for path in &files {
        let probed = eds::probe(path).expect("a regular file");
        assert_eq!(probed.len(), std::fs::metadata(path).expect("metadata").len());
        assert_eq!(probed.path(), path.as_path());
        let parsed = reader.read_probed(&probed, &Options::lenient()).expect("readable");
        assert!(seen(&parsed) == seen(&eds::read_file(path, &Options::lenient()).expect("readable")));
        reader.recycle(parsed);
    }
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let e = eds::probe(dir).expect_err("a directory");
    assert_eq!(e.kind(), std::io::ErrorKind::InvalidInput);
    assert!(e.to_string().contains("directory"), "{e}");
    assert_eq!(eds::probe(Path::new("/nonexistent/x.eds")).expect_err("absent").kind(), std::io::ErrorKind::NotFound);
    if Path::new("/dev/null").exists() {
        let e = eds::probe(Path::new("/dev/null")).expect_err("a device");
        assert_eq!(e.kind(), std::io::ErrorKind::InvalidInput);
    }
}

/// A regular file whose size is given as 0 but that has text (as the files of `/proc` have) is
/// read to its end, not as empty; an empty file is read as empty.
#[test]
fn files_of_size_zero_are_read_to_their_end() {
    let proc_file = Path::new("/proc/self/status");
    if std::fs::metadata(proc_file).is_ok_and(|m| m.is_file() && m.len() == 0) {
        let bytes = eds::read_bytes(proc_file).expect("readable");
        assert!(bytes.len() > 20, "{} bytes", bytes.len());
    }
    let dir = std::env::temp_dir().join(format!("eds-reader-empty-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let empty = dir.join("empty.eds");
    std::fs::write(&empty, "").expect("write");
    assert!(eds::read_bytes(&empty).expect("readable").is_empty());
    let mut reader = eds::Reader::new();
    let parsed = reader.read_file(&empty, &Options::lenient()).expect("readable");
    assert!(parsed.document.source.text.is_empty());
    let _ = std::fs::remove_dir_all(&dir);
}

/// `Options::keep_from` keeps exactly the diagnostics at least that severe, in the same order
/// and with the same text, and counts the others by severity: on every fixture and corpus file,
/// lenient and strict, read alone and through a `Reader`.
#[test]
fn keep_from_keeps_the_severe_diagnostics_and_counts_the_rest() {
    use eds::Severity;
    let files = inputs();
    let mut dropped_somewhere = [0usize; 2];
    for base in [Options::lenient(), Options::strict()] {
        let mut reader = eds::Reader::new();
        for path in &files {
            let all = eds::read_file(path, &base).expect("readable");
            assert_eq!(all.not_kept, eds::NotKept::default(), "{}", path.display());
            for least in [Severity::Warning, Severity::Error] {
                let options = base.clone().keep_from(least);
                assert_eq!(options.least_kept(), least);
                let expected: Vec<_> = all.diagnostics.iter().filter(|d| d.severity >= least).cloned().collect();
                let count = |s: Severity| all.diagnostics.iter().filter(|d| d.severity == s).count();
                let not_kept = eds::NotKept {
                    warnings: if least > Severity::Warning { count(Severity::Warning) } else { 0 },
                    notes: count(Severity::Note),
                };
                for some in [eds::read_file(path, &options).expect("readable"), {
                    let p = reader.read_file(path, &options).expect("readable");
                    let copy = eds::Parsed {
                        document: p.document.clone(),
                        model: p.model.clone(),
                        diagnostics: p.diagnostics.clone(),
                        not_kept: p.not_kept,
                    };
                    reader.recycle(p);
                    copy
                }] {
                    assert!(some.diagnostics == expected, "{} keeping from {least:?}", path.display());
                    assert_eq!(some.not_kept, not_kept, "{} keeping from {least:?}", path.display());
                    assert!(some.model == all.model, "{}: the model does not depend on what is kept", path.display());
                }
                dropped_somewhere[0] += not_kept.warnings;
                dropped_somewhere[1] += not_kept.notes;
            }
        }
    }
    assert!(dropped_somewhere[0] > 0 && dropped_somewhere[1] > 0, "{dropped_somewhere:?}");
}

/// A path that was a regular file when probed and is a FIFO when read (it was replaced in
/// between) is refused at once: the open does not wait for a writer that never comes.
#[cfg(target_os = "linux")]
#[test]
fn a_file_replaced_by_a_fifo_after_its_probe_is_refused_without_waiting() {
    let dir = std::env::temp_dir().join(format!("eds-reader-fifo-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    // (Leaked so that the probe, which borrows it, can go to a thread that may never end.)
    let path: &'static Path = Box::leak(dir.join("swapped.eds").into_boxed_path());
    std::fs::write(path, "[FileInfo]\nFileName=x.eds\n").expect("write");
    let probed = eds::probe(path).expect("a regular file");
    std::fs::remove_file(path).expect("remove");
    let made = std::process::Command::new("mkfifo").arg(path).status().is_ok_and(|s| s.success());
    if !made {
        eprintln!("no mkfifo here: skipped");
        return;
    }
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let _ = tx.send(eds::Reader::new().read_probed(&probed, &Options::lenient()).map(|_| ()));
    });
    let result = rx.recv_timeout(std::time::Duration::from_secs(20));
    if result.is_err() {
        // Release the waiting reader before failing.
        let _ = std::fs::OpenOptions::new().write(true).open(path);
    }
    let _ = std::fs::remove_dir_all(&dir);
    let result = result.expect("the read should return at once, not wait for a writer");
    let e = result.expect_err("a FIFO is refused");
    assert_eq!(e.kind(), std::io::ErrorKind::InvalidInput, "{e}");
}

/// A reader reads each file's bytes exactly, whatever the sizes before it: larger (the buffer
/// it reads into still holds their bytes, which must not show through), smaller, of size 0,
/// larger than `Reader::ROOM` (a new buffer), and of one byte.
#[test]
fn a_reader_reads_every_byte_whatever_the_sizes_before() {
    let dir = std::env::temp_dir().join(format!("eds-reader-sizes-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let sizes = [0usize, 1, 100_000, 5, eds::Reader::ROOM + 30_000, 17, 270_000, 0, 8191, 8192, 8193, 64, 44_000];
    let files: Vec<(PathBuf, String)> = sizes
        .iter()
        .enumerate()
        .map(|(i, &n)| {
            // Each file's own bytes (printable ASCII, a line end now and then).
            let text: String = (0..n)
                .map(|k| if k % 61 == 60 { '\n' } else { char::from(b'!' + ((k * 7 + i * 13) % 90) as u8) })
                .collect();
            let path = dir.join(format!("f{i}.eds"));
            std::fs::write(&path, &text).expect("write");
            (path, text)
        })
        .collect();
    let orders: [Vec<usize>; 3] =
        [(0..files.len()).collect(), (0..files.len()).rev().collect(), vec![4, 3, 6, 1, 2, 7, 0, 5, 12, 8, 11, 10, 9]];
    for order in &orders {
        let mut reader = eds::Reader::new();
        for &i in order {
            let (path, text) = &files[i];
            let parsed = reader.read_file(path, &Options::lenient()).expect("readable");
            assert!(parsed.document.source.text == *text, "{} ({} bytes) read wrong", path.display(), text.len());
            reader.recycle(parsed);
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// `probe_with` judges a path by metadata the caller has already asked for, as `probe` does
/// by asking: a file's size, a directory and a device refused with the same errors, and the
/// metadata of a symbolic link itself refused (`probe` follows links).
#[test]
fn probe_with_metadata_judges_as_probe_does() {
    let here = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut paths = vec![here.join("tests/fixtures/base.eds"), here.to_path_buf()];
    if Path::new("/dev/null").exists() {
        paths.push(PathBuf::from("/dev/null"));
    }
    for path in &paths {
        let by_asking = eds::probe(path).map(|p| p.len()).map_err(|e| (e.kind(), e.to_string()));
        let m = std::fs::metadata(path).expect("metadata");
        let with = eds::probe_with(path, &m).map(|p| p.len()).map_err(|e| (e.kind(), e.to_string()));
        assert_eq!(by_asking, with, "{}", path.display());
    }
    #[cfg(unix)]
    {
        let dir = std::env::temp_dir().join(format!("eds-reader-link-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        let link = dir.join("link.eds");
        let _ = std::fs::remove_file(&link);
        std::os::unix::fs::symlink(here.join("tests/fixtures/base.eds"), &link).expect("symlink");
        let own = std::fs::symlink_metadata(&link).expect("metadata");
        assert_eq!(eds::probe_with(&link, &own).expect_err("a link").kind(), std::io::ErrorKind::InvalidInput);
        let followed = std::fs::metadata(&link).expect("metadata");
        assert!(eds::probe_with(&link, &followed).is_ok());
        let _ = std::fs::remove_dir_all(&dir);
    }
}
