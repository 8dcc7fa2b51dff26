"""PDOs with python-canopen's pdo API: reading the configuration, remapping and saving it over
SDO, and SYNC-driven exchange (TPDO values on SYNC, RPDO values applied at SYNC) with a
simulated DRVI; and a remapping stored with 1010h surviving a new process (--state-dir)."""

import time

import pytest

NODE = 2


def start_drvi(start_drive_sim, canopen_network, device_eds, *extra):
    sim = start_drive_sim("run", "--device", "drvi", "--node-id", NODE, *extra, "--listen", "127.0.0.1:0")
    network = canopen_network(sim)
    node = network.add_node(NODE, str(device_eds["drvi"]))
    return sim, network, node


@pytest.fixture
def drvi(start_drive_sim, canopen_network, device_eds):
    return start_drvi(start_drive_sim, canopen_network, device_eds)


def mapping(pdo_map):
    return [(v.index, v.subindex, v.length) for v in pdo_map.map]


def test_read_the_default_configuration(drvi):
    _, _, node = drvi
    node.tpdo.read()
    node.rpdo.read()
    t1 = node.tpdo[1]
    assert (t1.cob_id, t1.enabled, t1.trans_type, t1.event_timer) == (0x182, True, 255, 100)
    assert mapping(t1) == [(0x6041, 0, 16)]
    assert node.tpdo[2].enabled is False and mapping(node.tpdo[2]) == []
    r1 = node.rpdo[1]
    assert (r1.cob_id, r1.enabled, r1.trans_type) == (0x202, True, 255)
    assert mapping(r1) == [(0x6040, 0, 16)]


def remap(node):
    """TPDO1: statusword + position actual value on every SYNC; TPDO2: velocity actual value
    every second SYNC; RPDO1: controlword + modes of operation, applied at SYNC."""
    node.tpdo.read()
    node.rpdo.read()
    t1 = node.tpdo[1]
    t1.clear()
    t1.add_variable(0x6041)
    t1.add_variable(0x6064)
    t1.trans_type = 1
    t1.event_timer = 0
    t1.enabled = True
    t2 = node.tpdo[2]
    t2.clear()
    t2.add_variable(0x606C)
    t2.trans_type = 2
    t2.cob_id = 0x282
    t2.enabled = True
    r1 = node.rpdo[1]
    r1.clear()
    r1.add_variable(0x6040)
    r1.add_variable(0x6060)
    r1.trans_type = 1
    r1.enabled = True
    node.tpdo.save()
    node.rpdo.save()


def test_remap_and_save_writes_the_dictionary(drvi):
    _, _, node = drvi
    remap(node)
    assert [node.sdo[0x1A00][i].raw for i in range(3)] == [2, 0x60410010, 0x60640020]
    assert node.sdo[0x1800][1].raw == 0x182 and node.sdo[0x1800][2].raw == 1
    assert [node.sdo[0x1A01][i].raw for i in range(2)] == [1, 0x606C0020]
    assert node.sdo[0x1801][1].raw == 0x282 and node.sdo[0x1801][2].raw == 2
    assert [node.sdo[0x1600][i].raw for i in range(3)] == [2, 0x60400010, 0x60600008]
    assert node.sdo[0x1400][2].raw == 1
    # What the device reports reads back into the same python-canopen configuration.
    node.tpdo.read()
    assert mapping(node.tpdo[1]) == [(0x6041, 0, 16), (0x6064, 0, 32)]
    assert mapping(node.tpdo[2]) == [(0x606C, 0, 32)]


def test_sync_driven_exchange(drvi, frames):
    _, network, node = drvi
    remap(node)
    seen = frames(network, 0x182, 0x282)
    node.nmt.state = "OPERATIONAL"
    seen.none(within=0.2)  # synchronous TPDOs wait for SYNC
    counts = []
    for k in range(1, 7):
        seen.clear()
        network.sync.transmit()
        first = seen.next(timeout=2)
        if k % 2:
            seen.none(within=0.05)
        else:
            seen.next(0x282, timeout=2)
        counts.append(len(seen.all(0x282)))
        assert first[1] == 0x182
        assert first[2] == (0x0240).to_bytes(2, "little") + (0).to_bytes(4, "little", signed=True)
    assert counts == [0, 1, 0, 1, 0, 1]  # TPDO2: every second SYNC

    # python-canopen decodes the TPDO it receives.
    received = []
    node.tpdo[1].add_callback(lambda pdo: received.append((pdo[0].raw, pdo[1].raw)))
    network.sync.transmit()
    deadline = time.monotonic() + 2
    while not received and time.monotonic() < deadline:
        time.sleep(0.01)
    assert received == [(0x0240, 0)]

    # RPDO of type 1: held until the next SYNC, then applied before the TPDOs are sampled.
    r1 = node.rpdo[1]
    r1[0].raw = 0x0006  # controlword: shutdown
    r1[1].raw = 1  # profile position mode
    seen.clear()
    r1.transmit()
    time.sleep(0.1)
    assert node.sdo[0x6040].raw == 0
    network.sync.transmit()
    tpdo = seen.next(0x182, timeout=2)[2]
    assert int.from_bytes(tpdo[0:2], "little") == 0x0231  # Ready to switch on, already in this SYNC's TPDO
    assert node.sdo[0x6040].raw == 0x0006
    assert node.sdo[0x6060].raw == 1
    assert node.sdo[0x6061].raw == 1  # modes of operation display follows


def test_event_driven_rpdo_and_tpdo(drvi, frames):
    _, network, node = drvi
    seen = frames(network, 0x182)
    node.nmt.state = "OPERATIONAL"
    assert seen.next(0x182)[2] == b"\x40\x02"
    node.rpdo.read()
    # Default RPDO1 (type 255): applied at once; TPDO1 (type 255) sent on the change.
    node.rpdo[1][0].raw = 0x0006
    seen.clear()
    node.rpdo[1].transmit()
    assert seen.next(0x182)[2] == b"\x31\x02"
    # The 100 ms event timer repeats it.
    t0 = seen.next(0x182)[0]
    t1 = seen.next(0x182)[0]
    assert 0.05 < t1 - t0 < 0.3


def test_a_stored_mapping_survives_a_new_process(start_drive_sim, canopen_network, device_eds, tmp_path):
    state = tmp_path / "state"
    sim, _, node = start_drvi(start_drive_sim, canopen_network, device_eds, "--state-dir", state)
    remap(node)
    node.store()  # 1010h sub 1 = "save"
    assert sim.stop() == 0
    # The three 1010h areas (one file, replaced as one), and the data the DRVI keeps over a
    # power cycle (5.0.3: the position).
    assert sorted(p.name for p in state.iterdir()) == ["drvi-node2.params", "drvi-node2.retained"]
    _, _, again = start_drvi(start_drive_sim, canopen_network, device_eds, "--state-dir", state)
    again.tpdo.read()
    assert mapping(again.tpdo[1]) == [(0x6041, 0, 16), (0x6064, 0, 32)]
    assert again.tpdo[1].trans_type == 1
    # 1011h "load": defaults after the next reset.
    again.restore()
    again.nmt.send_command(0x81)
    time.sleep(0.2)
    again.tpdo.read()
    assert mapping(again.tpdo[1]) == [(0x6041, 0, 16)]
