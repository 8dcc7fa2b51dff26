//! A deterministic mutation test: thousands of mutants of real files (the corpus in
//! `$EDS_CORPUS_DIR`, default `../shared/eds-corpus` beside the repository, plus our device files
//! and the eds fixtures), made with a fixed seed, each read in both modes. For every mutant:
//! no panic; every rendered diagnostic is a few lines of bounded width; the JSON of every
//! diagnostic is valid; and when the file has no errors and nothing `eds::write::unrepresentable`
//! lists, its canonical text reads back as the same model without errors, with no more
//! warnings, and is a fixed point (`fmt` is idempotent). One mutant in
//! `BINARY_EVERY` also goes through the `odgen` binary under a 1 GiB address-space limit and a
//! time limit: `check --strict --format json` gives valid JSON, `fmt` then `fmt --check` agree.
//!
//! `MUTANTS=N` and `MUTATION_SEED=S` change the count (default 2000) and the seed; a failure
//! names the mutant's seed, input and mutation, so it can be made again.

use std::path::{Path, PathBuf};
use std::process::Stdio;

use crate::common;
use std::time::{Duration, Instant};

use eds::{Options, Severity};

const BINARY_EVERY: usize = 25;

/// xorshift64*: small, fast and the same everywhere.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }

    fn below(&mut self, n: usize) -> usize {
        if n == 0 { 0 } else { (self.next() % n as u64) as usize }
    }
}

fn inputs() -> Vec<(String, Vec<u8>)> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let corpus =
        std::env::var_os("EDS_CORPUS_DIR").map(PathBuf::from).unwrap_or_else(|| root.join("../shared/eds-corpus"));
    let mut dirs = vec![root.join("devices"), root.join("eds/tests/fixtures"), root.join("eds/tests/fixtures/diag")];
    dirs.push(corpus);
    let mut out = Vec::new();
    for dir in dirs {
        let Ok(entries) = std::fs::read_dir(&dir) else { continue };
        let mut paths: Vec<PathBuf> = entries
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| {
                p.extension()
                    .and_then(|e| e.to_str())
                    .is_some_and(|e| e.eq_ignore_ascii_case("eds") || e.eq_ignore_ascii_case("dcf"))
            })
            .collect();
        paths.sort();
        for p in paths {
            out.push((p.file_name().unwrap().to_string_lossy().into_owned(), std::fs::read(&p).unwrap()));
        }
    }
    out
}

/// Text a mutation inserts: the bytes that shape lines and values, and lines that make a
/// reader work hard.
const PIECES: &[&str] = &[
    "[",
    "]",
    "=",
    ";",
    "#",
    "\r",
    "\n",
    "\r\n",
    "\t",
    " ",
    "$NODEID",
    "$NODEID+",
    "0x",
    "-",
    "sub",
    "\u{FEFF}",
    "\u{e9}",
    "\0",
    "\x7f",
    "\n[1018]\n",
    "\n[1A00sub40]\n",
    "\nCompactSubObj=255\n",
    "\nSubNumber=0xFF\n",
    "\nObjectType=0x8\n",
    "\nObjectType=0x9\n",
    "\nDataType=0x0009\n",
    "\nDataType=0x000A\n",
    "\nDataType=0x0008\n",
    "\nDefaultValue=$NODEID+0x123456789012345678901234567890\n",
    "\nDefaultValue=-0x8000000000000000\n",
    "\nPDOMapping=1\n",
    "\nAccessType=const\n",
    "\n[FileInfo]\n",
    "\n[DeviceInfo]\n",
    "\n[DeviceComissioning]\nNodeID=5\n",
    "\n[Foo]\nKey=1\n",
    "\n[1600Name]\nNrOfEntries=1\n1=x\n",
    "\nNrOfRXPDO=512\n",
    "\n1=0x1000\n",
    "\nSupportedObjects=65535\n",
];

