"""Real-time benchmark (a report, not a test): N simulated DRVIs in one `drive-sim run` process on
its TCP hub, each at 60 rpm in profile velocity with a 100 ms heartbeat (1017h), watched by a
socketcand master for 10 s. Prints the drive-sim process's CPU share, the frames per second
reaching the master and the heartbeat intervals (how well real time holds).

    cargo build --release -p drive --bin drive-sim
    $(bash scripts/venv.sh) scripts/bench_realtime.py target/release/drive-sim 32
"""
import os
import statistics
import subprocess
import sys
import time

import can

BIN = sys.argv[1]
N = int(sys.argv[2]) if len(sys.argv) > 2 else 32
SECONDS = 10.0
args = [BIN, "run", "--quiet", "--listen", "127.0.0.1:0"]
for i in range(1, N + 1):
    args += ["--device", "drvi", "--node-id", str(i)]
p = subprocess.Popen(args, stdout=subprocess.PIPE, text=True)
addr = p.stdout.readline().strip().split()[-1]
host, port = addr.rsplit(":", 1)
bus = can.Bus(interface="socketcand", host=host, port=int(port), channel="can0")

def sdo(node, index, sub, value, size):
    cmd = {1: 0x2F, 2: 0x2B, 4: 0x23}[size]
    data = [cmd, index & 0xFF, index >> 8, sub] + list(value.to_bytes(4, "little", signed=value < 0))
    bus.send(can.Message(arbitration_id=0x600 + node, data=data, is_extended_id=False))
    deadline = time.monotonic() + 2
    while time.monotonic() < deadline:
        m = bus.recv(0.5)
        if m is not None and m.arbitration_id == 0x580 + node:
            assert m.data[0] == 0x60, (node, hex(index), m)
            return
    raise SystemExit(f"no SDO answer from {node}")

for n in range(1, N + 1):
    sdo(n, 0x1017, 0, 100, 2)
    for cw in (6, 7, 0xF):
        sdo(n, 0x6040, 0, cw, 2)
    sdo(n, 0x6060, 0, 3, 1)
    sdo(n, 0x6083, 0, 600, 4)
    sdo(n, 0x60FF, 0, 6000, 4)
bus.send(can.Message(arbitration_id=0, data=[1, 0], is_extended_id=False))
time.sleep(1)

def cpu():
    f = open(f"/proc/{p.pid}/stat").read().split(")")[1].split()
    return (int(f[11]) + int(f[12])) / os.sysconf("SC_CLK_TCK")

beats = {n: [] for n in range(1, N + 1)}
frames = 0
c0, t0, w0 = cpu(), time.monotonic(), time.time()
while time.monotonic() - t0 < SECONDS:
    m = bus.recv(0.1)
    if m is None or m.timestamp < w0:
        continue
    frames += 1
    if 0x701 <= m.arbitration_id <= 0x700 + N:
        beats[m.arbitration_id - 0x700].append(m.timestamp)
c1, t1 = cpu(), time.monotonic()
intervals = [b - a for ts in beats.values() for a, b in zip(ts, ts[1:])]
print(f"{N} DRVIs, {t1 - t0:.1f} s wall: drive-sim CPU {100 * (c1 - c0) / (t1 - t0):.1f} % of one core, "
      f"{frames / (t1 - t0):.0f} frames/s to the master")
print(f"heartbeats: {sum(len(v) for v in beats.values())} (expected ~{int(N * SECONDS / 0.1)}), interval "
      f"mean {1000 * statistics.mean(intervals):.1f} ms, min {1000 * min(intervals):.1f}, max {1000 * max(intervals):.1f}")
bus.shutdown()
p.terminate()
p.wait(10)
