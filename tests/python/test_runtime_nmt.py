"""NMT with python-canopen as the master: boot-up, the state commands and both resets, against
simulated devices run by `drive-sim run` (the od-runtime device core over generated
dictionaries), through the socketcand hub."""

import pytest

try:
    import canopen
except ImportError:  # the fixtures skip (or fail in CI) with the reason
    canopen = None

NODE = 2
HEARTBEAT_ID = 0x700 + NODE
STATE_BYTES = {"PRE-OPERATIONAL": 0x7F, "OPERATIONAL": 0x05, "STOPPED": 0x04}


@pytest.fixture
def drvi(start_drive_sim, canopen_network, device_eds):
    sim = start_drive_sim("run", "--device", "drvi", "--node-id", NODE, "--listen", "127.0.0.1:0")
    network = canopen_network(sim)
    node = network.add_node(NODE, str(device_eds["drvi"]))
    return sim, network, node


def test_boot_up_is_the_first_frame_of_a_device_joining_a_bus(start_drive_sim, canopen_network, frames, device_eds):
    hub = start_drive_sim("hub", "--listen", "127.0.0.1:0")
    network = canopen_network(hub)
    seen = frames(network, 0x702, 0x703, 0x182, 0x183)
    start_drive_sim("run", "--device", "drvi", "--node-id", 2, "--bus", hub.bus_spec(), ready="running on ")
    assert seen.next(timeout=10)[1:] == (0x702, b"\x00")
    # A second device joins the same hub as its own process.
    start_drive_sim("run", "--device", "drcs", "--node-id", 3, "--bus", hub.bus_spec(), ready="running on ")
    assert seen.next(timeout=10)[1:] == (0x703, b"\x00")
    # Both are pre-operational (no PDO) and answer python-canopen.
    drvi = network.add_node(2, str(device_eds["drvi"]))
    drcs = network.add_node(3, str(device_eds["drcs"]))
    assert drvi.sdo[0x1008].raw == "DRVI"
    assert drcs.sdo[0x1008].raw == "DRCS"
    seen.none(0x182, within=0.2)


def test_state_commands_are_reflected_in_the_heartbeat(drvi, frames):
    _, network, node = drvi
    seen = frames(network, HEARTBEAT_ID)
    node.sdo[0x1017].raw = 50  # heartbeat every 50 ms
    for state in ["OPERATIONAL", "STOPPED", "PRE-OPERATIONAL", "OPERATIONAL", "PRE-OPERATIONAL"]:
        node.nmt.state = state
        seen.clear()
        # The next heartbeats carry the new state; python-canopen's NMT master agrees.
        for _ in range(2):
            assert seen.next(HEARTBEAT_ID, timeout=2)[2] == bytes([STATE_BYTES[state]])
        assert node.nmt.state == state


def test_stopped_devices_do_not_answer_sdo_and_send_no_pdo(drvi, frames):
    _, network, node = drvi
    seen = frames(network, 0x182, 0x582)
    node.nmt.state = "OPERATIONAL"
    assert seen.next(0x182)[2] == b"\x40\x02"  # TPDO1 (statusword) on entering Operational
    node.nmt.state = "STOPPED"
    seen.clear()
    node.sdo.RESPONSE_TIMEOUT = 0.3
    with pytest.raises(canopen.SdoCommunicationError):
        node.sdo[0x1000].raw
    # The TPDO1 event timer (100 ms) is silent too.
    seen.none(within=0.4)
    node.nmt.state = "PRE-OPERATIONAL"
    assert node.sdo[0x1000].raw == 0xFF7A0192


def test_reset_node_boots_up_with_every_area_back_to_defaults(drvi, frames):
    _, network, node = drvi
    seen = frames(network, HEARTBEAT_ID)
    node.sdo[0x6083].raw = 1234  # profile acceleration (application area)
    node.sdo[0x1017].raw = 40  # heartbeat (communication area)
    node.nmt.state = "OPERATIONAL"
    seen.clear()
    node.nmt.send_command(0x81)
    assert seen.next(HEARTBEAT_ID)[2] == b"\x00"  # boot-up
    assert node.sdo[0x6083].raw == 0
    assert node.sdo[0x1017].raw == 0
    seen.none(HEARTBEAT_ID, within=0.2)  # no heartbeat any more
    # Pre-operational after the reset: PDOs off, SDO on.
    assert node.sdo[0x1000].raw == 0xFF7A0192


def test_reset_communication_keeps_the_application_values(drvi, frames):
    _, network, node = drvi
    seen = frames(network, HEARTBEAT_ID)
    node.sdo[0x6083].raw = 4321
    node.sdo[0x1017].raw = 40
    seen.clear()
    node.nmt.send_command(0x82)
    assert seen.next(HEARTBEAT_ID)[2] == b"\x00"
    assert node.sdo[0x6083].raw == 4321
    assert node.sdo[0x1017].raw == 0


def test_broadcast_and_addressed_commands(start_drive_sim, canopen_network, frames, device_eds):
    sim = start_drive_sim(
        "run", "--device", "drvi", "--node-id", 2, "--device", "akd", "--node-id", 4, "--listen", "127.0.0.1:0"
    )
    network = canopen_network(sim)
    seen = frames(network, 0x702, 0x704)
    # Reset communication of all nodes (node id 0): both boot up.
    network.nmt.send_command(0x82)
    ids = sorted(seen.next(timeout=5)[1] for _ in range(2))
    assert ids == [0x702, 0x704]
    # Addressed to node 4 only.
    seen.clear()
    network.send_message(0x000, [0x81, 4])
    assert seen.next(timeout=5)[1:] == (0x704, b"\x00")
    seen.none(within=0.2)
    # A node id nobody has: nothing happens.
    network.send_message(0x000, [0x81, 5])
    seen.none(within=0.2)
