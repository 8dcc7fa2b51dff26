"""Times one `odgen` command line end to end with several binaries, in alternating runs (to
compare builds: before and after a change, or two profiles). Each run's output goes to a file,
as a user would redirect it; every binary runs three times first, unmeasured.

Usage: bench_check_ab.py RUNS "ARGS" ODGEN...
  e.g. bench_check_ab.py 600 "check ../shared/eds-corpus" /tmp/before/odgen target/release/odgen
Prints the mean and median wall time of each binary. A benchmark: it asserts nothing.
"""

import os
import shlex
import statistics
import subprocess
import sys
import tempfile
import time


def main():
    runs, args, binaries = int(sys.argv[1]), shlex.split(sys.argv[2]), sys.argv[3:]
    times = {b: [] for b in binaries}
    with tempfile.TemporaryDirectory() as d:
        report = os.path.join(d, "report.txt")

        def run(binary):
            with open(report, "wb") as out:
                start = time.perf_counter()
                subprocess.run([binary, *args], stdout=out, stderr=subprocess.DEVNULL)
                return (time.perf_counter() - start) * 1e3

        for b in binaries:
            for _ in range(3):
                run(b)
        # Binary after binary, run by run: a drift of the machine's speed weighs on all alike.
        for _ in range(runs):
            for b in binaries:
                times[b].append(run(b))
    for b in binaries:
        t = times[b]
        print(f"{b}: mean {statistics.mean(t):.2f} ms, median {statistics.median(t):.2f} ms ({len(t)} runs)")


if __name__ == "__main__":
    main()