/// One mutant of `input`, and what was done (for the failure message).
fn mutate(input: &[u8], rng: &mut Rng) -> (Vec<u8>, String) {
    let mut b = input.to_vec();
    let rounds = 1 + rng.below(4);
    let mut what = Vec::new();
    for _ in 0..rounds {
        let at = rng.below(b.len() + 1);
        match rng.below(10) {
            0 => {
                if at < b.len() {
                    b[at] = rng.next() as u8;
                }
                what.push(format!("byte {at} changed"));
            }
            1 => {
                let n = (1 + rng.below(64)).min(b.len() - at.min(b.len()));
                b.drain(at..at + n);
                what.push(format!("{n} bytes deleted at {at}"));
            }
            2 | 3 => {
                let piece = PIECES[rng.below(PIECES.len())];
                let piece = if rng.below(8) == 0 { piece.repeat(1 + rng.below(200)) } else { piece.to_owned() };
                what.push(format!("{piece:?} inserted at {at}"));
                b.splice(at..at, piece.into_bytes());
            }
            4 => {
                // A run of lines copied elsewhere (duplicate sections and keys).
                let from = rng.below(b.len() + 1);
                let len = rng.below(2000).min(b.len() - from);
                let copy = b[from..from + len].to_vec();
                b.splice(at..at, copy);
                what.push(format!("{len} bytes from {from} copied to {at}"));
            }
            5 => {
                b.truncate(at);
                what.push(format!("truncated at {at}"));
            }
            6 => {
                let from: &[u8] = [&b"\n"[..], b"\r\n", b"\r"][rng.below(3)];
                let to: &[u8] = [&b"\n"[..], b"\r\n", b"\r"][rng.below(3)];
                let text = String::from_utf8_lossy(&b)
                    .replace(std::str::from_utf8(from).unwrap_or("\n"), std::str::from_utf8(to).unwrap_or("\n"));
                b = text.into_bytes();
                what.push(format!("line ends {from:?} -> {to:?}"));
            }
            7 => {
                // Encoded as UTF-16 (either order) with its mark.
                let text = String::from_utf8_lossy(&b).into_owned();
                let little = rng.below(2) == 0;
                let mut out = if little { vec![0xFF, 0xFE] } else { vec![0xFE, 0xFF] };
                for u in text.encode_utf16() {
                    out.extend(if little { u.to_le_bytes() } else { u.to_be_bytes() });
                }
                b = out;
                what.push(format!("UTF-16 {}", if little { "LE" } else { "BE" }));
            }
            8 => {
                let n = 1 + rng.below(8);
                let bytes: Vec<u8> = (0..n).map(|_| rng.next() as u8).collect();
                what.push(format!("{n} random bytes at {at}"));
                b.splice(at..at, bytes);
            }
            _ => {
                // Two lines swapped.
                let text = String::from_utf8_lossy(&b).into_owned();
                let mut lines: Vec<&str> = text.split('\n').collect();
                if lines.len() > 2 {
                    let (i, j) = (rng.below(lines.len()), rng.below(lines.len()));
                    lines.swap(i, j);
                    what.push(format!("lines {i} and {j} swapped"));
                }
                b = lines.join("\n").into_bytes();
            }
        }
    }
    (b, what.join(", "))
}

/// The checks made in the process for one mutant.
fn check_in_process(name: &str, bytes: &[u8]) -> Result<(), String> {
    for options in [Options::lenient(), Options::strict()] {
        let parsed = eds::parse(name, bytes, &options);
        for d in &parsed.diagnostics {
            let text = eds::diag::render(d, &parsed.document.source);
            let widest = text.lines().map(|l| l.chars().count()).max().unwrap_or(0);
            if widest > eds::diag::MAX_QUOTED as usize + 400 {
                return Err(format!("a rendered diagnostic has a line of {widest} characters:\n{text}"));
            }
            let mut json = String::new();
            eds::diag::push_json(&mut json, d);
            // Validated, not built into a tree: `IgnoredAny` walks the whole document with the
            // same parser (a third of this test's time went to building `Value`s).
            serde_json::from_str::<serde::de::IgnoredAny>(&json).map_err(|e| format!("invalid JSON ({e}): {json}"))?;
        }
        // (What `unrepresentable` lists cannot survive a write, by the writer's contract: fmt
        // refuses such a file, which the binary check below holds it to.)
        if options.strictness == eds::Strictness::Lenient
            && !parsed.has_errors()
            && eds::write::unrepresentable(&parsed.model).is_empty()
        {
            let text = eds::write::write(&parsed.model);
            let back = eds::parse(name, text.as_bytes(), &options);
            if back.model != parsed.model {
                return Err("the canonical text reads back as another model".into());
            }
            if let Some(e) = back.errors().next() {
                return Err(format!("the canonical text has an error: {}", e.message));
            }
            let again = eds::write::write(&back.model);
            if again != text {
                return Err("the canonical text is not a fixed point (fmt is not idempotent)".into());
            }
            let worse = |p: &eds::Parsed| p.diagnostics.iter().filter(|d| d.severity >= Severity::Warning).count();
            if worse(&back) > worse(&parsed) {
                return Err(format!("the canonical text has more warnings ({} > {})", worse(&back), worse(&parsed)));
            }
        }
    }
    Ok(())
}

