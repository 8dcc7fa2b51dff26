//! The `odgen` binary, run as a real process on files in a temporary directory.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

const GOOD: &str = "\
[FileInfo]
FileName=drive.eds
FileVersion=1
FileRevision=0
EDSVersion=4.0
Description=CLI test drive
CreationTime=10:00AM
CreationDate=01-02-2025
CreatedBy=odgen tests
ModificationTime=10:00AM
ModificationDate=01-02-2025
ModifiedBy=odgen tests

[DeviceInfo]
VendorName=Example
VendorNumber=0x00000151
ProductName=Drive
ProductNumber=0x00000001
RevisionNumber=0x00000001
OrderCode=D-1
BaudRate_10=0
BaudRate_20=0
BaudRate_50=0
BaudRate_125=1
BaudRate_250=1
BaudRate_500=1
BaudRate_800=0
BaudRate_1000=1
SimpleBootUpMaster=0
SimpleBootUpSlave=1
Granularity=8
DynamicChannelsSupported=0
GroupMessaging=0
NrOfRXPDO=0
NrOfTXPDO=0
LSS_Supported=0

[DummyUsage]
Dummy0001=0
Dummy0002=0
Dummy0003=0
Dummy0004=0
Dummy0005=1
Dummy0006=1
Dummy0007=1

[MandatoryObjects]
SupportedObjects=3
1=0x1000
2=0x1001
3=0x1018

[1000]
ParameterName=Device type
ObjectType=0x7
DataType=0x0007
AccessType=ro
DefaultValue=0x00020192
PDOMapping=0

[1001]
ParameterName=Error register
ObjectType=0x7
DataType=0x0005
AccessType=ro
DefaultValue=0
PDOMapping=1

[1018]
ParameterName=Identity object
ObjectType=0x9
SubNumber=0x2

[1018sub0]
ParameterName=Highest sub-index supported
ObjectType=0x7
DataType=0x0005
AccessType=ro
DefaultValue=1
PDOMapping=0

[1018sub1]
ParameterName=Vendor-ID
ObjectType=0x7
DataType=0x0007
AccessType=ro
DefaultValue=0x00000151
PDOMapping=0

[OptionalObjects]
SupportedObjects=2
1=0x1014
2=0x6060

[1014]
ParameterName=COB-ID EMCY
ObjectType=0x7
DataType=0x0007
AccessType=rw
DefaultValue=$NODEID+0x80
PDOMapping=0

[6060]
ParameterName=Modes of operation
ObjectType=0x7
DataType=0x0002
AccessType=rw
DefaultValue=0
LowLimit=-10
HighLimit=10
PDOMapping=1

[ManufacturerObjects]
SupportedObjects=0
";

fn odgen(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_odgen")).args(args).output().expect("run odgen")
}

