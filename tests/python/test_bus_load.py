"""The bus under load and faults, with python-canopen as the master: it gets in past clients
that hold connections and say nothing, it keeps talking to a device while another client floods
the bus, and a device on `run --bus` whose hub goes away comes back by itself with its state.

The Rust side of the same rules: drive/tests/hub_tcp.rs (admission, slow readers, floods, the
emulated wire) and drive/tests/it/e2e_cli.rs (reconnection).
"""

import socket
import threading
import time

import pytest

from conftest import DEVICE_EDS

WAIT = 10.0


def idle_client(host, port, handshake=True):
    """A TCP connection to the hub that opens a channel (or only connects) and then says
    nothing."""
    s = socket.create_connection((host, port), timeout=WAIT)
    s.settimeout(WAIT)
    greeting = s.recv(64)
    assert greeting.startswith(b"< hi >"), greeting
    if handshake:
        for command in (b"< open can0 >", b"< rawmode >"):
            s.sendall(command)
            assert s.recv(64).startswith(b"< ok >")
    return s


def until_closed(s):
    """Reads what `s` is sent until the hub closes it: True, or False if it stays open for
    WAIT seconds. Everything read before the end must be frames."""
    deadline = time.monotonic() + WAIT
    while time.monotonic() < deadline:
        try:
            data = s.recv(4096)
        except socket.timeout:
            return False
        if not data:
            return True
        assert data.startswith(b"< frame "), data
    return False


def read_device_type(network, node_id, eds):
    node = network.add_node(node_id, str(eds))
    node.sdo.RESPONSE_TIMEOUT = 2.0
    return node.sdo[0x1000].raw


def test_the_master_gets_in_past_idle_clients_at_the_limit(start_drive_sim, canopen_network):
    sim = start_drive_sim(
        "run", "--device", "drvi", "--node-id", "2", "--listen", "127.0.0.1:0", "--max-clients", "8", "--quiet"
    )
    # Eight connections hold every slot: six in raw mode, two that never finish the handshake.
    idle = [idle_client(sim.host, sim.port) for _ in range(6)]
    idle += [idle_client(sim.host, sim.port, handshake=False) for _ in range(2)]
    try:
        network = canopen_network(sim)
        assert read_device_type(network, 2, DEVICE_EDS["drvi"]) != 0
        # The connection idle longest (the first) made room: it is closed. Frames it was sent
        # before (the node's boot-up, if the node booted after it joined) come first.
        idle[0].settimeout(WAIT)
        assert until_closed(idle[0]), "the longest-idle silent client was closed"
        assert "closed to make room" in sim.log()
    finally:
        for s in idle:
            s.close()


def test_the_default_limit_is_far_above_what_idle_clients_used_to_exhaust(start_drive_sim, canopen_network):
    sim = start_drive_sim("run", "--device", "drvi", "--node-id", "2", "--listen", "127.0.0.1:0", "--quiet")
    idle = [idle_client(sim.host, sim.port) for _ in range(100)]
    try:
        network = canopen_network(sim)
        assert read_device_type(network, 2, DEVICE_EDS["drvi"]) != 0
        for s in idle[:5]:
            # Still connected (nobody had to make room): frames of the bus, never the end.
            s.setblocking(False)
            try:
                assert s.recv(65536) != b""
            except BlockingIOError:
                pass
    finally:
        for s in idle:
            s.close()


def flood(host, port, stop, sent):
    """Sends frames as fast as the hub takes them until `stop` is set."""
    s = socket.create_connection((host, port), timeout=WAIT)
    s.recv(64)
    for command in (b"< open can0 >", b"< rawmode >"):
        s.sendall(command)
        s.recv(64)
    burst = b"< send 7ff 8 1 2 3 4 5 6 7 8 >" * 512
    s.settimeout(0.5)
    try:
        while not stop.is_set():
            try:
                s.sendall(burst)
                sent[0] += 512
            except socket.timeout:
                pass  # the hub slows us down: that is the point
    finally:
        s.close()


def test_a_device_on_the_bus_survives_a_flood_and_a_lost_hub(start_drive_sim, canopen_network):
    hub = start_drive_sim("hub", "--listen", "127.0.0.1:0", "--quiet")
    address = hub.address
    device = start_drive_sim("run", "--device", "drcs", "--node-id", "3", "--bus", hub.bus_spec(), ready="running on ")
    network = canopen_network(hub)
    node = network.add_node(3, str(DEVICE_EDS["drcs"]))
    node.sdo.RESPONSE_TIMEOUT = 2.0
    node.sdo[0x6083].raw = 4321  # kept only by the running device

    stop, sent = threading.Event(), [0]
    flooder = threading.Thread(target=flood, args=(hub.host, hub.port, stop, sent), daemon=True)
    flooder.start()
    try:
        deadline = time.monotonic() + 3.0
        rounds = 0
        while time.monotonic() < deadline:
            # The device stays on the bus and answers; new clients join meanwhile.
            assert node.sdo[0x6083].raw == 4321
            late = canopen_network(hub)
            late.disconnect()
            rounds += 1
        assert rounds >= 1 and sent[0] > 0
    finally:
        stop.set()
        flooder.join(WAIT)
    assert device.process.poll() is None, device.log()
    assert "disconnected" not in device.log()

    # The hub goes away and comes back on the same address: the device reconnects, with its state.
    network.disconnect()
    assert hub.stop() == 0
    time.sleep(0.3)
    assert device.process.poll() is None, "the device runs on without its bus"
    hub = start_drive_sim("hub", "--listen", address, "--quiet")
    network = canopen_network(hub)
    node = network.add_node(3, str(DEVICE_EDS["drcs"]))
    node.sdo.RESPONSE_TIMEOUT = 0.5
    deadline = time.monotonic() + 30.0
    while True:
        try:
            value = node.sdo[0x6083].raw
            break
        except Exception:
            assert time.monotonic() < deadline, device.log()
    assert value == 4321
    assert "reconnected after" in device.log()
