//! The valgrind driver shared by the instruction-count benches (`od-runtime/benches/icount.rs`,
//! `generated/benches/icount.rs`): each bench binary names its operations and runs one of them
//! in a loop when given `OP N`; under `cargo bench` (the `--bench` argument), it runs itself under
//! `valgrind --tool=cachegrind` for every operation at two loop counts and prints the difference
//! of the instruction counts per iteration (start-up cancels out); under `cargo test` (no
//! arguments) it runs each operation ten times as a smoke test.

use std::process::Command;

/// The instructions valgrind counted for `exe OP N`.
fn instructions(exe: &str, op: &str, n: usize) -> Result<u64, String> {
    let out = Command::new("valgrind")
        .args(["--tool=cachegrind", "--cache-sim=no", "--cachegrind-out-file=/dev/null", exe, op, &n.to_string()])
        .output()
        .map_err(|e| format!("cannot run valgrind: {e}"))?;
    let text = String::from_utf8_lossy(&out.stderr);
    text.lines()
        .find_map(|l| l.split_once("I   refs:").map(|(_, v)| v.trim().replace(',', "")))
        .and_then(|v| v.parse().ok())
        .ok_or_else(|| format!("no instruction count in valgrind's output:\n{text}"))
}

/// The bench's `main`: `ops` are `(name, description)`, `run(op, n)` runs one operation `n`
/// times, `(n1, n2)` the two loop counts valgrind is given.
pub fn main(ops: &[(&str, &str)], (n1, n2): (usize, usize), run: fn(&str, usize) -> Result<(), String>) {
    let args: Vec<String> = std::env::args().collect();
    if let (Some(op), Some(n)) = (args.get(1), args.get(2).and_then(|n| n.parse().ok()))
        && !op.starts_with('-')
    {
        if let Err(e) = run(op, n) {
            eprintln!("{e}");
            std::process::exit(2);
        }
        return;
    }
    if !args.iter().any(|a| a == "--bench") {
        // `cargo test` runs bench binaries without `--bench`: run every operation a few times as
        // a smoke test (no valgrind needed), failing on the first error.
        for (op, _) in ops {
            if let Err(e) = run(op, 10) {
                eprintln!("{op}: {e}");
                std::process::exit(1);
            }
        }
        println!("{} operations ran (smoke test; `cargo bench` counts instructions)", ops.len());
        return;
    }
    let exe = args.first().cloned().unwrap_or_default();
    println!("instructions per operation (valgrind cachegrind, ({n2} - {n1}) iterations)");
    for (op, what) in ops {
        match (instructions(&exe, op, n1), instructions(&exe, op, n2)) {
            (Ok(a), Ok(b)) => {
                let per = (b.saturating_sub(a)) as f64 / (n2 - n1) as f64;
                println!("{op:>12}: {per:7.1}  {what}");
            }
            (Err(e), _) | (_, Err(e)) => {
                println!("{op:>12}: not measured ({e})");
                return;
            }
        }
    }
}
