"""`od-master` (the command-line master) over the real `drive-sim hub` binary, with the three
simulated drives (DRVI node 2, DRCS node 3, AKD node 4) joined to it from a `drive-sim run --bus`
process, as drives on a CAN bus are: scan, read and write, NMT (checked by the drives'
heartbeats, seen by `od-master monitor`), a CiA 402 home and move of each drive with the
position it reports checked against 6064h, and a hub restart that `od-master monitor` rides
through (its bus reconnects) while the next transfer succeeds.

OD_MASTER points at the od-master binary (otherwise target/debug/od-master); DRIVE_SIM at
drive-sim (see conftest.py)."""

import json
import os
import socket
import subprocess
import time
from pathlib import Path

import pytest

from conftest import ROOT, missing

DRIVES = [("drvi", 2), ("drcs", 3), ("akd", 4)]
VENDORS = {2: 0x97, 3: 0x151, 4: 0x6A}


@pytest.fixture
def od_master():
    path = Path(os.environ.get("OD_MASTER") or ROOT / "target" / "debug" / "od-master")
    if not path.is_file():
        missing(f"od-master binary not found at {path} (set OD_MASTER or run `cargo build -p od-master-cli`)")
    return path


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start_drives(start_drive_sim, hub):
    args = ["run", "--bus", hub.bus_spec(), "--reconnect-ms", "50"]
    for device, node in DRIVES:
        args += ["--device", device, "--node-id", str(node)]
    return start_drive_sim(*args, ready="running on ")


@pytest.fixture
def bus(start_drive_sim):
    """A hub with the three drives on it; the bus address for od-master."""
    hub = start_drive_sim("hub", "--listen", "127.0.0.1:0", "--quiet")
    start_drives(start_drive_sim, hub)
    return f"socketcand://{hub.address}/can0"


def run(od_master, bus, *args, sdo_timeout=2000):
    return subprocess.run(
        [str(od_master), "--bus", bus, "--timeout", str(sdo_timeout), *args], capture_output=True, text=True, timeout=120
    )


def ok(out):
    assert out.returncode == 0, f"exit {out.returncode}\nstdout: {out.stdout}\nstderr: {out.stderr}"
    return out.stdout


def read(od_master, bus, node, obj):
    return json.loads(ok(run(od_master, bus, "--json", "read", str(node), obj)))["value"]


def test_scan_finds_the_three_drives_with_their_identity(od_master, bus):
    lines = [json.loads(line) for line in ok(run(od_master, bus, "scan", "--json")).splitlines()]
    assert [line["node"] for line in lines] == [2, 3, 4]
    for line in lines:
        assert line["vendor_id"] == VENDORS[line["node"]], line
        assert line["name"], line
        assert line["device_type"] & 0xFFFF == 402, line
    text = ok(run(od_master, bus, "scan"))
    assert [line.split(":")[0].split()[-1] for line in text.splitlines()] == ["2", "3", "4"]


def test_read_and_write_each_drive(od_master, bus):
    for _, node in DRIVES:
        # 1018h sub 1 read two ways; a write read back; a string.
        assert read(od_master, bus, node, "1018h:1") == VENDORS[node]
        assert read(od_master, bus, node, "0x1018:1") == VENDORS[node]
        for value in (1234, 4321 + node):
            ok(run(od_master, bus, "write", str(node), "6083h", f"u32:{value}"))
            assert read(od_master, bus, node, "6083h") == value
        name = ok(run(od_master, bus, "read", str(node), "1008h")).strip()
        assert name and name.isprintable()
    # An object the drive does not have: one line naming node and object, exit code 1.
    out = run(od_master, bus, "read", "3", "5FFEh")
    assert out.returncode == 1, out
    assert "node 3" in out.stderr and "5FFEh" in out.stderr, out.stderr
    # A node that is not there: a timeout, exit code 1.
    out = run(od_master, bus, "read", "9", "1000h", sdo_timeout=200)
    assert out.returncode == 1 and "node 9" in out.stderr, out