fn stdout(o: &Output) -> String {
    String::from_utf8_lossy(&o.stdout).into_owned()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

struct TempDir(PathBuf);

impl TempDir {
    fn new(name: &str) -> Self {
        let p = std::env::temp_dir().join(format!("odgen-cli-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&p);
        std::fs::create_dir_all(&p).unwrap();
        TempDir(p)
    }

    fn file(&self, name: &str, text: &str) -> PathBuf {
        let p = self.0.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

#[test]
fn check_passes_a_good_file_and_fails_a_bad_one() {
    let dir = TempDir::new("check");
    let good = dir.file("good.eds", GOOD);
    let o = odgen(&["check", "--strict", s(&good)]);
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    assert!(stdout(&o).contains("checked 1 file: "), "{}", stdout(&o));

    let bad = dir.file("bad.eds", &GOOD.replace("DataType=0x0002\n", ""));
    let o = odgen(&["check", s(&good), s(&bad)]);
    assert_eq!(o.status.code(), Some(1), "{}", stdout(&o));
    let out = stdout(&o);
    // rustc style: code, location arrow, the quoted line, a caret, and the summary.
    assert!(out.contains("error[E"), "{out}");
    assert!(out.contains(&format!("--> {}:", bad.display())), "{out}");
    assert!(out.contains("| [6060]"), "{out}");
    assert!(out.contains("lacks DataType"), "{out}");
    assert!(out.contains('^'), "{out}");
    assert!(out.contains("checked 2 files: 1 error"), "{out}");
}

#[test]
fn strict_turns_deviations_into_errors() {
    let dir = TempDir::new("strict");
    // A value that cannot be read is kept as text: a warning, an error under --strict.
    let f = dir.file("value.eds", &GOOD.replace("DefaultValue=0\nLowLimit", "DefaultValue=0x1G\nLowLimit"));
    let lenient = odgen(&["check", s(&f)]);
    assert!(lenient.status.success(), "{}", stdout(&lenient));
    assert!(stdout(&lenient).contains("warning"), "{}", stdout(&lenient));
    let strict = odgen(&["check", "--strict", s(&f)]);
    assert_eq!(strict.status.code(), Some(1), "{}", stdout(&strict));
}

#[test]
fn check_json_is_machine_readable() {
    let dir = TempDir::new("json");
    let bad = dir.file("bad.eds", &GOOD.replace("DataType=0x0002\n", ""));
    let o = odgen(&["check", "--format", "json", s(&bad)]);
    assert_eq!(o.status.code(), Some(1));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("JSON output");
    assert_eq!(v["errors"], 1, "{v:#}");
    let d = &v["files"][0]["diagnostics"][0];
    assert_eq!(d["severity"], "error");
    assert!(d["code"].as_str().unwrap().starts_with('E'));
    assert!(d["at"]["line"].as_u64().unwrap() > 100);
}

#[test]
fn check_on_several_threads_prints_what_one_thread_prints() {
    let dir = TempDir::new("jobs");
    let mut files: Vec<PathBuf> = (0..12)
        .map(|i| {
            let text = if i % 3 == 0 {
                GOOD.replace("DataType=0x0002\n", "")
            } else {
                GOOD.replace("DefaultValue=0\nLowLimit", &format!("DefaultValue=0x{i}G\nLowLimit"))
            };
            dir.file(&format!("f{i:02}.eds"), &text)
        })
        .collect();
    files.insert(5, dir.0.join("missing.eds"));
    // (One thread renders each report straight into the output, several into blocks handed
    // to the writer: every format and level must come out the same.)
    let run = |jobs: &str, more: &[&str]| {
        let mut args = vec!["check", "--jobs", jobs];
        args.extend(more);
        args.extend(files.iter().map(|p| s(p)));
        odgen(&args)
    };
    let one = run("1", &[]);
    assert_eq!(one.status.code(), Some(2), "{}", stdout(&one));
    assert!(stdout(&one).contains("checked 13 files: 4 errors"), "{}", stdout(&one));
    let variants: [&[&str]; 6] = [
        &[],
        &["--notes"],
        &["--format", "json"],
        &["--format", "sarif"],
        &["--format", "sarif", "--level", "error"],
        &["--format", "json", "--level", "error", "--strict"],
    ];
    for more in variants {
        let one = run("1", more);
        for jobs in ["2", "8"] {
            let many = run(jobs, more);
            assert_eq!(
                (many.status.code(), stdout(&many), stderr(&many)),
                (one.status.code(), stdout(&one), stderr(&one)),
                "--jobs {jobs} {more:?}"
            );
        }
    }
}

/// A file whose report is several times larger than the blocks output is rendered and written
/// in (64 KiB), between two small ones: every format prints each file's report whole and in the
/// files' order, with one thread or several.
#[test]
fn reports_larger_than_an_output_block_stay_whole_and_in_order() {
    let dir = TempDir::new("blocks");
    let small = GOOD.replace("DataType=0x0002\n", "");
    // Each `#` comment is a warning of its own (about 250 bytes of human output, more in JSON).
    let comments: String = (0..3000).map(|i| format!("# comment number {i} of many\n")).collect();
    let big = GOOD.replacen("\n[", &format!("\n{comments}["), 1);
    let files = [dir.file("a.eds", &small), dir.file("big.eds", &big), dir.file("c.eds", &small)];
    let paths: Vec<&str> = files.iter().map(|p| s(p)).collect();
    let without_summary = |o: &Output| {
        let text = stdout(o);
        let end = text.rfind("checked ").expect("summary");
        text[..end].to_owned()
    };
    let alone: String = paths.iter().map(|p| without_summary(&odgen(&["check", p]))).collect();
    assert!(alone.len() > 4 * 65536, "{} bytes", alone.len());
    for jobs in ["1", "2"] {
        let mut args = vec!["check", "--jobs", jobs];
        args.extend(&paths);
        assert_eq!(without_summary(&odgen(&args)), alone, "--jobs {jobs}");
        for format in ["json", "sarif"] {
            let mut args = vec!["check", "--jobs", jobs, "--format", format];
            args.extend(&paths);
            let o = odgen(&args);
            let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("JSON output");
            if format == "json" {
                let counts: Vec<usize> =
                    (0..3).map(|i| v["files"][i]["diagnostics"].as_array().map_or(0, Vec::len)).collect();
                assert!(counts[1] >= 3000 && counts[0] == counts[2] && counts[0] > 0, "{counts:?}");
                let names: Vec<&str> = (0..3).map(|i| v["files"][i]["file"].as_str().unwrap_or("")).collect();
                assert_eq!(names, paths, "--jobs {jobs}");
            } else {
                assert!(v["runs"][0]["results"].as_array().map_or(0, Vec::len) >= 3002, "--jobs {jobs}");
            }
        }
    }
}

#[test]
fn check_reports_unreadable_files() {
    let o = odgen(&["check", "/nonexistent/x.eds"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("cannot read /nonexistent/x.eds"), "{}", stderr(&o));
}

#[test]
fn fmt_rewrites_and_check_detects() {
    let dir = TempDir::new("fmt");
    // Same meaning, other spelling: padding, key order, a comment, CRLF.
    let messy = GOOD
        .replace("DefaultValue=0x00020192", "DefaultValue=0x20192")
        .replace("[1001]\n", "; the error register\n[1001]\n")
        .replace('\n', "\r\n");
    let f = dir.file("messy.eds", &messy);
    let o = odgen(&["fmt", "--check", s(&f)]);
    assert_eq!(o.status.code(), Some(1), "{}{}", stdout(&o), stderr(&o));
    assert!(stdout(&o).contains("not in canonical form"), "{}", stdout(&o));
    assert_eq!(std::fs::read_to_string(&f).unwrap(), messy, "--check must not change the file");

    let before = eds::read_file(&f, &eds::Options::lenient()).unwrap().model;
    let o = odgen(&["fmt", s(&f)]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("1 comment line dropped"), "{}", stderr(&o));
    let after = std::fs::read_to_string(&f).unwrap();
    assert!(!after.contains('\r') && after.contains("DefaultValue=0x00020192"));
    assert_eq!(eds::read_file(&f, &eds::Options::lenient()).unwrap().model, before, "fmt changed the meaning");
    let o = odgen(&["fmt", "--check", s(&f)]);
    assert!(o.status.success(), "formatted file is not canonical: {}", stdout(&o));
    // The canonical form of GOOD is GOOD itself.
    let g = dir.file("good.eds", GOOD);
    assert!(odgen(&["fmt", "--check", s(&g)]).status.success());
}

#[test]
fn fmt_leaves_files_with_errors_alone() {
    let dir = TempDir::new("fmt-errors");
    let text = GOOD.replace("DataType=0x0002\n", "");
    let f = dir.file("bad.eds", &text);
    let o = odgen(&["fmt", s(&f)]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("fix its errors first"), "{}", stderr(&o));
    assert_eq!(std::fs::read_to_string(&f).unwrap(), text);
}

#[test]
fn dump_prints_the_model() {
    let dir = TempDir::new("dump");
    let f = dir.file("good.eds", GOOD);
    let o = odgen(&["dump", "--format", "json", s(&f)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let model: eds::Model = serde_json::from_value(v).expect("the JSON is the model");
    assert_eq!(model, eds::read_file(&f, &eds::Options::lenient()).unwrap().model);

    let o = odgen(&["dump", s(&f)]);
    assert!(o.status.success());
    let y = stdout(&o);
    assert!(y.starts_with("kind: Eds\nfile_info:\n  file_name: drive.eds\n"), "{y}");
    assert!(y.contains("      name: Modes of operation\n"), "{y}");
    assert!(y.contains("DefaultValue") || y.contains("default:"), "{y}");
}

#[test]
fn dcf_configures_a_node() {
    let dir = TempDir::new("dcf");
    let f = dir.file("good.eds", GOOD);
    let out = dir.0.join("node5.dcf");
    let o = odgen(&[
        "dcf",
        "--node-id",
        "5",
        "--baud",
        "500",
        "--set",
        "0x6060sub0=3",
        "--set",
        "1014sub0=$NODEID+0x81",
        s(&f),
        "-o",
        s(&out),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let dcf = eds::read_file(&out, &eds::Options::strict()).unwrap();
    assert!(!dcf.has_errors(), "{:#?}", dcf.errors().collect::<Vec<_>>());
    let m = dcf.model;
    assert_eq!(m.kind, eds::FileKind::Dcf);
    assert_eq!(m.node_id(), Some(5));
    assert_eq!(m.commissioning.as_ref().unwrap().baudrate, Some(500));
    let e = m.entry(0x6060, 0).unwrap();
    assert_eq!((e.default.clone(), e.parameter_value().cloned()), (Some(eds::Value::int(0)), Some(eds::Value::int(3))));
    assert_eq!(
        m.entry(0x1014, 0).unwrap().parameter_value().cloned(),
        Some(eds::Value::NodeIdPlus { offset: 0x81, radix: eds::Radix::Hex })
    );
}

#[test]
fn dcf_refuses_bad_values_with_locations() {
    let dir = TempDir::new("dcf-bad");
    let f = dir.file("good.eds", GOOD);
    let out = dir.0.join("bad.dcf");
    let o = odgen(&[
        "dcf",
        "--node-id",
        "5",
        "--baud",
        "800",
        "--set",
        "0x6060sub0=11",
        "--set",
        "0x1000sub0=1",
        "--set",
        "0x6060sub0x=1",
        "--set",
        "0x6061sub0=1",
        s(&f),
        "-o",
        s(&out),
    ]);
    assert_eq!(o.status.code(), Some(1));
    let err = stderr(&o);
    assert!(err.contains("error: 11 is above the entry's HighLimit 10"), "{err}");
    assert!(err.contains(&format!("--> {}:", f.display())), "{err}");
    assert!(err.contains("| [6060]"), "{err}");
    assert!(err.contains("the entry is `ro`"), "{err}");
    assert!(err.contains("does not support 800 kbit/s"), "{err}");
    assert!(err.contains("is not a hex sub-index"), "{err}");
    assert!(err.contains("no object 0x6061"), "{err}");
    assert!(err.contains("no DCF written (5 problems)"), "{err}");
    assert!(!out.exists());
    let o = odgen(&["dcf", "--node-id", "200", s(&f)]);
    assert_eq!(o.status.code(), Some(2), "clap rejects it");
    assert!(stderr(&o).contains("outside 1..=127"));
}

#[test]
fn bench_read_reports_throughput() {
    let dir = TempDir::new("bench");
    dir.file("a.eds", GOOD);
    dir.file("b.dcf", GOOD);
    let o = odgen(&["bench-read", "--iterations", "3", s(&dir.0)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["files"], 2);
    assert_eq!(v["bytes"], 2 * GOOD.len());
    assert_eq!(v["objects_per_pass"], 10);
    assert_eq!(v["allocator"], "system");
    assert!(v["mb_per_s"].as_f64().unwrap() > 0.0);
}

/// Runs odgen with its standard output a pipe whose reading end is closed at once, as
/// `odgen dump x.eds | head -0` does.
fn with_closed_stdout(args: &[&str]) -> Output {
    let mut child = Command::new(env!("CARGO_BIN_EXE_odgen"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .args(args)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("run odgen");
    drop(child.stdout.take());
    child.wait_with_output().expect("wait for odgen")
}

#[test]
fn a_closed_stdout_ends_quietly_with_the_usual_exit_code() {
    let akd = "../devices/kollmorgen-akd.eds";
    for (args, code) in [
        (vec!["dump", akd], 0),
        (vec!["dump", "--format", "json", akd], 0),
        (vec!["check", akd, akd], 0),
        (vec!["dcf", "--node-id", "3", akd], 0),
        (vec!["diff", "tests/fixtures/diff/old.eds", "tests/fixtures/diff/new.eds"], 1),
    ] {
        let o = with_closed_stdout(&args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(code), "odgen {args:?}: {err}");
        assert!(!err.contains("panicked") && !err.contains("Broken pipe"), "odgen {args:?}: {err}");
    }
}

#[test]
fn bad_paths_and_arguments_get_clear_errors() {
    let dir = TempDir::new("bad-args");
    let eds = dir.file("good.eds", GOOD);
    for (args, code, message) in [
        (vec!["dump", "/nonexistent/x.eds"], 2, "error: cannot read /nonexistent/x.eds: "),
        (vec!["dump", s(&dir.0)], 2, "error: cannot read "),
        (vec!["fmt", "/nonexistent/x.eds"], 2, "error: cannot read /nonexistent/x.eds"),
        (vec!["diff", s(&eds), "/nonexistent/x.eds"], 2, "error: cannot read /nonexistent/x.eds"),
        (
            vec!["dcf", "--node-id", "5", s(&eds), "-o", "/nonexistent/dir/x.dcf"],
            2,
            "error: cannot write /nonexistent/dir/x.dcf",
        ),
        (vec!["dcf", "--node-id", "x", s(&eds)], 2, "`x` is not a node id"),
        (vec!["dcf", s(&eds)], 2, "--node-id"),
        (vec!["dcf", "--network", "net.toml", "--node-id", "5", "-o", "out"], 2, "cannot be used with"),
        (vec!["dcf", "--network", "/nonexistent/net.toml", "-o", s(&dir.0)], 2, "cannot read /nonexistent/net.toml"),
        (vec!["dcf", "--network", "/nonexistent/net.toml", "-o", s(&eds)], 2, "cannot read /nonexistent/net.toml"),
        (vec!["diff", s(&eds)], 2, "<NEW>"),
        (vec!["frobnicate"], 2, "unrecognized subcommand"),
    ] {
        let o = odgen(&args);
        let err = stderr(&o);
        assert_eq!(o.status.code(), Some(code), "odgen {args:?}: {err}");
        assert!(err.contains(message), "odgen {args:?}: expected {message:?} in {err}");
        assert!(!err.contains("panicked"), "odgen {args:?}: {err}");
    }
}

/// A folder stands for the `.eds` and `.dcf` files in it and its subfolders (any case of the
/// extension), in the order of their paths; other files are left out, a link to a folder is
/// not followed (a loop ends), and the output is what naming the files gives.
#[test]
fn check_takes_folders_for_their_description_files() {
    let dir = TempDir::new("folders");
    std::fs::create_dir_all(dir.0.join("b/inner")).unwrap();
    let files = [
        dir.file("a.eds", GOOD),
        dir.file("b/c.DCF", GOOD),
        dir.file("b/inner/d.Eds", &GOOD.replace("DataType=0x0002\n", "")),
        dir.file("z.eds", GOOD),
    ];
    dir.file("notes.txt", "not a description");
    dir.file("b/readme.md", "# not one either");
    #[cfg(unix)]
    std::os::unix::fs::symlink(&dir.0, dir.0.join("b/loop")).unwrap();
    let named: Vec<&str> = files.iter().map(|p| s(p)).collect();
    let mut by_name = vec!["check", "--jobs", "2"];
    by_name.extend(&named);
    let expected = odgen(&by_name);
    let folder = odgen(&["check", "--jobs", "2", s(&dir.0)]);
    assert_eq!(folder.status.code(), expected.status.code());
    assert_eq!(stdout(&folder), stdout(&expected));
    assert!(stdout(&folder).contains("checked 4 files"), "{}", stdout(&folder));
    // JSON names the files in path order.
    let o = odgen(&["check", "--format", "json", s(&dir.0)]);
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("JSON output");
    let listed: Vec<&str> = v["files"].as_array().unwrap().iter().map(|f| f["file"].as_str().unwrap()).collect();
    assert_eq!(listed, named);
}
