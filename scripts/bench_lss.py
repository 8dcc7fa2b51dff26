#!/usr/bin/env python3
"""LSS fastscan benchmark (issue #37): three simulated DRVI drives without a node-ID, with
serial numbers 1001, 1002, 1003, on one `drive-sim hub`:

  1. `od-master lss scan`              full fastscan, default step timeout
  2. `od-master --eds DRVI lss scan`   vendor, product and revision from the EDS matched
  3. `od-master lss assign NET.toml`   given nodes 2, 3, 4 by their identity (switch state
     selective; a fastscan for devices the description does not name), stored
  3b. `od-master boot NET-lss.toml`    the same network with `lss = true` on each node: the
     LSS step (node-IDs given, boot-ups waited for), then the boot (identity, writes, start)
  4. python-canopen `LssMaster.fast_scan()` (its default 0.5 s answer timeout), each found
     drive given a node-ID so that the next scan finds the next one

Each od-master run starts from fresh drives. Prints wall time and LSS frames for each.
Usage: scripts/bench_lss.py [--skip-python] [--rounds N] (run from the repository root, after
`cargo build -p drive --bin drive-sim -p od-master-cli`; OD_MASTER=path and DRIVE_SIM=path run
other builds, e.g. older ones, for a before/after on the same machine).
"""

import os
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SIM = os.environ.get("DRIVE_SIM", os.path.join(ROOT, "target/debug/drive-sim"))
MASTER = os.environ.get("OD_MASTER", os.path.join(ROOT, "target/debug/od-master"))
EDS = os.path.join(ROOT, "devices/camozzi-drvi.eds")
SERIALS = [1001, 1002, 1003]


def start(args, ready):
    p = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    while True:
        line = p.stdout.readline()
        if not line:
            raise SystemExit(f"{args[1]} did not start")
        if line.startswith(ready):
            return p, line[len(ready):].strip()


def rig():
    hub, addr = start([SIM, "hub", "--listen", "127.0.0.1:0", "-q"], "listening on ")
    args = [SIM, "run"]
    for s in SERIALS:
        args += ["--device", "drvi", "--node-id", "none", "--serial", str(s)]
    drives, _ = start(args + ["--bus", f"tcp://{addr}/can0"], "running on ")
    time.sleep(0.3)
    return hub, drives, addr


def stop(*ps):
    for p in ps:
        p.terminate()
        p.wait()


def master(addr, *args):
    t = time.monotonic()
    out = subprocess.run([MASTER, "--bus", f"socketcand://{addr}/can0", *args], capture_output=True, text=True)
    return time.monotonic() - t, out


def network(dir, lss=False):
    path = os.path.join(dir, "three-drvi-lss.toml" if lss else "three-drvi.toml")
    with open(path, "w") as f:
        f.write("[network]\nbaud_rate = 1000\n")
        for i, s in enumerate(SERIALS):
            f.write(f'\n[nodes.axis{i}]\ndevice = "{EDS}"\nnode_id = {2 + i}\nserial = {s}\n')
            if lss:
                f.write("lss = true\n")
    return path


def rounds():
    if "--rounds" in sys.argv:
        return int(sys.argv[sys.argv.index("--rounds") + 1])
    return 1


def main():
    with tempfile.TemporaryDirectory() as dir:
        net = network(dir)
        marked = network(dir, lss=True)
        for _ in range(rounds()):
            for name, args in [("full scan", ["lss", "scan"]), ("EDS-narrowed scan", ["--eds", EDS, "lss", "scan"])]:
                hub, drives, addr = rig()
                dt, out = master(addr, *args)
                stop(drives, hub)
                print(f"od-master {name}: {dt:.3f} s: {out.stdout.strip().splitlines()[-1] if out.stdout else out.stderr.strip()}")
            hub, drives, addr = rig()
            dt, out = master(addr, "lss", "assign", net)
            stop(drives, hub)
            print(f"od-master lss assign (found and assigned nodes 2, 3, 4, stored): {dt:.3f} s: "
                  + "; ".join(out.stdout.strip().splitlines()) + out.stderr.strip())
            hub, drives, addr = rig()
            dt, out = master(addr, "boot", marked)
            stop(drives, hub)
            print(f"od-master boot, nodes marked lss = true (assigned, boot-ups, then booted): {dt:.3f} s: "
                  + "; ".join(out.stdout.strip().splitlines()) + out.stderr.strip())
        if "--skip-python" in sys.argv:
            return
        import canopen

        hub, drives, addr = rig()
        host, port = addr.rsplit(":", 1)
        network_ = canopen.Network()
        network_.connect(interface="socketcand", host=host, port=int(port), channel="can0")
        time.sleep(0.3)
        lss = network_.lss
        sent = [0]
        send = network_.send_message

        def counting(can_id, data, remote=False):
            if can_id == 0x7E5:
                sent[0] += 1
            return send(can_id, data, remote)

        network_.send_message = counting
        t = time.monotonic()
        found = []
        for node in range(2, 5):
            ok, ids = lss.fast_scan()
            if not ok:
                break
            found.append(ids)
            lss.configure_node_id(node)
            lss.send_switch_state_global(lss.WAITING_STATE)
        dt = time.monotonic() - t
        network_.disconnect()
        stop(drives, hub)
        print(f"python-canopen fast_scan x3 (+ configure, switch): {dt:.3f} s, {sent[0]} LSS frames, found serials "
              + str([i[3] for i in found]))


if __name__ == "__main__":
    main()