/// Runs odgen under a 1 GiB address-space limit (`ulimit -v`) and a 60 s bound.
fn odgen_limited(args: &[&str]) -> std::process::Output {
    let mut child = common::odgen_under_limit(1 << 20)
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run odgen");
    // Read the pipes while waiting, so that a large output cannot block the child.
    let mut stdout = child.stdout.take().unwrap();
    let mut stderr = child.stderr.take().unwrap();
    let out = std::thread::spawn(move || {
        let mut v = Vec::new();
        std::io::Read::read_to_end(&mut stdout, &mut v).map(|_| v).unwrap_or_default()
    });
    let err = std::thread::spawn(move || {
        let mut v = Vec::new();
        std::io::Read::read_to_end(&mut stderr, &mut v).map(|_| v).unwrap_or_default()
    });
    let start = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().expect("wait") {
            break s;
        }
        if start.elapsed() > Duration::from_secs(60) {
            let _ = child.kill();
            let _ = child.wait();
            panic!("odgen {args:?} did not finish in 60 s");
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    std::process::Output { status, stdout: out.join().unwrap(), stderr: err.join().unwrap() }
}

fn check_binary(dir: &Path, bytes: &[u8]) -> Result<(), String> {
    let path = dir.join("mutant.eds");
    std::fs::write(&path, bytes).unwrap();
    let p = path.to_str().unwrap();
    let o = odgen_limited(&["check", "--strict", "--format", "json", p]);
    let err = String::from_utf8_lossy(&o.stderr);
    if !matches!(o.status.code(), Some(0 | 1)) || err.contains("panicked") {
        return Err(format!("check exited with {:?}: {err}", o.status));
    }
    serde_json::from_slice::<serde::de::IgnoredAny>(&o.stdout)
        .map_err(|e| format!("check printed invalid JSON: {e}"))?;
    let o = odgen_limited(&["fmt", p]);
    if !matches!(o.status.code(), Some(0 | 2)) || String::from_utf8_lossy(&o.stderr).contains("panicked") {
        return Err(format!("fmt exited with {:?}: {}", o.status, String::from_utf8_lossy(&o.stderr)));
    }
    if o.status.success() {
        let o = odgen_limited(&["fmt", "--check", p]);
        if !o.status.success() {
            return Err(format!("fmt output is not canonical: {}", String::from_utf8_lossy(&o.stdout)));
        }
    }
    Ok(())
}

#[test]
fn mutants_of_real_files() {
    let inputs = inputs();
    assert!(inputs.len() >= 10, "too few inputs: {}", inputs.len());
    let count: usize = std::env::var("MUTANTS").ok().and_then(|n| n.parse().ok()).unwrap_or(2000);
    let seed: u64 = std::env::var("MUTATION_SEED").ok().and_then(|n| n.parse().ok()).unwrap_or(0x0DDB_A11C_AFE5_EED5);
    let dir = std::env::temp_dir().join(format!("odgen-mutation-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut failures = Vec::new();
    for i in 0..count {
        let mutant_seed = seed ^ (i as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
        let mut rng = Rng(mutant_seed);
        let (name, input) = &inputs[rng.below(inputs.len())];
        let (bytes, what) = mutate(input, &mut rng);
        let mut result = check_in_process(name, &bytes);
        if result.is_ok() && i % BINARY_EVERY == 0 {
            result = check_binary(&dir, &bytes);
        }
        if let Err(e) = result {
            if let Some(d) = std::env::var_os("MUTATION_DUMP") {
                let _ = std::fs::write(PathBuf::from(d).join(format!("mutant-{i}.eds")), &bytes);
            }
            failures.push(format!("mutant {i} (seed {mutant_seed:#x}) of {name} ({what}): {e}"));
            if failures.len() >= 10 {
                break;
            }
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
    assert!(failures.is_empty(), "{} failure(s):\n{}", failures.len(), failures.join("\n\n"));
}
