"""Error control and emergencies with python-canopen: the heartbeat producer (1017h) at the
period set, the heartbeat consumer (1016h) reporting a lost master by EMCY, and EMCY messages
provoked from the bus (an RPDO shorter than its mapping) with the error register, the error
history and the EMCY inhibit time.

Node guarding (100Ch/100Dh) is driven by python-canopen's own NMT master
(`start_node_guarding`): its remote frames reach the hub through the fixtures'
`RtrSocketcandBus` (python-can's stock socketcand interface drops the RTR bit). The frame-level
details (toggle bit per state, life guarding event latched until a fault reset) are also tested
in Rust, drive/tests/it/e2e_guarding.rs."""

import statistics
import time

import pytest


@pytest.fixture
def devices(start_drive_sim, canopen_network, device_eds):
    """A DRVI (node 2) and an AKD (node 4), the AKD having a heartbeat consumer (1016h)."""
    sim = start_drive_sim(
        "run", "--device", "drvi", "--node-id", 2, "--device", "akd", "--node-id", 4, "--listen", "127.0.0.1:0"
    )
    network = canopen_network(sim)
    drvi = network.add_node(2, str(device_eds["drvi"]))
    akd = network.add_node(4, str(device_eds["akd"]))
    return network, drvi, akd


def intervals(times):
    return [b - a for a, b in zip(times, times[1:])]


def test_heartbeat_producer_runs_at_the_period_set(devices, frames):
    network, drvi, _ = devices
    seen = frames(network, 0x702)
    seen.none(within=0.3)  # 1017h = 0 by default: no heartbeat
    drvi.sdo[0x1017].raw = 100
    stamps = [seen.next(0x702, timeout=2) for _ in range(11)]
    assert all(data == b"\x7f" for _, _, data in stamps)
    gaps = intervals([t for t, _, _ in stamps])
    assert abs(statistics.median(gaps) - 0.100) < 0.010, gaps
    assert all(0.05 < g < 0.2 for g in gaps), gaps
    # A new period takes effect at once; 0 stops it.
    drvi.sdo[0x1017].raw = 30
    seen.clear()
    gaps = intervals([seen.next(0x702, timeout=2)[0] for _ in range(11)])
    assert abs(statistics.median(gaps) - 0.030) < 0.008, gaps
    drvi.sdo[0x1017].raw = 0
    time.sleep(0.05)
    seen.clear()
    seen.none(0x702, within=0.3)
    # python-canopen's NMT master tracks the state from the heartbeat.
    drvi.sdo[0x1017].raw = 20
    drvi.nmt.wait_for_heartbeat(timeout=2)
    assert drvi.nmt.state == "PRE-OPERATIONAL"


def test_heartbeat_consumer_reports_a_lost_master(devices, wait_until):
    network, _, akd = devices
    master_id = 1
    akd.sdo[0x1016][1].raw = (master_id << 16) | 100  # monitor node 1 with 100 ms
    heartbeat = network.send_periodic(0x700 + master_id, [0x05], 0.02)
    try:
        time.sleep(0.3)
        assert akd.emcy.log == []  # heartbeats arriving in time: nothing to report
    finally:
        heartbeat.stop()
    lost = wait_until(lambda: [e for e in akd.emcy.log if e.code == 0x8130], timeout=2, what="EMCY 8130h")
    assert lost[0].register == 0x11  # generic + communication
    assert lost[0].data[0] == master_id
    assert akd.sdo[0x1001].raw == 0x11
    assert akd.sdo[0x1003][1].raw & 0xFFFF == 0x8130
    # The master's heartbeat returns. The AKD latches F129 (manual 5.4.7) until a fault reset
    # (controlword bit 7): then the "error reset" EMCY, register clear.
    heartbeat = network.send_periodic(0x700 + master_id, [0x05], 0.02)
    try:
        time.sleep(0.1)
        akd.sdo[0x6040].raw = 0x0080
        wait_until(lambda: [e for e in akd.emcy.log if e.code == 0x0000], timeout=2, what="error reset EMCY")
        assert akd.emcy.active == []
        assert akd.sdo[0x1001].raw == 0
    finally:
        heartbeat.stop()


