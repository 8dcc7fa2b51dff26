//! `odgen` against inputs and targets that are not what a command expects: symbolic links,
//! files of other modes and owners, devices, FIFOs, lines the reader ignored. Each test runs the
//! binary as a user would.

use std::os::unix::fs::{MetadataExt as _, PermissionsExt as _};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

fn odgen(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_odgen")).args(args).output().expect("run odgen")
}

/// Runs odgen with a limit: a command that blocks (on a FIFO, say) is killed and reported.
fn odgen_bounded(args: &[&str]) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_odgen"))
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run odgen");
    let start = Instant::now();
    while child.try_wait().expect("wait").is_none() {
        if start.elapsed() > Duration::from_secs(60) {
            let _ = child.kill();
            let _ = child.wait();
            panic!("odgen {args:?} did not finish in 60 s");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.wait_with_output().expect("output")
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// The conformant fixture of the eds crate (not in canonical form: it has comments).
fn base() -> String {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../eds/tests/fixtures/base.eds");
    std::fs::read_to_string(p).expect("base.eds")
}

struct TempDir(PathBuf);

impl TempDir {
    fn new(name: &str) -> Self {
        let p = std::env::temp_dir().join(format!("odgen-hostile-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&p);
        std::fs::create_dir_all(&p).unwrap();
        TempDir(p)
    }

    fn file(&self, name: &str, text: &str) -> PathBuf {
        let p = self.0.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    fn path(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        // (Read-only files inside do not stop the directory's removal.)
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn mkfifo(p: &Path) {
    let ok = Command::new("mkfifo").arg(p).status().expect("mkfifo").success();
    assert!(ok, "mkfifo {}", p.display());
}

/// The commands that replace a file, as (arguments, the file written).
fn writers(eds: &Path, target: &Path) -> Vec<Vec<String>> {
    let (e, t) = (s(eds).to_owned(), s(target).to_owned());
    vec![vec!["fmt".into(), t.clone()], vec!["dcf".into(), "--node-id".into(), "5".into(), e, "-o".into(), t]]
}

/// Writing through a symbolic link writes its target; the link stays a link (and a link to a
/// file that does not exist yet creates the file there).
#[test]
fn writes_go_through_symbolic_links() {
    let dir = TempDir::new("symlink");
    let eds = dir.file("device.eds", &base());
    for (i, args) in writers(&eds, &dir.path("link.eds")).into_iter().enumerate() {
        let target = dir.file(&format!("real{i}.eds"), &base());
        let link = dir.path("link.eds");
        let _ = std::fs::remove_file(&link);
        std::os::unix::fs::symlink(format!("real{i}.eds"), &link).unwrap();
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let o = odgen(&args);
        assert!(o.status.success(), "{args:?}: {}", stderr(&o));
        assert!(std::fs::symlink_metadata(&link).unwrap().file_type().is_symlink(), "{args:?}: the link was replaced");
        assert_ne!(std::fs::read_to_string(&target).unwrap(), base(), "{args:?}: the target was not written");
    }
    // A dangling link: the file it names is created.
    let link = dir.path("dangling.dcf");
    std::os::unix::fs::symlink("made.dcf", &link).unwrap();
    let o = odgen(&["dcf", "--node-id", "5", s(&eds), "-o", s(&link)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(std::fs::symlink_metadata(&link).unwrap().file_type().is_symlink());
    assert!(std::fs::read_to_string(dir.path("made.dcf")).unwrap().contains("[DeviceComissioning]"));
}

/// A replaced file keeps its permission bits, and its owner and group (when the tests run as
/// root, who may give files away).
#[test]
fn writes_keep_mode_and_owner() {
    let dir = TempDir::new("mode");
    let eds = dir.file("device.eds", &base());
    let root = std::fs::metadata(&eds).unwrap().uid() == 0;
    for mode in [0o600, 0o640, 0o755, 0o200] {
        for args in writers(&eds, &dir.path("target.eds")) {
            let target = dir.file("target.eds", &base());
            std::fs::set_permissions(&target, std::fs::Permissions::from_mode(mode)).unwrap();
            if root {
                std::os::unix::fs::chown(&target, Some(4321), Some(4322)).unwrap();
            }
            let args: Vec<&str> = args.iter().map(String::as_str).collect();
            let o = odgen(&args);
            assert!(o.status.success(), "{args:?} on mode {mode:o}: {}", stderr(&o));
            let m = std::fs::metadata(&target).unwrap();
            assert_eq!(m.permissions().mode() & 0o7777, mode, "{args:?}");
            if root {
                assert_eq!((m.uid(), m.gid()), (4321, 4322), "{args:?}");
            }
            std::fs::set_permissions(&target, std::fs::Permissions::from_mode(0o644)).unwrap();
            std::fs::remove_file(&target).unwrap();
        }
    }
}

/// A read-only file (no write permission bit) is not replaced, even by root, who could.
#[test]
fn read_only_files_are_refused() {
    let dir = TempDir::new("readonly");
    let eds = dir.file("device.eds", &base());
    for mode in [0o444, 0o400, 0o555] {
        for args in writers(&eds, &dir.path("target.eds")) {
            let target = dir.file("target.eds", &base());
            std::fs::set_permissions(&target, std::fs::Permissions::from_mode(mode)).unwrap();
            let args: Vec<&str> = args.iter().map(String::as_str).collect();
            let o = odgen(&args);
            assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
            assert!(stderr(&o).contains("read-only"), "{args:?}: {}", stderr(&o));
            assert_eq!(std::fs::read_to_string(&target).unwrap(), base());
            assert_eq!(std::fs::metadata(&target).unwrap().permissions().mode() & 0o7777, mode);
            std::fs::set_permissions(&target, std::fs::Permissions::from_mode(0o644)).unwrap();
            std::fs::remove_file(&target).unwrap();
        }
    }
}

/// A character device like /dev/null, made in `dir` (as root), so that no test ever points a
/// command that writes at the system's own devices. `None` when the tests cannot make one.
fn null_device(dir: &TempDir) -> Option<PathBuf> {
    let p = dir.path("null");
    let ok =
        Command::new("mknod").arg(&p).args(["c", "1", "3"]).stderr(Stdio::null()).status().is_ok_and(|s| s.success());
    ok.then_some(p)
}

/// Devices, FIFOs and directories are neither read as descriptions nor replaced: each command
/// says what the path is and finishes at once (a FIFO blocked `check` until killed, and
/// `fmt /dev/null` run as root replaced the system's /dev/null with a regular file).
#[test]
fn devices_and_fifos_are_refused() {
    let dir = TempDir::new("devices");
    let eds = dir.file("device.eds", &base());
    let fifo = dir.path("fifo.eds");
    mkfifo(&fifo);
    let device = null_device(&dir);
    let mut inputs = vec![s(&fifo), s(&dir.0)];
    inputs.extend(device.as_deref().map(s));
    for input in &inputs {
        for cmd in [
            vec!["check", input],
            vec!["check", "--format", "json", input],
            vec!["fmt", input],
            vec!["fmt", "--check", input],
            vec!["dump", input],
            vec!["dcf", "--node-id", "5", input],
        ] {
            let o = odgen_bounded(&cmd);
            assert_eq!(o.status.code(), Some(2), "{cmd:?}: {}", stderr(&o));
            if !cmd.contains(&"json") {
                assert!(stderr(&o).contains("cannot read"), "{cmd:?}: {}", stderr(&o));
            }
        }
    }
    // Endless devices are refused before a byte is read (by the commands that only read: the
    // system's devices are never given to one that writes).
    for cmd in [vec!["check", "/dev/urandom"], vec!["dump", "/dev/zero"], vec!["dcf", "--node-id", "5", "/dev/urandom"]]
    {
        let o = odgen_bounded(&cmd);
        assert_eq!(o.status.code(), Some(2), "{cmd:?}: {}", stderr(&o));
        assert!(stderr(&o).contains("not a regular file"), "{cmd:?}: {}", stderr(&o));
    }
    let mut targets = vec![s(&fifo)];
    targets.extend(device.as_deref().map(s));
    for target in targets {
        let o = odgen_bounded(&["dcf", "--node-id", "5", s(&eds), "-o", target]);
        assert_eq!(o.status.code(), Some(2), "-o {target}: {}", stderr(&o));
        assert!(stderr(&o).contains("not a regular file"), "-o {target}: {}", stderr(&o));
    }
    if let Some(device) = &device {
        assert!(std::fs::symlink_metadata(device).unwrap().file_type().is_char_device_like());
    }
    assert!(std::fs::symlink_metadata(&fifo).unwrap().file_type().is_fifo_like());
}

trait FileTypeLike {
    fn is_char_device_like(&self) -> bool;
    fn is_fifo_like(&self) -> bool;
}

impl FileTypeLike for std::fs::FileType {
    fn is_char_device_like(&self) -> bool {
        std::os::unix::fs::FileTypeExt::is_char_device(self)
    }
    fn is_fifo_like(&self) -> bool {
        std::os::unix::fs::FileTypeExt::is_fifo(self)
    }
}

/// `-o -` writes the DCF to standard output (and creates no file named `-`).
#[test]
fn dash_is_standard_output() {
    let dir = TempDir::new("dash");
    let eds = dir.file("device.eds", &base());
    let o = Command::new(env!("CARGO_BIN_EXE_odgen"))
        .current_dir(&dir.0)
        .args(["dcf", "--node-id", "5", s(&eds), "-o", "-"])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8(o.stdout).unwrap();
    assert!(text.contains("[DeviceComissioning]\nNodeID=5\n"), "{text}");
    assert!(!dir.path("-").exists());
}

/// `fmt` never drops a line the reader ignored without saying so: it refuses the file and lists
/// the lines; the file is left as it was.
#[test]
fn fmt_refuses_to_drop_ignored_lines() {
    let dir = TempDir::new("ignored");
    let mut text = String::from("Stray=before any section\n");
    text.push_str(&base());
    text = text.replacen("[DeviceInfo]\n", "[DeviceInfo]\nthis line is neither\n", 1);
    for i in 0..30 {
        text.push_str(&format!("junk {i}\n"));
    }
    let f = dir.file("ignored.eds", &text);
    let o = odgen(&["fmt", s(&f)]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let err = stderr(&o);
    assert!(err.contains("the reader ignored 32 lines"), "{err}");
    assert!(err.contains("line 1: Stray=before any section"), "{err}");
    assert!(err.contains(": this line is neither"), "{err}");
    assert!(err.contains("… and 12 more"), "{err}");
    assert_eq!(std::fs::read_to_string(&f).unwrap(), text);
}

/// `dump` writes an OCTET_STRING as one string of hex digits (two output bytes per value byte,
/// plus the rest of the model), in JSON and YAML, and the JSON reads back as the model: a
/// pretty list of numbers took about 19 output bytes per value byte.
#[test]
fn dump_writes_bytes_as_hex() {
    let dir = TempDir::new("octets");
    let n = 200_000;
    let value: String = (0..n).map(|i| format!("{:02X}", (i * 7) as u8)).collect();
    let text = format!(
        "{}\n[2100]\nParameterName=Blob\nObjectType=0x7\nDataType=0x000A\nAccessType=rw\nDefaultValue={value}\nPDOMapping=0\n",
        base()
    );
    let f = dir.file("octets.eds", &text);
    let small = dir.file("base.eds", &base());
    for format in ["json", "yaml"] {
        let size = |p: &Path| {
            let o = odgen(&["dump", "--format", format, s(p)]);
            assert!(o.status.success(), "{}", stderr(&o));
            o.stdout
        };
        let (with, without) = (size(&f), size(&small));
        let extra = with.len() - without.len();
        assert!(extra < 2 * n + 2000, "{format}: {extra} bytes for {n} value bytes");
        assert!(String::from_utf8_lossy(&with).contains(&value), "{format}");
        if format == "json" {
            let model: eds::Model = serde_json::from_slice(&with).unwrap();
            assert_eq!(model, eds::read_file(&f, &eds::Options::lenient()).unwrap().model);
        }
    }
}
