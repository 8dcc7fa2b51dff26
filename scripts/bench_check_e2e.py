"""Times `odgen check` end to end, as a user runs it (the third part of bench-read.sh): the
process started, the files read and checked, the report written to a file. Also the same with
`--notes` (every note rendered), for comparison.

Usage: bench_check_e2e.py ODGEN RUNS PATH...   (files, or directories of *.eds/*.dcf)
Prints one JSON line: files, bytes, runs, seconds, ms_per_run, cpu_ms_per_run (the children's
user + system time), out_bytes, notes_ms_per_run, notes_out_bytes.
"""

import json
import resource
import os
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
        for name, extra in (("default", []), ("notes", ["--notes"])):
            with open(report, "wb") as out:
                subprocess.run([odgen, "check", *extra, *paths], stdout=out, stderr=subprocess.DEVNULL)  # warm-up
            before = resource.getrusage(resource.RUSAGE_CHILDREN)
            start = time.perf_counter()
            for _ in range(runs):
                with open(report, "wb") as out:
                    subprocess.run([odgen, "check", *extra, *paths], stdout=out, stderr=subprocess.DEVNULL)
            seconds = time.perf_counter() - start
            after = resource.getrusage(resource.RUSAGE_CHILDREN)
            cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
            figures[name] = (seconds, os.path.getsize(report), cpu)
    seconds, out_bytes, cpu = figures["default"]
    print(json.dumps({
        "files": len(paths), "bytes": size, "runs": runs, "seconds": seconds,
        "ms_per_run": seconds * 1e3 / runs, "out_bytes": out_bytes, "cpu_ms_per_run": cpu * 1e3 / runs,
        "notes_ms_per_run": figures["notes"][0] * 1e3 / runs, "notes_out_bytes": figures["notes"][1],
    }))


if __name__ == "__main__":
    main()
