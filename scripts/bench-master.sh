#!/usr/bin/env bash
# The master's speed over the TCP hub, against python-canopen in the same run (a benchmark, not
# a test: it asserts nothing, it reports; the figures go in the README's "Speed" table).
#
#   scripts/bench-master.sh                   (SECONDS_READS=10 CSP_SECONDS=60 ROUNDS=3)
#
# 1. One `drive-sim hub`; one `drive-sim run --bus` with a DRVI (node 1), a DRCS (2) and an
#    AKD (3) on it (one connection for the three, as devices of one process; each sees every
#    frame, as on a CAN bus). The hub runs without its flood limit (`--max-rate 0`; by default
#    it slows any client past 20,000 frames/s, which would cap the three-node case at exactly
#    that): this measures the software path, not what a CAN bus carries. Expedited SDO reads of
#    1000h, back to back: od-master to node 1 (the `bench` example of od-master), python-canopen
#    to node 1 (scripts/bench_master_canopen.py, python-can's socketcand interface), and
#    od-master to nodes 1, 2 and 3 at once, in alternating rounds so that a drift of the
#    machine's speed weighs on all alike. Also the floor of the path: the same reads by a plain
#    blocking socketcand client (no master; `bench raw`). od-master runs on tokio's multi-thread
#    runtime (two workers, what `#[tokio::main]` gives here) and again on a current-thread one
#    (`BENCH_RUNTIME=current`), which saves the wake-ups between workers. Each master's own time per read is its
#    time per read less the plain client's: what the master adds to the path.
# 2. A fresh hub with three AKDs (nodes 11, 12, 13; of the three drives only the AKD does cyclic
#    synchronous position): SYNC every 1 ms and a set-point per SYNC per drive for CSP_SECONDS,
#    counted, with the SYNC jitter from the hub's time stamps (`bench csp`).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
target=${CARGO_TARGET_DIR:-$root/target}
case "$target" in /*) ;; *) target="$root/$target" ;; esac
reads_s=${SECONDS_READS:-10}
csp_s=${CSP_SECONDS:-60}
rounds=${ROUNDS:-3}
echo "building drive-sim and od-master's bench example (cargo build --release)..." >&2
cargo build --release -q -p drive --bin drive-sim -p od-master --example bench
sim="$target/release/drive-sim"
bench="$target/release/examples/bench"
python=${PYTHON:-$root/.venv/bin/python}
[ -x "$python" ] || python=$(bash "$root/scripts/venv.sh")

pids=()
cleanup() { for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done; }
trap cleanup EXIT

# Starts a hub on a free port; sets $addr.
start_hub() {
  local out
  out=$(mktemp)
  "$sim" hub --listen 127.0.0.1:0 --quiet "$@" >"$out" 2>&1 &
  pids+=($!)
  for _ in $(seq 100); do
    addr=$(sed -n 's/^listening on //p' "$out")
    [ -n "$addr" ] && break
    sleep 0.05
  done
  [ -n "$addr" ] || { echo "the hub did not start: $(cat "$out")" >&2; exit 1; }
}

# Starts drives on the hub at $addr: start_drives DEVICE ID [DEVICE ID ...]
start_drives() {
  local args=() out
  while [ "$#" -gt 0 ]; do args+=(--device "$1" --node-id "$2"); shift 2; done
  out=$(mktemp)
  "$sim" run --bus "socketcand://$addr/can0" "${args[@]}" >"$out" 2>&1 &
  pids+=($!)
  for _ in $(seq 100); do
    grep -q '^running on' "$out" && return
    sleep 0.05
  done
  echo "the drives did not start: $(cat "$out")" >&2
  exit 1
}

start_hub --max-rate 0
start_drives drvi 1 drcs 2 akd 3
bus="socketcand://$addr/can0"
echo "machine: $(nproc) cores, $(uname -srm), load average $(cut -d' ' -f1-3 /proc/loadavg)" >&2
runs=()
for r in $(seq "$rounds"); do
  echo "round $r/$rounds: reads ${reads_s}s each" >&2
  runs+=("$("$bench" reads --bus "$bus" --nodes 1 --seconds "$reads_s" | sed 's/"bench":"reads"/"bench":"od-master 1 node"/')")
  runs+=("$("$python" "$root/scripts/bench_master_canopen.py" "$addr" 1 "$reads_s")")
  runs+=("$("$bench" reads --bus "$bus" --nodes 1,2,3 --seconds "$reads_s" | sed 's/"bench":"reads"/"bench":"od-master 3 nodes"/')")
  runs+=("$(BENCH_RUNTIME=current "$bench" reads --bus "$bus" --nodes 1 --seconds "$reads_s" | sed 's/"bench":"reads"/"bench":"od-master 1 node, current-thread"/')")
  runs+=("$(BENCH_RUNTIME=current "$bench" reads --bus "$bus" --nodes 1,2,3 --seconds "$reads_s" | sed 's/"bench":"reads"/"bench":"od-master 3 nodes, current-thread"/')")
  runs+=("$("$bench" raw --bus "$bus" --nodes 1 --seconds "$reads_s")")
done

start_hub
start_drives akd 11 akd 12 akd 13
echo "CSP: 3 AKDs, SYNC 1 ms, ${csp_s}s" >&2
runs+=("$("$bench" csp --bus "socketcand://$addr/can0" --nodes 11,12,13 --seconds "$csp_s" --period-us 1000)")

"$python" - "$(nproc)" "${runs[@]}" <<'PY'
import json, sys
cores = sys.argv[1]
runs = [json.loads(a) for a in sys.argv[2:]]
for r in runs:
    print(json.dumps(r))

def rate(name):
    rs = [r for r in runs if r["bench"] == name]
    return sum(r["reads"] for r in rs) / sum(r["seconds"] for r in rs), [r["reads_per_s"] for r in rs]

ours, ours_each = rate("od-master 1 node")
theirs, theirs_each = rate("python-canopen reads")
three, three_each = rate("od-master 3 nodes")
raw, raw_each = rate("raw reads")
ours_ct, ours_ct_each = rate("od-master 1 node, current-thread")
three_ct, three_ct_each = rate("od-master 3 nodes, current-thread")
print(f"\nexpedited SDO reads/s over the hub ({cores} cores), totals over the rounds (each round):")
print(f"  od-master, 1 node        {ours:8.0f}  {ours_each}")
print(f"  python-canopen, 1 node   {theirs:8.0f}  {theirs_each}")
print(f"  od-master, 3 nodes       {three:8.0f}  {three_each}")
print(f"  plain blocking client    {raw:8.0f}  {raw_each}  (the hub and drive path, no master)")
print(f"  od-master, 1 node, current-thread runtime  {ours_ct:8.0f}  {ours_ct_each}")
print(f"  od-master, 3 nodes, current-thread runtime {three_ct:8.0f}  {three_ct_each}")
print(f"  od-master / python-canopen: {ours / theirs:.2f}x (current-thread {ours_ct / theirs:.2f}x)   "
      f"3 nodes / 1 node: {three / ours:.2f}x (current-thread {three_ct / ours_ct:.2f}x)")
floor = 1e6 / raw
own_ours, own_theirs = 1e6 / ours - floor, 1e6 / theirs - floor
print(f"  time per read: path (plain client) {floor:.1f} us; beyond it od-master {own_ours:.1f} us, "
      f"python-canopen {own_theirs:.1f} us ({own_theirs / own_ours if own_ours > 0 else float('inf'):.1f}x)")
csp = [r for r in runs if r["bench"] == "csp"][-1]
j = csp["jitter_us"]
print(f"CSP, 3 drives, SYNC {csp['period_us']} us, {csp['seconds']:.0f} s: {csp['syncs']} SYNCs, "
      f"set-points missed {csp['missed']} (with no stall {csp['missed_on_time']}) repeated {csp.get('repeated')} "
      f"doubled {csp['doubled']} "
      f"of {csp['periods']} periods; SYNCs over half a period late {csp['late_syncs']}; "
      f"SYNC jitter p50/p99/max {j['p50']}/{j['p99']}/{j['max']} us")
PY
