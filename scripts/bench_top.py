"""Load benchmark of `od-master top` (a report, not a test): 8,000 frames/s (a 1 Mbit/s bus)
through a `drive-sim hub`, sent by a socketcand client of its own: TPDOs and heartbeats of eight
nodes (10..17) and an EMCY of node 10 ten times a second. `od-master top` runs in tmux (80x24)
on the same hub. Prints its CPU share idle and under load, its redraws per second, the time a
redraw and the taking in of the traffic take (measured by top itself, OD_MASTER_TOP_STATS), the
frames it saw and dropped, and whether every EMCY reached the events.

    cargo build --release -p drive --bin drive-sim -p od-master-cli
    $(bash scripts/venv.sh) scripts/bench_top.py target/release/drive-sim target/release/od-master

With `--plot`, top reads a network description of the eight nodes (DRVIs whose TPDO1 carries
statusword and position, as the frames sent do) and, one second into the load, opens a plot of
four series in two panels: the redraw figures are then those of the plot.
"""
import json
import os
import socket
import subprocess
import sys
import tempfile
import time
import uuid

PLOT = "--plot" in sys.argv
ARGS = [a for a in sys.argv[1:] if a != "--plot"]
SIM, TOP = ARGS[0], ARGS[1]
RATE = int(ARGS[2]) if len(ARGS) > 2 else 8000
SECONDS = 10.0

hub = subprocess.Popen([SIM, "hub", "--listen", "127.0.0.1:0", "--quiet"], stdout=subprocess.PIPE, text=True)
addr = hub.stdout.readline().strip().split()[-1]
host, port = addr.rsplit(":", 1)
tmux = ["tmux", "-L", f"bench-top-{uuid.uuid4().hex[:6]}"]
stats = os.path.join(tempfile.mkdtemp(), "stats.json")


def cpu(pid):
    f = open(f"/proc/{pid}/stat").read().split(")")[1].split()
    return (int(f[11]) + int(f[12])) / os.sysconf("SC_CLK_TCK")


def expect(sock, what):
    data = b""
    while not data.endswith(b">"):
        data += sock.recv(1)
    assert what in data.decode(), data


network = ""
if PLOT:
    network = os.path.join(os.path.dirname(stats), "bench.toml")
    drvi = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "devices", "camozzi-drvi.eds")
    with open(network, "w") as f:
        f.write('[network]\nname = "bench"\nbaud_rate = 1000\n')
        for n in range(10, 18):
            f.write(f'[nodes.n{n}]\ndevice = "{drvi}"\nnode_id = {n}\n')
            f.write(f'[nodes.n{n}.tpdo1]\nmap = ["statusword", "position_actual_value"]\n')

try:
    env = f"OD_MASTER_TOP_STATS={stats}"
    subprocess.run(
        tmux + ["new-session", "-d", "-x", "80", "-y", "24", f"{env} exec {TOP} --bus socketcand://{addr}/can0 top {network}"],
        check=True,
    )
    pid = int(subprocess.run(tmux + ["display", "-p", "#{pane_pid}"], capture_output=True, text=True).stdout)
    time.sleep(2)
    c0, t0 = cpu(pid), time.monotonic()
    time.sleep(5)
    idle = (cpu(pid) - c0) / (time.monotonic() - t0)

    s = socket.create_connection((host, int(port)))
    expect(s, "hi")
    s.sendall(b"< open can0 >")
    expect(s, "ok")
    s.sendall(b"< rawmode >")
    expect(s, "ok")
    batch = RATE // 200  # every 5 ms
    sent = emcys = 0
    c0, t0 = cpu(pid), time.monotonic()
    tick = 0
    while time.monotonic() - t0 < SECONDS:
        out = []
        for i in range(batch):
            node = 10 + (sent + i) % 8
            v = (sent + i) & 0xFFFF
            out.append(f"< send {0x180 + node:X} 6 37 06 {v & 0xFF:02X} {v >> 8:02X} 00 00 >")
        if tick % 20 == 0:  # every 100 ms: a heartbeat of each node, an EMCY of node 10
            out[: 8] = [f"< send {0x700 + n:X} 1 05 >" for n in range(10, 18)]
            out[8] = f"< send 8A 8 {0x10 + emcys % 16:02X} 10 01 00 00 00 00 00 >"
            emcys += 1
        s.sendall("".join(out).encode())
        sent += len(out)
        if PLOT and tick == 200:
            # Node 10's position; node 11's statusword and position; node 12's position.
            keys = ["g", "Right", "Space", "Right", "Space", "Right", "Right", "Space"]
            subprocess.run(tmux + ["send-keys", *keys], check=True)
        tick += 1
        time.sleep(max(0.0, t0 + tick * 0.005 - time.monotonic()))
    elapsed = time.monotonic() - t0
    loaded = (cpu(pid) - c0) / elapsed
    time.sleep(0.5)
    screen = subprocess.run(tmux + ["capture-pane", "-p"], capture_output=True, text=True).stdout
    subprocess.run(tmux + ["send-keys", "q"], check=True)
    for _ in range(50):
        if os.path.exists(stats) and os.path.getsize(stats):
            break
        time.sleep(0.1)
    st = json.loads(open(stats).read())
    print(screen)
    print(f"sent {sent} frames in {elapsed:.1f} s: {sent / elapsed:.0f} frames/s, {emcys} EMCYs")
    print(f"od-master top CPU: idle {100 * idle:.1f}% of a core, at load {100 * loaded:.1f}% of a core")
    print(f"redraws {st['redraws']} in {st['seconds']:.1f} s: {st['redraws'] / st['seconds']:.1f}/s; "
          f"redraw mean {st['draw_mean_us']:.0f} us, max {st['draw_max_us']} us; "
          f"taking the traffic in: mean {st['take_mean_us']:.0f} us a tick")
    print(f"top saw {st['frames']} frames, dropped {st['dropped']}; events {st['events']}, EMCYs {st['emcys']} of {emcys}")
finally:
    subprocess.run(tmux + ["kill-server"], capture_output=True)
    hub.terminate()
