"""`od-master run` supervising a device the project did not write: python-canopen's LocalNode
(with the DRCS's EDS) as node 5 on a `drive-sim hub`. `od-master run` boots it (identity, the
description's values, start); the test then makes the node forget its configuration and sends
its boot-up message, as a node that restarted at run time does: the supervisor configures it
again with the description's values.

And the three drives of networks/example.toml, each in a `drive-sim run` process of its own:
one process killed with SIGKILL and started again, supervised by `od-master run`.

OD_MASTER points at the binary (otherwise target/debug/od-master)."""

import json
import os
import queue
import signal
import struct
import subprocess
import threading
import time
from pathlib import Path

from conftest import ROOT, missing

DRCS_EDS = ROOT / "devices" / "camozzi-drcs.eds"


def binary(env, name):
    path = Path(os.environ.get(env) or ROOT / "target" / "debug" / name)
    if not path.is_file():
        missing(f"{name} binary not found at {path} (set {env} or run `cargo build --workspace --bins`)")
    return str(path)


def test_a_local_node_that_reboots_is_configured_again(start_drive_sim, canopen_network, tmp_path, wait_until):
    import canopen

    hub = start_drive_sim("hub", "--listen", "127.0.0.1:0", "--quiet")
    network = canopen_network(hub)
    local = canopen.LocalNode(5, str(DRCS_EDS))
    network.add_node(local)
    description = tmp_path / "local.toml"
    description.write_text(
        f"""[network]
baud_rate = 1000

[nodes.p]
device = "{DRCS_EDS}"
node_id = 5
tpdo1 = ["statusword"]

[nodes.p.parameters]
producer_heartbeat_time = 100
"""
    )
    proc = subprocess.Popen(
        [binary("OD_MASTER", "od-master"), "--bus", f"socketcand://{hub.address}/can0", "--json", "run", str(description)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    lines = queue.Queue()
    threading.Thread(target=lambda: [lines.put(json.loads(l)) for l in proc.stdout], daemon=True).start()

    def expect(event, timeout=10):
        seen = []
        while True:
            try:
                line = lines.get(timeout=timeout)
            except queue.Empty:
                raise AssertionError(f"no {event} line; seen {seen}; stderr {proc.stderr.read() if proc.poll() is not None else ''}")
            if line["event"] == event:
                return line
            seen.append(line)

    try:
        booted = expect("booted")
        assert booted["node"] == 5 and booted["writes"] > 0, booted
        assert local.sdo[0x1017].raw == 100
        wait_until(lambda: local.nmt.state == "OPERATIONAL", timeout=3, what="node 5 operational")
        # The node restarts: its configuration back to the EDS defaults, then its boot-up.
        local.sdo[0x1017].raw = 0
        local.nmt.state = "PRE-OPERATIONAL"
        network.send_message(0x705, [0x00])
        rebooted = expect("rebooted")
        assert rebooted["node"] == 5, rebooted
        done = expect("reconfigured")
        assert done["node"] == 5 and done["writes"] == booted["writes"], done
        assert local.sdo[0x1017].raw == 100
        wait_until(lambda: local.nmt.state == "OPERATIONAL", timeout=3, what="node 5 operational again")
    finally:
        proc.send_signal(signal.SIGINT)
        code = proc.wait(timeout=10)
    assert code == 0, proc.stderr.read()


# y_axis (the DRCS, node 3) of networks/example.toml: what `od-master run` configures, read back
# after the first boot and after the process was killed and started again.
Y_OBJECTS = [
    (0x1017, 0),
    (0x1400, 1), (0x1400, 2), (0x1401, 1), (0x1401, 2),
    (0x1600, 0), (0x1600, 1), (0x1600, 2), (0x1601, 0), (0x1601, 1), (0x1601, 2),
    (0x1800, 1), (0x1800, 2), (0x1800, 5), (0x1801, 1), (0x1801, 2),
    (0x1A00, 0), (0x1A00, 1), (0x1A00, 2), (0x1A01, 0), (0x1A01, 1), (0x1A01, 2),
    (0x6060, 0),
]
SYNC_PERIOD = 0.01
# The drives not killed get a set-point before every SYNC, as from a CSP master: target position
# (607Ah) in x_axis's RPDO 1 (controlword, target position) and z_axis's RPDO 2 (mode, target
# position); each echoes its target in a TPDO 3 the test maps (607Ah, after every SYNC).
SETPOINT_RPDO = {2: (0x202, lambda v: struct.pack("<Hi", 0, v)), 4: (0x304, lambda v: struct.pack("<bi", 3, v))}


def test_a_drive_process_killed_and_started_again_is_configured_again_and_the_others_miss_no_sync(
        start_drive_sim, canopen_network, can_bus, wait_until):
    """The three drives of networks/example.toml, each in a `drive-sim run` process of its own
    on a hub, supervised by `od-master run`. The DRCS's process is killed with SIGKILL (no
    frame more, its configuration gone with it) and started again: the supervisor reports it
    lost, then its boot-up, configures it with the same writes as at the first boot, and its
    PDO mappings, heartbeat time and mode read back as after the first boot. Meanwhile the
    DRVI and the AKD answer every SYNC (the test's, every 10 ms) with their TPDO 2, and take the
    set-point (target position, by RPDO) sent before each SYNC: their TPDO 3 after each SYNC
    echoes the set-point in force at that SYNC."""
    import canopen

    hub = start_drive_sim("hub", "--listen", "127.0.0.1:0", "--quiet")
    drives = {}
    for device, node_id in (("drvi", 2), ("drcs", 3), ("akd", 4)):
        drives[node_id] = start_drive_sim(
            "run", "--device", device, "--node-id", node_id, "--bus", hub.bus_spec(), ready="running on ")
    proc = subprocess.Popen(
        [binary("OD_MASTER", "od-master"), "--bus", f"socketcand://{hub.address}/can0", "--json", "run",
         str(ROOT / "networks" / "example.toml")],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    lines = queue.Queue()
    threading.Thread(target=lambda: [lines.put(json.loads(l)) for l in proc.stdout], daemon=True).start()

    def expect(event, node, timeout=10):
        seen = []
        while True:
            try:
                line = lines.get(timeout=timeout)
            except queue.Empty:
                raise AssertionError(f"no {event} line for node {node}; seen {seen}")
            if line["event"] == event and line.get("node") == node:
                return line, seen
            seen.append(line)

    network = canopen_network(hub)
    y = network.add_node(3, str(ROOT / "devices" / "camozzi-drcs.eds"))

    def read_back():
        return {(i, s): bytes(y.sdo.upload(i, s)) for i, s in Y_OBJECTS}

    # TPDO 3 of the drives not killed: their target position, after every SYNC (CiA 301's
    # order: disabled, mapping emptied, filled, counted, transmission type, enabled).
    def map_echo(node_id, eds):
        node = network.add_node(node_id, str(ROOT / "devices" / eds))
        cob = 0x380 + node_id
        for index, sub, value, size in ((0x1802, 1, 0x80000000 | cob, 4), (0x1A02, 0, 0, 1),
                                         (0x1A02, 1, 0x607A0020, 4), (0x1A02, 0, 1, 1),
                                         (0x1802, 2, 1, 1), (0x1802, 1, cob, 4)):
            node.sdo.download(index, sub, value.to_bytes(size, "little"))

    # SYNC every 10 ms, each after a set-point to x and z (a new target each time); the
    # set-points in force at each SYNC, in order.
    in_force = {2: [], 4: []}
    cycling = threading.Event()

    def cycle():
        k, at = 0, time.monotonic()
        while cycling.is_set():
            k += 1
            for node_id, (cob, pack) in SETPOINT_RPDO.items():
                value = (1 if node_id == 2 else -1) * (1000 + k)
                network.send_message(cob, pack(value))
                in_force[node_id].append(value)
            network.send_message(0x080, b"")
            at += SYNC_PERIOD
            time.sleep(max(0.0, at - time.monotonic()))

    cycler = threading.Thread(target=cycle, daemon=True)

    # Every frame on the bus, in the hub's order, from another connection.
    listener = can_bus(hub)
    frames = []
    listening = threading.Event()
    listening.set()

    def listen():
        while listening.is_set():
            msg = listener.recv(timeout=0.1)
            if msg is not None:
                frames.append((msg.arbitration_id, bytes(msg.data), time.monotonic()))

    reader = threading.Thread(target=listen, daemon=True)
    try:
        booted = {}
        for node in (2, 3, 4):
            booted[node], _ = expect("booted", node)
        wait_until(lambda: y.nmt.state == "OPERATIONAL", timeout=3, what="node 3 operational")
        first = read_back()
        assert first[(0x1017, 0)] == (100).to_bytes(2, "little"), first
        assert first[(0x1A01, 0)] == bytes([2]), first

        map_echo(2, "camozzi-drvi.eds")
        map_echo(4, "kollmorgen-akd.eds")
        reader.start()
        cycling.set()
        cycler.start()
        time.sleep(0.2)
        killed = drives.pop(3)
        killed.process.send_signal(signal.SIGKILL)
        killed.process.wait(timeout=5)
        start_drive_sim.started.remove(killed)
        killed.exit_code = killed.process.returncode
        expect("lost", 3, timeout=3)
        drives[3] = start_drive_sim(
            "run", "--device", "drcs", "--node-id", 3, "--bus", hub.bus_spec(), ready="running on ")
        _, between = expect("rebooted", 3)
        assert not [e for e in between if e.get("node") in (2, 4)], between
        done, between = expect("reconfigured", 3)
        assert done["writes"] == booted[3]["writes"], (done, booted[3])
        assert not [e for e in between if e.get("node") in (2, 4)], between
        time.sleep(0.2)
        cycling.clear()
        cycler.join(timeout=2)
        time.sleep(0.05)
        listening.clear()
        reader.join(timeout=2)

        wait_until(lambda: y.nmt.state == "OPERATIONAL", timeout=3, what="node 3 operational again")
        again = read_back()
        assert again == first, {k: (first[k].hex(), again[k].hex()) for k in first if first[k] != again[k]}

        # Every SYNC answered by the DRVI and the AKD with one TPDO 2 (transmission type 1: only
        # a SYNC makes them send it), while the DRCS was killed, silent, started and configured.
        syncs = [i for i, (cob, _, _) in enumerate(frames) if cob == 0x080]
        assert len(syncs) > 50, f"{len(syncs)} SYNCs"
        after_first = [cob for cob, _, _ in frames[syncs[0]:]]
        answered = {cob: after_first.count(cob) for cob in (0x282, 0x284)}
        # (On failure: the SYNC periods without exactly one of each, seconds after the first.)
        odd = []
        for a, b in zip(syncs, syncs[1:] + [len(frames)]):
            window = [f"{cob:03X}h" for cob, _, _ in frames[a + 1:b] if cob in (0x282, 0x284)]
            if window.count("282h") != 1 or window.count("284h") != 1:
                odd.append((round(frames[a][2] - frames[syncs[0]][2], 4), window))
        assert answered == {0x282: len(syncs), 0x284: len(syncs)}, f"{answered} for {len(syncs)} SYNCs: {odd}"
        # Every set-point taken: the n-th TPDO 3 of each carries the set-point sent before the
        # n-th SYNC (the listener saw every SYNC the test sent: the same number).
        assert len(syncs) == len(in_force[2]), (len(syncs), len(in_force[2]))
        for node_id in (2, 4):
            echoed = [struct.unpack("<i", data[:4])[0] for cob, data, _ in frames[syncs[0]:] if cob == 0x380 + node_id]
            wrong = [(n, want, got) for n, (want, got) in enumerate(zip(in_force[node_id], echoed)) if want != got]
            assert len(echoed) == len(syncs) and not wrong, \
                f"node {node_id}: {len(echoed)} echoes for {len(syncs)} SYNCs; (SYNC, sent, echoed) differing: {wrong[:10]}"
        # The new process's boot-up went out on the bus.
        assert any(cob == 0x703 and data == b"\x00" for cob, data, _ in frames)
    finally:
        listening.clear()
        cycling.clear()
        proc.send_signal(signal.SIGINT)
        code = proc.wait(timeout=10)
    assert code == 0, proc.stderr.read()
