#!/usr/bin/env bash
# Read+validate throughput: our reader (`odgen bench-read`, a release build) against
# python-canopen's import_od, over the same files, in one run. Prints both figures and the ratio.
#
#   scripts/bench-read.sh [DIR_OR_FILES...]      default: $EDS_CORPUS_DIR or ../shared/eds-corpus
#   ROUNDS=8 OURS_ITERATIONS=100 PY_ITERATIONS=1 scripts/bench-read.sh   (the defaults)
#
# This is a benchmark, not a test: it asserts nothing; it reports. The target is >= 100x in
# process (the reader against import_od: what a program using `eds` gets). `odgen check` end to
# end (on the files as a user runs it: process start, every file read and checked, the report
# written to a file) is reported beside it, against python-canopen's in-process time, which
# leaves out its interpreter's start (the ratio favours python-canopen).
# The first figures are one thread against python-canopen's one; the last line is odgen reading
# the files on every core, as `odgen check` does (python-canopen has no such mode).
# Both wall time and CPU time are printed: on a shared machine the CPU-time ratio is the steadier
# figure. Files python-canopen cannot import still cost it the time until it gives up.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
if [ "$#" -gt 0 ]; then
  inputs=("$@")
else
  corpus=${EDS_CORPUS_DIR:-../shared/eds-corpus}
  case "$corpus" in /*) ;; *) corpus="$root/$corpus" ;; esac
  [ -d "$corpus" ] || { echo "no corpus at $corpus (set EDS_CORPUS_DIR)" >&2; exit 2; }
  inputs=("$corpus")
fi
target=${CARGO_TARGET_DIR:-$root/target}
case "$target" in /*) ;; *) target="$root/$target" ;; esac
# The binary measured is odgen as `cargo install --path odgen` builds it (the release profile).
echo "building odgen (cargo build --release)..." >&2
cargo build --release -q -p odgen
odgen="$target/release/odgen"
python=$(bash "$root/scripts/venv.sh")
# The two sides run in alternating rounds (odgen, then python-canopen, ROUNDS times), so that a
# change in the machine's speed during the measurement (a shared or virtual machine's speed
# drifts by tens of percent over minutes) weighs on both alike. Each round is one JSON line per
# side (odgen on one thread, odgen on every core, python-canopen); the figures below are totals
# over the rounds, with the range of the per-round ratios.
rounds=${ROUNDS:-8}
ours_runs=() theirs_runs=() parallel_runs=() e2e_runs=()
for _ in $(seq "$rounds"); do
  ours_runs+=("$("$odgen" bench-read --jobs 1 --iterations "${OURS_ITERATIONS:-100}" "${inputs[@]}")")
  parallel_runs+=("$("$odgen" bench-read --jobs 0 --iterations "${OURS_ITERATIONS:-100}" "${inputs[@]}")")
  theirs_runs+=("$("$python" "$root/scripts/bench_read_canopen.py" "${PY_ITERATIONS:-1}" "${inputs[@]}")")
  e2e_runs+=("$("$python" "$root/scripts/bench_check_e2e.py" "$odgen" "${E2E_RUNS:-10}" "${inputs[@]}")")
done
"$python" - "${#ours_runs[@]}" "${ours_runs[@]}" "${theirs_runs[@]}" "${parallel_runs[@]}" "${e2e_runs[@]}" <<'PY'
import json, sys
n = int(sys.argv[1])
ours_runs = [json.loads(a) for a in sys.argv[2:2 + n]]
theirs_runs = [json.loads(a) for a in sys.argv[2 + n:2 + 2 * n]]
parallel_runs = [json.loads(a) for a in sys.argv[2 + 2 * n:2 + 3 * n]]
e2e_runs = [json.loads(a) for a in sys.argv[2 + 3 * n:2 + 4 * n]]

def total(runs):
    """Per-pass figures over all rounds, as one run would give them."""
    passes = sum(r["iterations"] for r in runs)
    seconds = sum(r["seconds"] for r in runs)
    cpu = None if any(r.get("cpu_seconds") is None for r in runs) else sum(r["cpu_seconds"] for r in runs)
    out = dict(runs[0])
    out.update(iterations=passes, seconds=seconds, ms_per_pass=seconds * 1e3 / passes,
               mb_per_s=runs[0]["bytes"] * passes / 1e6 / seconds if seconds else 0.0,
               cpu_seconds=cpu, cpu_ms_per_pass=None if cpu is None else cpu * 1e3 / passes)
    return out

ours, theirs, parallel = total(ours_runs), total(theirs_runs), total(parallel_runs)
rounds = [t["ms_per_pass"] / o["ms_per_pass"] for o, t in zip(ours_runs, theirs_runs)]
print(f"files: {ours['files']}  bytes: {ours['bytes']}  rounds: {n} (odgen and python-canopen alternating)")
print(f"odgen (eds::parse, read+validate, {ours['allocator']}): {ours['ms_per_pass']:9.3f} ms per pass  {ours['mb_per_s']:8.2f} MB/s  "
      f"({ours['iterations']} passes, {ours['seconds']:.3f} s)")
print(f"python-canopen {theirs['canopen_version']} import_od:    {theirs['ms_per_pass']:9.3f} ms per pass  "
      f"{theirs['mb_per_s']:8.2f} MB/s  ({theirs['iterations']} passes, {theirs['seconds']:.3f} s)")
if theirs["failures"]:
    print(f"  python-canopen could not import {len(theirs['failures'])} file(s): {', '.join(theirs['failures'])}")
ratio = theirs["ms_per_pass"] / ours["ms_per_pass"] if ours["ms_per_pass"] else float("inf")
print(f"wall-time ratio: odgen is {ratio:.1f}x faster than python-canopen "
      f"(rounds: {min(rounds):.1f}x to {max(rounds):.1f}x)")
if ours.get("cpu_ms_per_pass") and theirs.get("cpu_ms_per_pass"):
    cpu = theirs["cpu_ms_per_pass"] / ours["cpu_ms_per_pass"]
    print(f"CPU time per pass: odgen {ours['cpu_ms_per_pass']:.3f} ms ({ours['bytes'] / 1e3 / ours['cpu_ms_per_pass']:.2f} MB/s), "
          f"python-canopen {theirs['cpu_ms_per_pass']:.3f} ms")
    print(f"CPU-time ratio: odgen is {cpu:.1f}x faster (target >= 100x: {'met' if cpu >= 100 else 'NOT met'})")
else:
    print(f"(no CPU times on this system; target >= 100x on wall time: {'met' if ratio >= 100 else 'NOT met'})")
if parallel["jobs"] > 1:
    wall = theirs["ms_per_pass"] / parallel["ms_per_pass"]
    print(f"odgen on {parallel['jobs']} threads (as `odgen check` reads many files): {parallel['ms_per_pass']:.3f} ms "
          f"per pass wall, {parallel['mb_per_s']:.2f} MB/s: {wall:.1f}x python-canopen's wall time")
e2e_runs_total = sum(r["runs"] for r in e2e_runs)
e2e_ms = sum(r["seconds"] for r in e2e_runs) * 1e3 / e2e_runs_total
notes_ms = sum(r["notes_ms_per_run"] * r["runs"] for r in e2e_runs) / e2e_runs_total
e2e_ratio = theirs["ms_per_pass"] / e2e_ms
e2e_rounds = [t["ms_per_pass"] / e["ms_per_run"] for e, t in zip(e2e_runs, theirs_runs)]
print(f"end to end: `odgen check` on the {e2e_runs[0]['files']} files (process start, report of "
      f"{e2e_runs[0]['out_bytes']} bytes to a file): {e2e_ms:.3f} ms per run; with --notes "
      f"({e2e_runs[0]['notes_out_bytes']} bytes): {notes_ms:.3f} ms")
print(f"end-to-end ratio: odgen check is {e2e_ratio:.1f}x faster than python-canopen's import_od in process "
      f"(rounds: {min(e2e_rounds):.1f}x to {max(e2e_rounds):.1f}x)")
# The median and the one-thread figures show how much of the mean is the second core (on a VM
# it is often slow to start working).
import statistics
each = [t for r in e2e_runs for t in r["run_ms"]]
one = [t for r in e2e_runs for t in r["one_thread_run_ms"]]
print(f"end to end, per run: median {statistics.median(each):.3f} ms ({theirs['ms_per_pass'] / statistics.median(each):.1f}x), "
      f"best {min(each):.3f} ms ({theirs['ms_per_pass'] / min(each):.1f}x); with --jobs 1: mean "
      f"{statistics.mean(one):.3f} ms ({theirs['ms_per_pass'] / statistics.mean(one):.1f}x), median "
      f"{statistics.median(one):.3f} ms")
start_ms = sum(r["start_ms_per_run"] * r["runs"] for r in e2e_runs) / e2e_runs_total
spawn_ms = sum(r["spawn_ms_per_run"] * r["runs"] for r in e2e_runs) / e2e_runs_total
print(f"end to end, process start: `odgen --version` {start_ms:.3f} ms per run, `true` {spawn_ms:.3f} ms "
      f"(starting any program from the measuring script; python-canopen's figure has no process start)")
e2e_cpu = sum(r["cpu_ms_per_run"] * r["runs"] for r in e2e_runs) / e2e_runs_total
if theirs.get("cpu_ms_per_pass"):
    cpu_ratio = theirs["cpu_ms_per_pass"] / e2e_cpu
    print(f"end-to-end CPU time: odgen check {e2e_cpu:.3f} ms per run (user + system, process start included); "
          f"CPU-time ratio {cpu_ratio:.1f}x")
PY
