"""`od-master boot` end to end: networks/example.toml (and the DCFs `odgen dcf --network` writes
for it) booted on three `drive-sim run` processes behind one `drive-sim hub`, then checked by
python-canopen as a second master on the same hub: the PDO mappings read back from each drive
are the description's, the heartbeats say Operational, and the drives send their TPDOs.

OD_MASTER and ODGEN point at the binaries (otherwise target/debug/)."""

import json
import os
import subprocess
from pathlib import Path

import pytest

from conftest import ROOT, missing

EXAMPLE = ROOT / "networks" / "example.toml"

# node id -> device; the mappings networks/example.toml gives each node.
DRIVES = {2: "drvi", 3: "drcs", 4: "akd"}
TPDO = {1: [0x6041, 0x6064], 2: [0x6061, 0x606C]}
RPDO = {
    2: {1: [0x6040, 0x607A], 2: [0x6060, 0x60FF]},
    3: {1: [0x6040, 0x607A], 2: [0x6060, 0x60FF]},
    4: {1: [0x6040, 0x60FF], 2: [0x6060, 0x607A]},
}


def binary(env, name):
    path = Path(os.environ.get(env) or ROOT / "target" / "debug" / name)
    if not path.is_file():
        missing(f"{name} binary not found at {path} (set {env} or run `cargo build --workspace --bins`)")
    return str(path)


@pytest.fixture
def three(start_drive_sim, canopen_network, device_eds):
    import canopen

    hub = start_drive_sim("hub", "--listen", "127.0.0.1:0", "--quiet")
    for node_id, device in DRIVES.items():
        start_drive_sim("run", "--device", device, "--node-id", node_id, "--bus", hub.bus_spec(), ready="running on ")
    network = canopen_network(hub)
    nodes = {}
    for node_id, device in DRIVES.items():
        node = canopen.RemoteNode(node_id, str(device_eds[device]))
        network.add_node(node)
        nodes[node_id] = node
    return f"socketcand://{hub.address}/can0", nodes


def boot(bus, *files):
    return subprocess.run([binary("OD_MASTER", "od-master"), "--bus", bus, "--json", "boot", *map(str, files)],
                          capture_output=True, text=True, timeout=120)


def check_booted(out, nodes, wait_until):
    assert out.returncode == 0, out.stderr
    lines = [json.loads(line) for line in out.stdout.splitlines()]
    assert [(l["name"], l["node"]) for l in lines] == [("x_axis", 2), ("y_axis", 3), ("z_axis", 4)]
    for l in lines:
        assert l["ok"] and l["started"] and l["written"] == l["planned"] > 0, l
    for node_id, node in nodes.items():
        # The heartbeat boot configured (1017h = 100 ms) reports the state.
        wait_until(lambda n=node: n.nmt.state == "OPERATIONAL", timeout=3, what=f"node {node_id} operational")
        node.tpdo.read(from_od=False)
        node.rpdo.read(from_od=False)
        for n, mapped in TPDO.items():
            assert [v.od.index for v in node.tpdo[n].map] == mapped, f"node {node_id} TPDO {n}"
            assert node.tpdo[n].enabled, f"node {node_id} TPDO {n}"
        for n, mapped in RPDO[node_id].items():
            assert [v.od.index for v in node.rpdo[n].map] == mapped, f"node {node_id} RPDO {n}"
        assert node.sdo[0x1800][5].raw == 20, f"node {node_id} TPDO 1 event timer"
    # The drives send TPDO 1 every 20 ms now that they are operational.
    node = nodes[2]
    node.tpdo[1].wait_for_reception(timeout=2)
    assert node.tpdo[1]["Statusword"].raw is not None


def test_od_master_boots_the_example_network(three, wait_until):
    bus, nodes = three
    check_booted(boot(bus, EXAMPLE), nodes, wait_until)


def test_od_master_boots_the_dcfs_odgen_writes(three, wait_until, tmp_path):
    bus, nodes = three
    made = subprocess.run([binary("ODGEN", "odgen"), "dcf", "--network", str(EXAMPLE), "-o", str(tmp_path)],
                          capture_output=True, text=True, timeout=120)
    assert made.returncode == 0, made.stderr
    dcfs = [tmp_path / f"{name}.dcf" for name in ("x_axis", "y_axis", "z_axis")]
    check_booted(boot(bus, *dcfs), nodes, wait_until)


def test_the_network_boot_example_boots_and_moves_the_drives_behind_the_hub(three, wait_until):
    """examples/network-boot (built by `cargo build --workspace --bins`; NETWORK_BOOT points at
    it otherwise) against the same drive-sim processes: the boot, then each axis homed and moved
    through its generated client in its units, its position in units checked by the example
    against 6064h and the scaling objects, and here again from python-canopen's own reads."""
    bus, nodes = three
    out = subprocess.run([binary("NETWORK_BOOT", "network-boot"), "--bus", bus, str(EXAMPLE)], capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    assert lines[:3] == ["x_axis (node 2): 29 writes, started", "y_axis (node 3): 28 writes, started",
                         "z_axis (node 4): 28 writes, started"], out.stdout
    for line in lines[3:6]:
        name, _, rest = line.partition(": ")
        assert int(rest.split()[0]) >= 5, line  # every 20 ms at least, for 200 ms
    assert lines[6:] == [
        "x_axis (node 2): at 90 deg; 6064h = 9000, 2001h = 1/1, 0.01 deg; back at 0",
        "y_axis (node 3): at 20 mm; 6064h = 20, 2001h = 1/1, mm; back at 0",
        "z_axis (node 4): at 1 user units; 6064h = 1, 6092h = 1/1, 1 motor turns; back at 0",
    ], out.stdout
    # The example's conversions, redone from the EDS objects python-canopen reads: the DRVI in
    # 0.01 deg (2014h = 0, only motor) and the DRCS in mm, both times 2001h den/num; the AKD in
    # user units, one per 6092h feed/shaft revolutions of the motor.
    drvi, drcs, akd = nodes[2], nodes[3], nodes[4]
    assert drvi.sdo[0x2014].raw == 0
    for node in (drvi, drcs):
        assert (node.sdo[0x2001][1].raw, node.sdo[0x2001][2].raw) == (1, 1)
    assert (akd.sdo[0x6092][1].raw, akd.sdo[0x6092][2].raw) == (1, 1)
    for node_id, node in nodes.items():
        wait_until(lambda n=node: n.nmt.state == "OPERATIONAL", timeout=3, what=f"node {node_id} operational")
        assert node.sdo[0x6064].raw == 0, f"node {node_id} back at 0"
        assert node.sdo[0x6060].raw == 1, f"node {node_id} left in profile position mode"
