"""python-can's `slcan` interface (a host implementation this project did not write, over
pyserial) opens the pseudo-terminal of `drive-sim slcan`, the simulated CANable, and
python-canopen drives the simulated DRVI behind it: SDO (expedited and segmented), NMT,
heartbeat and a TPDO. Also: the binaries as built have SocketCAN on Linux (no feature to ask
for it; this machine has no CAN interface, so the check is that opening one fails in the
socketcan transport, naming the interface, not for want of a feature)."""

import subprocess
import sys

import pytest

NODE = 2


@pytest.fixture(params=["canable", "lawicel"])
def slcan_network(request, start_drive_sim, device_eds):
    pytest.importorskip("serial", reason="python-can's slcan interface needs pyserial (requirements-test.txt)")
    import canopen

    sim = start_drive_sim(
        "slcan", "--device", "drvi", "--node-id", str(NODE), "--firmware", request.param, ready="slcan on "
    )
    network = canopen.Network()
    network.connect(interface="slcan", channel=sim.address, bitrate=1000000, sleep_after_open=0)
    node = canopen.RemoteNode(NODE, str(device_eds["drvi"]))
    # python-can's slcan reads byte by byte in Python: give it time on a loaded machine.
    node.sdo.RESPONSE_TIMEOUT = 2.0
    network.add_node(node)
    yield network, node
    network.disconnect()


def test_python_canopen_drives_the_drvi_through_the_simulated_adapter(slcan_network, wait_until):
    network, node = slcan_network
    # SDO: expedited read and write, a segmented read.
    assert node.sdo.upload(0x1000, 0)[:2] == (402).to_bytes(2, "little")
    node.sdo.download(0x6083, 0, (12345).to_bytes(4, "little"))
    assert int.from_bytes(node.sdo.upload(0x6083, 0), "little") == 12345
    name = node.sdo.upload(0x1008, 0)
    assert name.decode().strip(), name
    # NMT and heartbeat: 100 ms heartbeats, the state followed through a start.
    node.sdo.download(0x1017, 0, (100).to_bytes(2, "little"))
    node.nmt.wait_for_heartbeat(timeout=2.0)
    assert node.nmt.state == "PRE-OPERATIONAL"
    node.nmt.state = "OPERATIONAL"
    wait_until(lambda: node.nmt.wait_for_heartbeat(timeout=1.0) == "OPERATIONAL", 3.0, what="OPERATIONAL")
    # PDO: the default TPDO1 (statusword, 100 ms event timer) arrives while operational.
    node.tpdo.read()
    tpdo = node.tpdo[1]
    assert tpdo.cob_id == 0x180 + NODE
    tpdo.wait_for_reception(timeout=2.0)
    assert tpdo["Statusword"].raw is not None
    node.nmt.state = "PRE-OPERATIONAL"


def test_the_binaries_have_socketcan_built_in(drive_sim_binary):
    if not sys.platform.startswith("linux"):
        pytest.skip("SocketCAN is Linux's")
    result = subprocess.run(
        [str(drive_sim_binary), "send", "--bus", "socketcan://nosuchcan7", "000#0100"],
        capture_output=True, text=True, timeout=30,
    )
    assert result.returncode != 0
    assert "nosuchcan7" in result.stderr and "does it exist" in result.stderr, result.stderr
    assert "feature" not in result.stderr, result.stderr


def test_the_simulated_adapter_on_a_hub_reaches_the_devices_there(start_drive_sim, device_eds):
    """`drive-sim slcan --bus socketcand://...`: the adapter joins a hub, where the devices of
    another drive-sim run; python-can's slcan reaches them through it."""
    pytest.importorskip("serial", reason="python-can's slcan interface needs pyserial (requirements-test.txt)")
    import canopen

    devices = start_drive_sim("run", "--device", "drvi", "--node-id", "5", "--listen", "127.0.0.1:0")
    adapter = start_drive_sim(
        "slcan", "--bus", f"socketcand://{devices.address}/can0", "--firmware", "lawicel", ready="slcan on "
    )
    network = canopen.Network()
    network.connect(interface="slcan", channel=adapter.address, bitrate=500000, sleep_after_open=0)
    try:
        node = canopen.RemoteNode(5, str(device_eds["drvi"]))
        node.sdo.RESPONSE_TIMEOUT = 2.0
        network.add_node(node)
        assert node.sdo.upload(0x1000, 0)[:2] == (402).to_bytes(2, "little")
        assert int.from_bytes(node.sdo.upload(0x1018, 1), "little") != 0
    finally:
        network.disconnect()