def heartbeats(od_master, bus, seconds, during):
    """Runs `od-master monitor` for `seconds` while `during()` runs; returns the heartbeat
    states seen per node, in order (consecutive repeats merged)."""
    monitor = subprocess.Popen(
        [str(od_master), "--bus", bus, "--json", "monitor", "--duration", str(seconds)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        time.sleep(0.5)
        during()
        out, err = monitor.communicate(timeout=seconds + 30)
    finally:
        monitor.kill()
    assert monitor.returncode == 0, err
    states = {}
    for line in out.splitlines():
        frame = json.loads(line)
        if frame.get("kind") == "heartbeat":
            seen = states.setdefault(frame["node"], [])
            if not seen or seen[-1] != frame["state"]:
                seen.append(frame["state"])
    return states


def test_nmt_commands_change_the_drives_states(od_master, bus):
    for _, node in DRIVES:
        ok(run(od_master, bus, "write", str(node), "1017h", "u16:50"))

    def commands():
        for command, target in [("start", "all"), ("stop", "3"), ("preop", "4"), ("start", "4")]:
            ok(run(od_master, bus, "nmt", command, target))
            time.sleep(0.4)
        # A stopped node does no SDO: a timeout naming it.
        out = run(od_master, bus, "read", "3", "1000h", sdo_timeout=300)
        assert out.returncode == 1 and "node 3" in out.stderr, out
        ok(run(od_master, bus, "nmt", "preop", "3"))
        time.sleep(0.4)

    states = heartbeats(od_master, bus, 4.5, commands)
    short = {node: [s.lower() for s in seen] for node, seen in states.items()}
    assert set(short) == {2, 3, 4}, states
    assert short[2][-1].startswith("operational"), states
    assert [s.split()[0] for s in short[3]][-3:] == ["operational", "stopped", "pre-operational"], states
    assert [s.split()[0] for s in short[4]][-3:] == ["operational", "pre-operational", "operational"], states
    # The reset commands: the node boots again and answers.
    ok(run(od_master, bus, "nmt", "reset", "2"))
    ok(run(od_master, bus, "nmt", "reset-comm", "all"))
    time.sleep(0.5)
    assert read(od_master, bus, 2, "1018h:1") == VENDORS[2]


# Each drive's "home here" method and a move in its default units (as od-master's own axis
# tests): the DRVI in 0.01 deg, the DRCS within its stroke, the AKD at 10 000 counts a turn.
AXES = [
    (2, 37, 12_000, 6_000, []),
    (3, 37, 100, 50, []),
    (4, 35, 5_000, 10_000, [("6092h:1", "u32:10000")]),
]


@pytest.mark.parametrize("node,method,target,velocity,setup", AXES, ids=["drvi", "drcs", "akd"])
def test_each_drive_homes_and_moves_and_reports_6064h(od_master, bus, node, method, target, velocity, setup):
    for obj, value in setup:
        ok(run(od_master, bus, "write", str(node), obj, value))
    ok(run(od_master, bus, "nmt", "start", str(node)))
    ok(run(od_master, bus, "axis", str(node), "enable"))
    out = ok(run(od_master, bus, "axis", str(node), "home", "--method", str(method)))
    assert out.strip() == f"homed (method {method}), position 0", out
    assert read(od_master, bus, node, "6064h") == 0
    move = ["axis", str(node), "move", "--velocity", str(velocity), "--acceleration", str(velocity)]
    out = ok(run(od_master, bus, *move, "--to", str(target), "--within", "60"))
    assert out.strip() == f"position {target}", out
    assert read(od_master, bus, node, "6064h") == target
    # Relative, back by half.
    out = ok(run(od_master, bus, *move, "--relative", "--to", str(-target // 2), "--within", "60"))
    back = target - target // 2
    assert out.strip() == f"position {back}", out
    assert read(od_master, bus, node, "6064h") == back


def test_a_restarted_hub_the_monitor_reconnects_and_the_next_transfer_succeeds(od_master, start_drive_sim):
    port = free_port()
    hub = start_drive_sim("hub", "--listen", f"127.0.0.1:{port}", "--quiet")
    start_drives(start_drive_sim, hub)
    bus = f"socketcand://127.0.0.1:{port}/can0"
    ok(run(od_master, bus, "write", "2", "6083h", "u32:1111"))
    monitor = subprocess.Popen(
        [str(od_master), "--bus", bus, "--json", "monitor", "--duration", "12"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        time.sleep(0.5)
        hub.stop()
        time.sleep(0.5)
        start_drive_sim("hub", "--listen", f"127.0.0.1:{port}", "--quiet")
        # The drives and the monitor come back on their own (with back-off); a transfer made
        # after that succeeds and the monitor sees it.
        deadline = time.monotonic() + 10
        while True:
            out = run(od_master, bus, "write", "2", "6083h", "u32:2222", sdo_timeout=300)
            if out.returncode == 0 or time.monotonic() > deadline:
                break
            time.sleep(0.2)
        ok(out)
        assert read(od_master, bus, 2, "6083h") == 2222
        out, err = monitor.communicate(timeout=40)
    finally:
        monitor.kill()
    assert monitor.returncode == 0, err
    frames = [json.loads(line) for line in out.splitlines()]
    # The write of 2222 (6083h, DE 08 00 00 little-endian from byte 4) after the restart.
    writes = [f for f in frames if f["id"] == 0x602 and f["data"].replace(" ", "").upper().startswith("23836000AE08")]
    answers = [f for f in frames if f["id"] == 0x582 and f["data"].replace(" ", "").upper().startswith("60836000")]
    assert writes and answers, out[-2000:]
