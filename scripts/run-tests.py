#!/usr/bin/env python3
"""Runs the workspace's test binaries, built once by cargo, two at a time.

`cargo test` runs one test binary at a time. On the project's 2-core machines that left a
core idle for most of the Rust tests: the longest binaries (the code generator's corpus
compile tests, the compile-fail tests, odgen's mutation test) each keep about one core busy,
while the simulated drives' tests mostly wait on sockets and timers. This script takes the
binaries that `cargo test --no-run --message-format=json` built (its standard input), and
runs them as `cargo test` does (in the package's directory, with cargo's variables), two at a
time: the longest first (`LONGEST`, measured on a fresh clone), then the rest in cargo's order,
each taken by whichever of the two runners is free. Each binary's output is printed whole when
it ends; the exit code is non-zero when any binary failed, and the failed ones are named at the
end.

Usage: cargo test ... --no-run --message-format=json | scripts/run-tests.py
"""

import json
import os
import subprocess
import sys
import threading
import time

# The test binaries that take longest (package, target), longest first: seconds on a fresh
# clone of a 2-core machine, 2026-12-06, two at a time: od-codegen's corpus compile tests 179,
# odgen's mutation and memory tests 119, the trybuild project 81, drive's 80, eds's 42 and
# 30, od-master's 27. Starting them first keeps the two runners busy to the end.
LONGEST = [
    ("od-codegen", "it"),
    ("odgen", "it"),
    ("od-macros", "ui"),
    ("drive", "it"),
    ("canopen-eds", "it"),
    ("canopen-eds", "canopen_eds"),
    ("od-master", "it"),
]
RUNNERS = 2


def package_name(package_id, manifest_path):
    # path+file:///work/main/eds#canopen-eds@0.1.0, or path+file:///work/main/od-sidecar#0.1.0
    tail = package_id.rsplit("#", 1)[-1]
    if "@" in tail:
        return tail.split("@", 1)[0], tail.split("@", 1)[1]
    return os.path.basename(os.path.dirname(manifest_path)), tail


def main():
    binaries = []
    for line in sys.stdin:
        line = line.strip()
        if not line.startswith("{"):
            continue
        m = json.loads(line)
        if m.get("reason") != "compiler-artifact" or not m.get("executable") or not m["profile"]["test"]:
            continue
        name, version = package_name(m["package_id"], m["manifest_path"])
        binaries.append(
            {
                "package": name,
                "version": version,
                "manifest": m["manifest_path"],
                "exe": m["executable"],
                "kind": m["target"]["kind"][0],
                "target": m["target"]["name"],
                "src": os.path.relpath(m["target"]["src_path"], os.path.dirname(m["manifest_path"])),
            }
        )
    if not binaries:
        print("run-tests.py: cargo built no test binary", file=sys.stderr)
        return 1

    cargo = os.environ.get("CARGO") or subprocess.run(
        ["rustup", "which", "cargo"], capture_output=True, text=True
    ).stdout.strip() or "cargo"
    # The toolchain cargo used (rust-toolchain.toml): a proc-macro crate's test harness links the
    # standard library dynamically, from the sysroot's lib/rustlib/HOST/lib, as cargo tells the
    # loader when it runs the binary itself.
    rustc = subprocess.run(["rustup", "which", "rustc"], capture_output=True, text=True).stdout.strip() or "rustc"
    sysroot = subprocess.run([rustc, "--print", "sysroot"], capture_output=True, text=True).stdout.strip()
    host = next(
        (l.split(":", 1)[1].strip() for l in subprocess.run([rustc, "-vV"], capture_output=True, text=True).stdout.splitlines() if l.startswith("host:")),
        "",
    )
    rustlib = os.path.join(sysroot, "lib", "rustlib", host, "lib")

    def rank(b):
        key = (b["package"], b["target"])
        return LONGEST.index(key) if key in LONGEST and b["kind"] in ("test", "lib") else len(LONGEST)

    queue = sorted(binaries, key=rank)  # stable: the rest stay in cargo's order
    lock = threading.Lock()
    failed = []

    def run(b):
        directory = os.path.dirname(b["manifest"])
        env = dict(os.environ)
        env.update(
            CARGO=cargo,
            CARGO_MANIFEST_DIR=directory,
            CARGO_MANIFEST_PATH=b["manifest"],
            CARGO_PKG_NAME=b["package"],
            CARGO_PKG_VERSION=b["version"],
            CARGO_CRATE_NAME=b["target"].replace("-", "_"),
            LD_LIBRARY_PATH=os.pathsep.join(
                p for p in [os.path.dirname(b["exe"]), rustlib, os.path.join(sysroot, "lib"), env.get("LD_LIBRARY_PATH", "")] if p
            ),
        )
        started = time.monotonic()
        out = subprocess.run([b["exe"]], cwd=directory, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
        took = time.monotonic() - started
        kind = "unittests " if b["kind"] in ("lib", "bin", "proc-macro") else ""
        with lock:
            sys.stdout.write(f"     Running {kind}{b['src']} ({os.path.relpath(b['exe'])}) [{b['package']}, {took:.1f} s]\n")
            sys.stdout.write(out.stdout.decode("utf-8", "replace"))
            sys.stdout.flush()
            if out.returncode != 0:
                failed.append(f"{b['package']} {kind}{b['src']} (exit {out.returncode})")

    def runner():
        while True:
            with lock:
                if not queue:
                    return
                b = queue.pop(0)
            run(b)

    threads = [threading.Thread(target=runner) for _ in range(RUNNERS)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    print(f"\n{len(binaries)} test binaries ran, {RUNNERS} at a time")
    if failed:
        print("failed:\n  " + "\n  ".join(failed))
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
