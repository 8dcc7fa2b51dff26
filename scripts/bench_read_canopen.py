"""Times python-canopen's import_od over EDS/DCF files (the other half of bench-read.sh).

Usage: bench_read_canopen.py ITERATIONS PATH...   (files, or directories of *.eds/*.dcf)
Prints one JSON line: files, bytes, iterations, seconds, failures (files import_od rejects),
ms_per_pass, and the process CPU time (cpu_seconds, cpu_ms_per_pass). Files are read from disk by import_od itself, as a user would call it.
"""

import json
import logging
import os
import sys
import time

import canopen


def main():
    iterations = int(sys.argv[1])
    paths = []
    for p in sys.argv[2:]:
        if os.path.isdir(p):
            paths += sorted(os.path.join(p, f) for f in os.listdir(p) if f.lower().endswith((".eds", ".dcf")))
        else:
            paths.append(p)
    logging.disable(logging.CRITICAL)
    size = sum(os.path.getsize(p) for p in paths)
    # Warm the OS cache and find the files python-canopen cannot import at all.
    failures = []
    for p in paths:
        try:
            canopen.import_od(p, 1)
        except Exception as e:  # noqa: BLE001
            failures.append(f"{os.path.basename(p)}: {type(e).__name__}")
    cpu_start = time.process_time()
    start = time.perf_counter()
    for _ in range(iterations):
        for p in paths:
            try:
                canopen.import_od(p, 1)
            except Exception:  # noqa: BLE001
                pass
    seconds = time.perf_counter() - start
    cpu_seconds = time.process_time() - cpu_start
    print(json.dumps({
        "files": len(paths), "bytes": size, "iterations": iterations, "seconds": seconds,
        "mb_per_s": size * iterations / 1e6 / seconds if seconds else 0.0,
        "ms_per_pass": seconds * 1e3 / iterations, "failures": failures,
        "cpu_seconds": cpu_seconds, "cpu_ms_per_pass": cpu_seconds * 1e3 / iterations,
        "canopen_version": canopen.__version__,
    }))


if __name__ == "__main__":
    main()
