#!/usr/bin/env bash
# Speed through an slcan adapter (a benchmark, not a test: it asserts nothing, it reports):
# expedited SDO reads of 1000h back to back, od-master (its `bench` example) against
# python-canopen over python-can's `slcan` interface, through the same simulated adapter
# (`drive-sim slcan --device drvi`, a CANable on a pseudo-terminal, the DRVI in its process),
# with the wire emulated at 500 kbit/s and at 1 Mbit/s (the adapter holds each frame for its
# length in bits at the rate of the host's `Sn`), and without it (`--no-wire`: the software
# path alone). Every read is two frames on the bus. Then the codec alone per frame
# (`cargo bench -p od-bus --bench hub -- slcan`).
#
#   scripts/bench-slcan.sh                 (SECONDS_READS=5)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
cd "$root"
target=${CARGO_TARGET_DIR:-$root/target}
case "$target" in /*) ;; *) target="$root/$target" ;; esac
reads_s=${SECONDS_READS:-5}
echo "building drive-sim and od-master's bench example (cargo build --release)..." >&2
cargo build --release -q -p drive --bin drive-sim -p od-master --example bench
sim="$target/release/drive-sim"
bench="$target/release/examples/bench"
python=${PYTHON:-$root/.venv/bin/python}
[ -x "$python" ] || python=$(bash "$root/scripts/venv.sh")

pids=()
cleanup() { for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done; }
trap cleanup EXIT

# Starts a simulated adapter with a DRVI as node 1; sets $tty.
start_adapter() {
  local out
  out=$(mktemp)
  "$sim" slcan --device drvi --node-id 1 "$@" >"$out" 2>&1 &
  pids+=($!)
  for _ in $(seq 100); do
    tty=$(sed -n 's/^slcan on //p' "$out")
    [ -n "$tty" ] && break
    sleep 0.1
  done
  [ -n "$tty" ] || { cat "$out" >&2; exit 1; }
}

canopen_reads() {
  "$python" - "$1" "$2" "$reads_s" <<'PY'
import sys, time, canopen
tty, bitrate, seconds = sys.argv[1], int(sys.argv[2]), float(sys.argv[3])
network = canopen.Network()
network.connect(interface="slcan", channel=tty, bitrate=bitrate, sleep_after_open=0)
node = canopen.RemoteNode(1, canopen.ObjectDictionary())
node.sdo.RESPONSE_TIMEOUT = 2.0
network.add_node(node)
node.sdo.upload(0x1000, 0)
n, start = 0, time.monotonic()
while time.monotonic() - start < seconds:
    node.sdo.upload(0x1000, 0)
    n += 1
elapsed = time.monotonic() - start
network.disconnect()
print(f'{{"bench":"reads","master":"python-canopen","reads_per_s":{n / elapsed:.0f}}}')
PY
}

for wire in 500000 1000000 none; do
  if [ "$wire" = none ]; then start_adapter --no-wire; rate=1000000; else start_adapter; rate=$wire; fi
  addr="slcan://$tty?bitrate=$rate"
  od=$("$bench" reads --bus "$addr" --nodes 1 --seconds "$reads_s")
  py=$(canopen_reads "$tty" "$rate")
  kill "${pids[-1]}" 2>/dev/null || true
  echo "wire $wire: od-master $od"
  echo "wire $wire: python    $py"
done
echo "codec per frame:"
cargo bench -q -p od-bus --bench hub -- slcan 2>&1 | grep -E "^slcan|time:|thrpt:"
