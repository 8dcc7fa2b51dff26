#!/usr/bin/env python3
"""Runs the workspace's test binaries, built once by cargo: the CPU-bound ones two at a time,
then the ones that keep time alone.

`cargo test` runs one test binary at a time. On the project's 2-core machines that leaves a
core idle for much of the Rust tests: the code generator's corpus compile tests, the
compile-fail tests and odgen's mutation test each spend long stretches in one process on one
core. Those binaries (the packages in `CPU_BOUND`: they read, generate and compile, and wait
on nothing but the CPU) run two at a time, the longest first. Every other binary (the bus, the
simulated drives, the master: real sockets, timers and deadlines) runs afterwards, one at a
time, as cargo runs them: side by side with a corpus compile, od-bus's hub timing tests failed
(tried on 2026-12-06).

The binaries are the ones `cargo test --no-run --message-format=json` built (its standard
input); each runs as `cargo test` runs it: in its package's directory, with cargo's variables.
A binary's output is printed whole when it ends; the exit code is non-zero when any binary
failed, and the failed ones are named at the end.

Usage: cargo test ... --no-run --message-format=json | scripts/run-tests.py
"""

import json
import os
import subprocess
import sys
import threading
import time

# Packages whose tests depend on nothing but the CPU: no sockets, no timers, no deadlines
# shorter than minutes.
CPU_BOUND = {"canopen-eds", "od-codegen", "od-macros", "odgen", "od-sidecar"}

# The longest of them (package, target), longest first: seconds on a fresh clone of a 2-core
# machine, 2026-12-06, one at a time: od-codegen's corpus compile tests 112, the trybuild
# project 77, odgen's mutation and memory tests 76, eds's 22 and 17. Starting them first keeps
# both runners busy to the end.
LONGEST = [
    ("od-codegen", "it"),
    ("od-macros", "ui"),
    ("odgen", "it"),
    ("canopen-eds", "it"),
    ("canopen-eds", "canopen_eds"),
]
RUNNERS = 2


def package_name(package_id, manifest_path):
    # path+file:///work/main/eds#canopen-eds@0.1.0, or path+file:///work/main/od-sidecar#0.1.0
    tail = package_id.rsplit("#", 1)[-1]
    if "@" in tail:
        return tail.split("@", 1)[0], tail.split("@", 1)[1]
    return os.path.basename(os.path.dirname(manifest_path)), tail


def toolchain():
    """cargo, and the directories a proc-macro crate's test harness loads the standard library
    from (it links it dynamically; cargo tells the loader where when it runs the binary)."""
    cargo = os.environ.get("CARGO") or subprocess.run(
        ["rustup", "which", "cargo"], capture_output=True, text=True
    ).stdout.strip() or "cargo"
    rustc = subprocess.run(["rustup", "which", "rustc"], capture_output=True, text=True).stdout.strip() or "rustc"
    sysroot = subprocess.run([rustc, "--print", "sysroot"], capture_output=True, text=True).stdout.strip()
    version = subprocess.run([rustc, "-vV"], capture_output=True, text=True).stdout.splitlines()
    host = next((line.split(":", 1)[1].strip() for line in version if line.startswith("host:")), "")
    return cargo, [os.path.join(sysroot, "lib", "rustlib", host, "lib"), os.path.join(sysroot, "lib")]


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

    cargo, libraries = toolchain()
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
                p for p in [os.path.dirname(b["exe"]), *libraries, env.get("LD_LIBRARY_PATH", "")] if p
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

    def rank(b):
        key = (b["package"], b["target"])
        return LONGEST.index(key) if key in LONGEST and b["kind"] in ("test", "lib") else len(LONGEST)

    # sorted() is stable: the rest keep cargo's order.
    parallel = sorted((b for b in binaries if b["package"] in CPU_BOUND), key=rank)
    alone = [b for b in binaries if b["package"] not in CPU_BOUND]

    def runner():
        while True:
            with lock:
                if not parallel:
                    return
                b = parallel.pop(0)
            run(b)

    started = time.monotonic()
    threads = [threading.Thread(target=runner) for _ in range(RUNNERS)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    first = time.monotonic() - started
    for b in alone:
        run(b)
    print(
        f"\n{len(binaries)} test binaries ran: the CPU-bound ones {RUNNERS} at a time ({first:.0f} s), "
        f"then {len(alone)} alone ({time.monotonic() - started - first:.0f} s)"
    )
    if failed:
        print("failed:\n  " + "\n  ".join(failed))
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
