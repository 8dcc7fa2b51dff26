//! `drive-sim run --machine` from the command line: the help names every device's default
//! machine, presets and files are accepted, bad ones are clear errors.

use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};

fn drive_sim(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_drive-sim")).args(args).output().expect("drive-sim runs")
}

#[test]
fn run_help_says_what_machine_each_drive_starts_with() {
    let out = drive_sim(&["run", "--help"]);
    assert!(out.status.success());
    let help = String::from_utf8(out.stdout).unwrap();
    for line in [
        "--machine <PRESET|FILE>",
        "drvi free (default)",
        "drvi drvi-actuator",
        "drcs drcs-belt (default)",
        "drcs free",
        "akd akd-linear (default)",
        "akd free",
    ] {
        assert!(help.contains(line), "{line:?} missing from:\n{help}");
    }
}

#[test]
fn bad_machines_are_clear_errors() {
    let dir = std::env::temp_dir().join(format!("machine-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let bad = dir.join("bad.toml");
    std::fs::write(&bad, "travel = \"rotary\"\npositive_end_stop = 2.0\n").unwrap();
    let bad = bad.to_str().unwrap();
    let cases: [(&[&str], &str); 4] = [
        (&["--device", "akd", "--node-id", "3", "--machine", "nope"], "neither a file nor a preset of the akd"),
        (&["--device", "drvi", "--node-id", "3", "--machine", "akd-linear"], "presets: free, drvi-actuator"),
        (&["--device", "drcs", "--node-id", "3", "--machine", bad], "a rotary machine turns freely"),
        (&["--machine", "free", "--device", "akd", "--node-id", "3"], "--machine must follow the --device"),
    ];
    for (args, want) in cases {
        let mut all = vec!["run"];
        all.extend_from_slice(args);
        all.extend_from_slice(&["--listen", "127.0.0.1:0"]);
        let out = drive_sim(&all);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert!(err.contains(want), "{args:?}: {err}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn every_drive_runs_with_a_preset_and_a_file() {
    let dir = std::env::temp_dir().join(format!("machine-cli-ok-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("axis.toml");
    std::fs::write(&file, "travel = \"linear\"\nnegative_end_stop = -5.0\npositive_end_stop = 5.0\n").unwrap();
    let file = file.to_str().unwrap();
    let mut child = Command::new(env!("CARGO_BIN_EXE_drive-sim"))
        .args(["run", "--device", "drvi", "--node-id", "2", "--machine", "drvi-actuator"])
        .args(["--device", "drcs", "--node-id", "3", "--machine", file])
        .args(["--device", "akd", "--node-id", "4", "--machine", "free", "--listen", "127.0.0.1:0"])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).unwrap();
    let _ = child.kill();
    let _ = child.wait();
    let _ = std::fs::remove_dir_all(&dir);
    assert!(line.starts_with("listening on "), "{line:?}");
}