def test_a_short_rpdo_is_an_emcy_with_history(devices, wait_until):
    network, drvi, _ = devices
    drvi.nmt.state = "OPERATIONAL"
    time.sleep(0.05)
    network.send_message(0x202, [0x06])  # RPDO1 maps the 2-byte controlword
    emcy = wait_until(lambda: drvi.emcy.active, timeout=2, what="an EMCY")[0]
    assert (emcy.code, emcy.register) == (0x8210, 0x11)  # PDO not processed: length error
    assert drvi.sdo[0x1001].raw == 0x11
    assert drvi.sdo[0x1003][0].raw == 1
    assert drvi.sdo[0x1003][1].raw & 0xFFFF == 0x8210
    # A second one: the history shifts.
    network.send_message(0x202, [])
    wait_until(lambda: len(drvi.emcy.log) == 2, timeout=2, what="a second EMCY")
    assert drvi.sdo[0x1003][0].raw == 2
    # Writing 0 to 1003h sub 0 clears the history.
    drvi.sdo[0x1003][0].raw = 0
    assert drvi.sdo[0x1003][0].raw == 0
    assert drvi.sdo[0x1003][1].raw == 0


def test_the_emcy_inhibit_time_spaces_messages(devices, frames):
    network, drvi, _ = devices
    drvi.sdo[0x1015].raw = 1500  # 150 ms, in units of 100 us
    drvi.nmt.state = "OPERATIONAL"
    seen = frames(network, 0x082)
    time.sleep(0.05)
    for _ in range(3):
        network.send_message(0x202, [0x06])
    stamps = [seen.next(0x082, timeout=2)[0] for _ in range(3)]
    # Measured on arrival here, so allow for delivery jitter; without the inhibit time the
    # three would arrive within a millisecond.
    assert all(g >= 0.11 for g in intervals(stamps)), intervals(stamps)


def test_emcy_stays_silent_when_stopped(devices, frames):
    network, drvi, _ = devices
    seen = frames(network, 0x082)
    drvi.nmt.state = "OPERATIONAL"
    time.sleep(0.05)
    drvi.nmt.state = "STOPPED"
    time.sleep(0.05)
    network.send_message(0x202, [0x06])  # no PDO processing when stopped
    seen.none(within=0.3)


def test_node_guarding_by_python_canopen(devices, frames, wait_until):
    network, drvi, _ = devices
    seen = frames(network, 0x702, 0x082)
    drvi.sdo[0x100C].raw = 100  # guard time, ms
    drvi.sdo[0x100D].raw = 3  # life time factor: the life time is 300 ms
    drvi.nmt.start_node_guarding(0.05)
    try:
        replies = [seen.next(0x702, timeout=2)[2] for _ in range(6)]
        # Each reply is the NMT state (7Fh pre-operational) with bit 7 toggling, starting at 0.
        assert [r[0] for r in replies] == [0x7F, 0xFF] * 3, replies
        # python-canopen's NMT master reads the state from the replies.
        drvi.nmt.state = "OPERATIONAL"
        wait_until(lambda: seen.next(0x702, timeout=2)[2][0] & 0x7F == 0x05, timeout=2, what="operational")
        assert drvi.nmt.state == "OPERATIONAL"
        seen.none(0x082, within=0.4)  # guarded in time: no life guarding event
    finally:
        drvi.nmt.stop_node_guarding()
    # The master goes silent: once the life time has passed, the life guarding event is an
    # EMCY 8130h with the communication bit in the error register.
    emcy = seen.next(0x082, timeout=2)[2]
    assert emcy == bytes([0x30, 0x81, 0x11, 0, 0, 0, 0, 0]), emcy
    lost = wait_until(lambda: [e for e in drvi.emcy.log if e.code == 0x8130], timeout=2, what="EMCY 8130h")
    assert lost[0].register == 0x11


def test_a_tpdo_answers_a_remote_request_from_python_canopen(devices, wait_until):
    network, drvi, _ = devices
    drvi.tpdo.read()
    tpdo = drvi.tpdo[1]
    tpdo.cob_id = 0x182  # RTR allowed (bit 30 clear)
    tpdo.trans_type = 253  # on remote request only
    tpdo.enabled = True
    tpdo.save()
    drvi.nmt.state = "OPERATIONAL"
    time.sleep(0.05)
    received = []
    tpdo.add_callback(lambda map: received.append(bytes(map.data)))
    tpdo.remote_request()
    wait_until(lambda: received, timeout=2, what="the TPDO answering the remote frame")
    assert received[0] == drvi.sdo[0x6041].raw.to_bytes(2, "little")
