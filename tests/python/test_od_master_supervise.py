"""`od-master run` supervising a device the project did not write: python-canopen's LocalNode
(with the DRCS's EDS) as node 5 on a `drive-sim hub`. `od-master run` boots it (identity, the
description's values, start); the test then makes the node forget its configuration and sends
its boot-up message, as a node that restarted at run time does: the supervisor configures it
again with the description's values.

OD_MASTER points at the binary (otherwise target/debug/od-master)."""

import json
import os
import queue
import signal
import subprocess
import threading
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
