"""Times `odgen check` end to end, as a user runs it (the third part of bench-read.sh): the
process started, the files read and checked, the report written to a file. Also the same with
`--notes` (every note rendered), for comparison.

Usage: bench_check_e2e.py ODGEN RUNS PATH...   (files, or directories of *.eds/*.dcf)
Prints one JSON line: files, bytes, runs, seconds, ms_per_run, cpu_ms_per_run (the children's
user + system time), out_bytes, notes_ms_per_run, notes_out_bytes, run_ms (each run's wall time,
for medians), one_thread_run_ms (each run of `odgen check --jobs 1`), start_ms_per_run (`odgen
--version`: starting the process and nothing else) and spawn_ms_per_run (`true`: what starting
any program from here costs).
"""

import json
import resource
import os
import shutil
import subprocess
import sys
import tempfile
import time


def main():
    odgen, runs = sys.argv[1], int(sys.argv[2])
    paths = []
    for p in sys.argv[3:]:
        if os.path.isdir(p):
            paths += sorted(os.path.join(p, f) for f in os.listdir(p) if f.lower().endswith((".eds", ".dcf")))
        else:
            paths.append(p)
    size = sum(os.path.getsize(p) for p in paths)
    figures = {}
    with tempfile.TemporaryDirectory() as d:
        report = os.path.join(d, "report.txt")
        check = [odgen, "check"]
        variants = (
            ("default", [*check, *paths]),
            ("notes", [*check, "--notes", *paths]),
            ("one_thread", [*check, "--jobs", "1", *paths]),
            ("start", [odgen, "--version"]),
            ("spawn", [shutil.which("true") or "/bin/true"]),
        )
        # The variants take turns, run by run, so that none is always the first after what ran
        # before this script (in bench-read.sh, python-canopen: for a few hundred milliseconds
        # after such a process a VM's fresh pages cost the next programs several times more, and
        # the variant run first took it all). One warm-up run each first.
        for _, command in variants:
            with open(report, "wb") as out:
                subprocess.run(command, stdout=out, stderr=subprocess.DEVNULL)
        each = {name: [] for name, _ in variants}
        cpu = {name: 0.0 for name, _ in variants}
        out_size = {}
        for _ in range(runs):
            for name, command in variants:
                with open(report, "wb") as out:
                    before = resource.getrusage(resource.RUSAGE_CHILDREN)
                    start = time.perf_counter()
                    subprocess.run(command, stdout=out, stderr=subprocess.DEVNULL)
                    each[name].append(time.perf_counter() - start)
                    after = resource.getrusage(resource.RUSAGE_CHILDREN)
                cpu[name] += (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
                out_size[name] = os.path.getsize(report)
        for name, _ in variants:
            figures[name] = (sum(each[name]), out_size[name], cpu[name], [t * 1e3 for t in each[name]])
    seconds, out_bytes, cpu, each = figures["default"]
    print(json.dumps({
        "files": len(paths), "bytes": size, "runs": runs, "seconds": seconds,
        "ms_per_run": seconds * 1e3 / runs, "out_bytes": out_bytes, "cpu_ms_per_run": cpu * 1e3 / runs,
        "notes_ms_per_run": figures["notes"][0] * 1e3 / runs, "notes_out_bytes": figures["notes"][1],
        "run_ms": each, "one_thread_run_ms": figures["one_thread"][3],
        "start_ms_per_run": figures["start"][0] * 1e3 / runs, "spawn_ms_per_run": figures["spawn"][0] * 1e3 / runs,
    }))


if __name__ == "__main__":
    main()
