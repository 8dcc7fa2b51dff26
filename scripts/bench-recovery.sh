#!/usr/bin/env bash
# The supervisor's recovery time, boot-up message to node Operational again, for each drive of
# networks/example.toml, on the in-memory bus (real time) and over the TCP hub; then a soak
# with random power cycles (a benchmark, not a test: it reports).
#
#   scripts/bench-recovery.sh              (ROUNDS=10 SOAK_SECONDS=600 SOAK_MIN=10 SOAK_MAX=30)
#   SOAK_SECONDS=60 SOAK_MIN=2 SOAK_MAX=5 scripts/bench-recovery.sh     a shortened soak
#
# The drives run in one `drive-sim run --listen ... --control SOCKET` (one process, one hub);
# each power cycle goes through the control socket (`drive-sim fault`'s protocol), 5 ms off.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
target=${CARGO_TARGET_DIR:-$root/target}
case "$target" in /*) ;; *) target="$root/$target" ;; esac
rounds=${ROUNDS:-10}
soak_s=${SOAK_SECONDS:-600}
echo "building drive-sim and od-master's recovery example (cargo build --release)..." >&2
cargo build --release -q -p drive --bin drive-sim -p od-master --example recovery
sim="$target/release/drive-sim"
bench="$target/release/examples/recovery"

pids=()
tmp=$(mktemp -d)
cleanup() { for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done; rm -rf "$tmp"; }
trap cleanup EXIT

echo "== in-memory bus, real time, $rounds rounds"
"$bench" mem "$rounds"

out="$tmp/sim.out"
"$sim" run --listen 127.0.0.1:0 --quiet --control "$tmp/ctl.sock" \
  --device drvi --node-id 2 --device drcs --node-id 3 --device akd --node-id 4 >"$out" 2>"$tmp/sim.err" &
pids+=($!)
addr=
for _ in $(seq 100); do
  addr=$(sed -n 's/^listening on //p' "$out")
  [ -n "$addr" ] && break
  sleep 0.05
done
[ -n "$addr" ] || { echo "drive-sim did not start: $(cat "$tmp/sim.err")" >&2; exit 1; }
bus="socketcand://$addr/can0"
echo "== over the hub ($bus), $rounds rounds"
"$bench" hub "$bus" "$tmp/ctl.sock" "$rounds"
echo "== soak over the hub: $soak_s s, a power cycle every ${SOAK_MIN:-10}..${SOAK_MAX:-30} s"
"$bench" soak "$bus" "$tmp/ctl.sock" "$soak_s" "${SOAK_MIN:-10}" "${SOAK_MAX:-30}"
# What drive-sim said besides its faults and start lines (a hub problem: frames dropped for an endpoint).
grep -v -e ': fault: node' -e ' started$' -e 'faults on demand at' "$tmp/sim.err" >&2 || true
