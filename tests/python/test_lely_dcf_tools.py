"""Our device files against the strictest outside checker: Lely's dcf-tools (the reference C
stack's own tools, from the Python registry, installed by scripts/venv.sh).

* `dcfchk` accepts each of our three device files, every DCF `odgen dcf` writes for them (at
  several node ids, with configured values) and the DCFs `odgen dcf --network` writes for the
  example network.
* `dcfgen` builds a master configuration from our EDS files; the concise DCF it writes for a
  node (the SDO downloads a Lely master makes when it boots the node: heartbeat, PDO
  communication and mapping) is applied to a running simulated drive over SDO by
  python-canopen, and every value reads back as written.

ODGEN points at the odgen binary (scripts/test-all.sh sets it; otherwise target/debug/odgen).
"""

import os
import struct
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import ROOT, missing

DEVICES = {
    "drvi": ROOT / "devices" / "camozzi-drvi.eds",
    "drcs": ROOT / "devices" / "camozzi-drcs.eds",
    "akd": ROOT / "devices" / "kollmorgen-akd.eds",
}


def tool(name):
    """A console script of the venv this Python runs in (dcf-tools installs `dcfchk`, `dcfgen`)."""
    path = Path(sys.executable).parent / name
    if not path.exists():
        missing(f"{name} is not installed (dcf-tools; run the tests with the python scripts/venv.sh prints)")
    return str(path)


@pytest.fixture(scope="module")
def odgen():
    path = Path(os.environ.get("ODGEN") or ROOT / "target" / "debug" / "odgen")
    if not path.is_file():
        missing(f"odgen binary not found at {path} (set ODGEN or run `cargo build -p odgen`)")
    return str(path)


def dcfchk(path, node_id=None):
    args = [tool("dcfchk")]
    if node_id is not None:
        args += ["-n", str(node_id)]
    result = subprocess.run(args + [str(path)], capture_output=True, text=True, timeout=120)
    return result.returncode, result.stdout + result.stderr


@pytest.mark.parametrize("device", sorted(DEVICES))
@pytest.mark.parametrize("node_id", [1, 5, 127])
def test_dcfchk_accepts_the_device_file(device, node_id):
    # (The files' $NODEID values need a node id to be checked.)
    code, out = dcfchk(DEVICES[device], node_id)
    assert code == 0, f"dcfchk -n {node_id} rejects {DEVICES[device].name}:\n{out}"


@pytest.mark.parametrize("device", sorted(DEVICES))
@pytest.mark.parametrize("node_id", [1, 5, 127])
def test_dcfchk_accepts_the_dcfs_odgen_writes(device, node_id, odgen, tmp_path):
    out = tmp_path / f"{device}-{node_id}.dcf"
    # A configured value too: the heartbeat producer time, which every device has.
    made = subprocess.run(
        [odgen, "dcf", "--node-id", str(node_id), "--baud", "1000", "--set", "0x1017sub0=100", str(DEVICES[device]),
         "-o", str(out)],
        capture_output=True, text=True, timeout=120,
    )
    assert made.returncode == 0, made.stderr
    code, text = dcfchk(out, node_id)
    assert code == 0, f"dcfchk rejects the DCF odgen wrote for {device} at node {node_id}:\n{text}"


def test_dcfchk_accepts_the_network_dcfs(odgen, tmp_path):
    made = subprocess.run(
        [odgen, "dcf", "--network", str(ROOT / "networks" / "example.toml"), "-o", str(tmp_path)],
        capture_output=True, text=True, timeout=120,
    )
    assert made.returncode == 0, made.stderr
    dcfs = sorted(tmp_path.glob("*.dcf"))
    assert len(dcfs) == 3
    for dcf in dcfs + sorted((ROOT / "generated" / "networks" / "example").glob("*.dcf")):
        node_id = int(next(line for line in dcf.read_text().splitlines() if line.startswith("NodeID=")).split("=")[1], 0)
        code, text = dcfchk(dcf, node_id)
        assert code == 0, f"dcfchk rejects {dcf}:\n{text}"


def read_concise_dcf(path):
    """The entries of a concise DCF (CiA 302-3): a u32 count, then per entry a u16 index, a u8
    sub-index, a u32 size and the data, little-endian."""
    data = path.read_bytes()
    (count,) = struct.unpack_from("<I", data, 0)
    at, entries = 4, []
    for _ in range(count):
        index, sub, size = struct.unpack_from("<HBI", data, at)
        at += 7
        entries.append((index, sub, data[at:at + size]))
        at += size
    assert at == len(data), "trailing bytes in the concise DCF"
    return entries


NODE = 5

# A master configuration in dcfgen's YAML: the DRVI at node 5 with a heartbeat and its first
# RPDO and TPDO remapped (controlword + modes of operation; statusword + position actual value).
DCFGEN_CONFIG = """\
master:
  node_id: 1
drvi:
  dcf: "{eds}"
  node_id: {node}
  heartbeat_producer: 500
  rpdo:
    1:
      enabled: true
      cob_id: auto
      transmission: 0xFF
      mapping:
        - {{index: 0x6040, sub_index: 0}}
        - {{index: 0x6060, sub_index: 0}}
  tpdo:
    1:
      enabled: true
      cob_id: auto
      transmission: 0xFF
      inhibit_time: 10
      mapping:
        - {{index: 0x6041, sub_index: 0}}
        - {{index: 0x6064, sub_index: 0}}
"""


def test_dcfgen_concise_dcf_is_accepted_by_a_running_drive(tmp_path, start_drive_sim, canopen_network):
    config = tmp_path / "master.yml"
    config.write_text(DCFGEN_CONFIG.format(eds=DEVICES["drvi"], node=NODE))
    made = subprocess.run([tool("dcfgen"), "-d", str(tmp_path), str(config)], capture_output=True, text=True,
                          timeout=120)
    assert made.returncode == 0, made.stdout + made.stderr
    code, text = dcfchk(tmp_path / "master.dcf", 1)
    assert code == 0, f"dcfchk rejects dcfgen's master DCF:\n{text}"
    entries = read_concise_dcf(tmp_path / "drvi.bin")
    indices = {index for index, _, _ in entries}
    assert {0x1017, 0x1400, 0x1600, 0x1800, 0x1A00} <= indices, entries

    sim = start_drive_sim("run", "--device", "drvi", "--node-id", NODE, "--listen", "127.0.0.1:0")
    network = canopen_network(sim)
    node = network.add_node(NODE, str(DEVICES["drvi"]))
    node.nmt.state = "PRE-OPERATIONAL"
    for index, sub, data in entries:
        # The same download a Lely master makes; an abort raises and fails the test.
        node.sdo.download(index, sub, data)
    # The last value written to each entry is what the drive now holds.
    final = {}
    for index, sub, data in entries:
        final[(index, sub)] = data
    for (index, sub), data in final.items():
        assert node.sdo.upload(index, sub) == data, f"0x{index:04X} sub {sub}"
    # And the drive works with it: its remapped TPDO1 (statusword, position) arrives once it
    # is operational.
    node.tpdo.read(from_od=False)
    assert [v.od.index for v in node.tpdo[1].map] == [0x6041, 0x6064]
