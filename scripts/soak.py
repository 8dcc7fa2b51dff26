#!/usr/bin/env python3
"""Soak benchmark (not a CI test): many simulated drives on one hub under a fast SYNC, with a
python-canopen master reading and writing over SDO the whole time.

    scripts/venv.sh                      # once: the venv with python-canopen
    .venv/bin/python scripts/soak.py [--drives 32] [--duration 600] [--sync-ms 1] [--bitrate 1000000]

It starts `drive-sim hub` (with --bitrate, an emulated wire of that rate), one `drive-sim run`
process with the drives (node ids 1..N, DRVI, DRCS and AKD in turn, each its own connection with
--bus, `--connection-per-device`; with --shared-connection one for all), connects the master, sets every heartbeat producer (1017h) to --heartbeat-ms, starts the
nodes (NMT start, so their default TPDOs run), starts SYNC and then reads 6041h and writes and
reads back 6083h on every node in turn until the time is up. It reports:

* frames lost: what the hub dropped for a reader that fell behind (its log), heartbeats received
  against those the producers' period promises (and intervals over 1.5 periods: late ones), and
  SDO transfers that failed;
* heartbeat jitter: per interval, |interval - period|, over every node (mean, p99, max), from
  the hub's time stamps (when the frame left the bus) and as the master's receive thread saw
  the frames (python-canopen, sharing the GIL with the SDO client and the SYNC thread);
* SYNC: frames the master put out per second;
* CPU: the hub's, the drives' and the master's CPU time over the run, as % of one core.

The figures depend on the machine and on what else runs on it; README's performance table
names the machine they came from. Build drive-sim first (`cargo build --release -p drive`); the
script uses target/release/drive-sim unless $DRIVE_SIM says otherwise.
"""

import argparse
import os
import re
import resource
import statistics
import subprocess
import sys
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "python"))

KINDS = ["drvi", "drcs", "akd"]
EDS = {
    "drvi": ROOT / "devices" / "camozzi-drvi.eds",
    "drcs": ROOT / "devices" / "camozzi-drcs.eds",
    "akd": ROOT / "devices" / "kollmorgen-akd.eds",
}


