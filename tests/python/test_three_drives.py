"""Three drives on one hub at once: a DRVI (node 2), a DRCS (node 3) and an AKD (node 4), each
its own `drive-sim run --bus` process joined to one `drive-sim hub`, driven together by one
python-canopen master: identity by SDO, NMT start of all nodes with one broadcast, the CiA 402
state machine to Operation enabled, homing on the current position, then profile velocity on
all three axes at the same time, halt, and a clean stop.
"""

import pytest

# node id -> (device, vendor id from its manual, homing method "on the current position")
DRIVES = {
    2: ("drvi", 0x97, 37),
    3: ("drcs", 0x151, 37),
    4: ("akd", 0x6A, 35),
}


@pytest.fixture
def three(start_drive_sim, canopen_network, device_eds):
    import canopen

    hub = start_drive_sim("hub", "--listen", "127.0.0.1:0")
    for node_id, (device, _, _) in DRIVES.items():
        start_drive_sim("run", "--device", device, "--node-id", node_id, "--bus", hub.bus_spec(), ready="running on ")
    network = canopen_network(hub)
    nodes = {}
    for node_id, (device, _, _) in DRIVES.items():
        node = canopen.RemoteNode(node_id, str(device_eds[device]))
        network.add_node(node)
        nodes[node_id] = node
    return network, nodes


def statusword(node):
    return node.sdo[0x6041].raw


def test_three_drives_share_one_hub(three, wait_until):
    network, nodes = three
    for node_id, node in nodes.items():
        assert node.sdo[0x1018][1].raw == DRIVES[node_id][1], f"vendor id of node {node_id}"

    # One NMT broadcast starts every node.
    for node in nodes.values():
        node.sdo[0x1017].raw = 50  # producer heartbeat, so the master sees each node's state
    network.nmt.send_command(0x01)
    for node_id, node in nodes.items():
        wait_until(lambda n=node: n.nmt.state == "OPERATIONAL", timeout=3, what=f"node {node_id} operational")

    # CiA 402: shutdown, switch on, enable operation, on all three.
    for command, mask, want, name in [
        (0x06, 0x6F, 0x21, "Ready to switch on"),
        (0x07, 0x6F, 0x23, "Switched on"),
        (0x0F, 0x6F, 0x27, "Operation enabled"),
    ]:
        for node in nodes.values():
            node.sdo[0x6040].raw = command
        for node_id, node in nodes.items():
            wait_until(lambda n=node: statusword(n) & mask == want, timeout=3, what=f"node {node_id}: {name}")

    # Homing on the current position (each device's method for it), all at once.
    for node_id, node in nodes.items():
        node.sdo[0x6060].raw = 6
        node.sdo[0x6098].raw = DRIVES[node_id][2]
        wait_until(lambda n=node: n.sdo[0x6061].raw == 6, timeout=2, what=f"node {node_id} in homing mode")
    for node in nodes.values():
        node.sdo[0x6040].raw = 0x1F
    for node_id, node in nodes.items():
        # bit 12 homing attained, bit 13 no homing error
        wait_until(lambda n=node: statusword(n) & 0x3400 == 0x1400, timeout=5, what=f"node {node_id} homed")
    for node in nodes.values():
        node.sdo[0x6040].raw = 0x0F

    # Profile velocity on the three axes together, then halt.
    for node_id, node in nodes.items():
        node.sdo[0x6060].raw = 3
        wait_until(lambda n=node: n.sdo[0x6061].raw == 3, timeout=2, what=f"node {node_id} in pv mode")
        node.sdo[0x6083].raw = 2000  # profile acceleration and deceleration (raw units)
        node.sdo[0x6084].raw = 2000
        node.sdo[0x60FF].raw = 1000
    for node_id, node in nodes.items():
        wait_until(lambda n=node: n.sdo[0x606C].raw > 0, timeout=5, what=f"node {node_id} moving")
    moving = {node_id: node.sdo[0x606C].raw for node_id, node in nodes.items()}
    assert all(v > 0 for v in moving.values()), moving

    for node in nodes.values():
        node.sdo[0x6040].raw = 0x010F  # halt (bit 8)
    for node_id, node in nodes.items():
        wait_until(lambda n=node: n.sdo[0x606C].raw == 0, timeout=10, what=f"node {node_id} halted")
        assert statusword(node) & 0x6F == 0x27, f"node {node_id} still enabled after halt"

    # Disable voltage on all, then stop all with one broadcast.
    for node in nodes.values():
        node.sdo[0x6040].raw = 0x00
    network.nmt.send_command(0x02)
    for node_id, node in nodes.items():
        wait_until(lambda n=node: n.nmt.state == "STOPPED", timeout=3, what=f"node {node_id} stopped")