def start(binary, args, ready):
    process = subprocess.Popen(
        [str(binary), *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    line = process.stdout.readline().strip()
    if not line.startswith(ready):
        process.kill()
        sys.exit(f"drive-sim {' '.join(args)} did not start: {line!r} {process.stderr.read()}")
    log = []
    threading.Thread(target=lambda: log.extend(process.stderr), daemon=True).start()
    return process, line[len(ready):], log


def cpu_seconds(pid):
    """User + system CPU time of a process so far, from /proc."""
    with open(f"/proc/{pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    ticks = os.sysconf("SC_CLK_TCK")
    return (int(fields[11]) + int(fields[12])) / ticks


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--drives", type=int, default=32)
    parser.add_argument("--duration", type=float, default=600.0, help="seconds of load")
    parser.add_argument("--sync-ms", type=float, default=1.0)
    parser.add_argument("--heartbeat-ms", type=int, default=100)
    parser.add_argument("--bitrate", type=int, default=1_000_000, help="0: no wire emulation")
    parser.add_argument("--shared-connection", action="store_true",
                        help="the drives on one connection and thread (drive-sim run's default); "
                             "without it each has its own, as separate CAN controllers the wire arbitrates")
    args = parser.parse_args()

    import logging

    import can  # noqa: F401  (fails early without the venv)
    import canopen

    # python-can warns about every message split across two reads; not news in a soak.
    logging.getLogger("can").setLevel(logging.ERROR)
    from conftest import rtr_socketcand_bus

    binary = Path(os.environ.get("DRIVE_SIM", ROOT / "target" / "release" / "drive-sim"))
    hub_args = ["hub", "--listen", "127.0.0.1:0", "--quiet"]
    if args.bitrate:
        hub_args += ["--bitrate", str(args.bitrate)]
    hub, address, hub_log = start(binary, hub_args, "listening on ")
    host, port = address.rsplit(":", 1)
    run_args = ["run", "--bus", f"tcp://{address}/can0", "--quiet"]
    if not args.shared_connection:
        run_args.append("--connection-per-device")
    nodes = list(range(1, args.drives + 1))
    for node_id in nodes:
        run_args += ["--device", KINDS[(node_id - 1) % 3], "--node-id", str(node_id)]
    drives, _, drives_log = start(binary, run_args, "running on ")

    network = canopen.Network(rtr_socketcand_bus("can0", host, int(port)))
    network.connect()
    heartbeats = {n: [] for n in nodes}
    lock = threading.Lock()

    def on_heartbeat(can_id, data, timestamp):
        # The hub's time stamp (when the frame left the wire) and when the master got it.
        with lock:
            heartbeats[can_id - 0x700].append((timestamp, time.monotonic()))

    for n in nodes:
        network.subscribe(0x700 + n, on_heartbeat)
    remotes = {}
    for n in nodes:
        remote = network.add_node(n, str(EDS[KINDS[(n - 1) % 3]]))
        remote.sdo.RESPONSE_TIMEOUT = 2.0
        remote.sdo[0x1017].raw = args.heartbeat_ms
        remotes[n] = remote
    network.nmt.state = "OPERATIONAL"
    if args.sync_ms > 0:
        network.sync.start(args.sync_ms / 1000.0)

    with lock:
        for n in nodes:
            heartbeats[n].clear()
    cpu0 = {"hub": cpu_seconds(hub.pid), "drives": cpu_seconds(drives.pid)}
    master0 = resource.getrusage(resource.RUSAGE_SELF)
    started = time.monotonic()
    transfers = failures = 0
    value = 0
    while time.monotonic() - started < args.duration:
        for n in nodes:
            value = (value + 1) % 10_000
            try:
                remotes[n].sdo[0x6041].raw
                remotes[n].sdo[0x6083].raw = 1000 + value
                if remotes[n].sdo[0x6083].raw != 1000 + value:
                    failures += 1
            except Exception as error:  # noqa: BLE001 (counted, the soak goes on)
                failures += 1
                print(f"node {n}: {error}", file=sys.stderr)
            transfers += 3
    elapsed = time.monotonic() - started
    cpu = {"hub": cpu_seconds(hub.pid) - cpu0["hub"], "drives": cpu_seconds(drives.pid) - cpu0["drives"]}
    master1 = resource.getrusage(resource.RUSAGE_SELF)
    cpu["master"] = (master1.ru_utime + master1.ru_stime) - (master0.ru_utime + master0.ru_stime)
    if args.sync_ms > 0:
        network.sync.stop()
    network.disconnect()
    for process in (drives, hub):
        process.terminate()
        process.wait(timeout=10)
    time.sleep(0.2)

    period = args.heartbeat_ms / 1000.0
    deviations, seen, late = [], [], 0
    received = expected = 0
    for n in nodes:
        pairs = [p for p in heartbeats[n] if p[1] <= started + elapsed]
        received += len(pairs)
        expected += int(elapsed / period)
        for (a, a_seen), (b, b_seen) in zip(pairs, pairs[1:]):
            deviations.append(abs(b - a - period))
            seen.append(abs(b_seen - a_seen - period))
            if b - a > 1.5 * period:
                late += 1
    dropped = 0
    for line in hub_log:
        found = re.search(r"\((\d+) in all\)", line)
        if found:
            dropped = max(dropped, int(found.group(1)))
    def summary(values):
        values = sorted(values)
        if not values:
            return "none"
        p99 = values[int(0.99 * (len(values) - 1))]
        return f"mean {statistics.mean(values) * 1e3:.2f} ms, p99 {p99 * 1e3:.2f} ms, max {values[-1] * 1e3:.2f} ms"

    print(f"drives {args.drives}, SYNC {args.sync_ms} ms, bitrate {args.bitrate or 'unlimited'}, "
          f"duration {elapsed:.0f} s")
    print(f"SDO transfers {transfers} ({transfers / elapsed:.0f}/s), failed {failures}")
    print(f"frames dropped by the hub {dropped}; heartbeats received {received} of {expected} expected "
          f"({max(0, expected - received)} short), {late} intervals over 1.5 periods")
    print(f"heartbeat jitter (|interval - {args.heartbeat_ms} ms|) on the bus (hub time stamps): {summary(deviations)}")
    print(f"  as the master's receive thread saw them: {summary(seen)}")
    print("CPU (% of one core): " + ", ".join(f"{k} {100 * v / elapsed:.0f}%" for k, v in cpu.items()))
    drive_errors = [line.strip() for line in drives_log if "reconnect" in line or "error" in line]
    if drive_errors:
        print("drive-sim run reported:", *drive_errors[:10], sep="\n  ")


if __name__ == "__main__":
    main()
