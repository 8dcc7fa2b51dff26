"""Every SDO abort code a client can provoke, against the simulated devices: through
python-canopen's SDO client where it can express the request, and with raw frames where it
cannot (an unknown command, a wrong toggle bit, a segment overrunning the announced size, a
transfer left unfinished)."""

import time

import pytest

try:
    import canopen
except ImportError:  # the fixtures skip (or fail in CI) with the reason
    canopen = None

SDO_TIMEOUT_MS = 300


@pytest.fixture(scope="module")
def devices_process(start_shared_drive_sim):
    """One process for the module: DRVI node 2, DRCS node 3, AKD node 4."""
    return start_shared_drive_sim(
        "run", "--device", "drvi", "--node-id", 2, "--device", "drcs", "--node-id", 3, "--device", "akd",
        "--node-id", 4, "--sdo-timeout-ms", SDO_TIMEOUT_MS, "--listen", "127.0.0.1:0",
    )


@pytest.fixture
def nodes(devices_process, canopen_network, device_eds):
    network = canopen_network(devices_process)
    drvi = network.add_node(2, str(device_eds["drvi"]))
    drcs = network.add_node(3, str(device_eds["drcs"]))
    akd = network.add_node(4, str(device_eds["akd"]))
    # Each test starts from the defaults.
    network.nmt.send_command(0x81)
    time.sleep(0.1)
    return network, {"drvi": drvi, "drcs": drcs, "akd": akd}


def abort_code(action):
    with pytest.raises(canopen.SdoAbortedError) as error:
        action()
    return error.value.code


def u32(value):
    return value.to_bytes(4, "little")


def test_read_a_write_only_object(nodes):
    _, n = nodes
    assert abort_code(lambda: n["akd"].sdo.upload(0x2026, 1)) == 0x06010001


def test_write_a_read_only_object(nodes):
    _, n = nodes
    assert abort_code(lambda: n["drvi"].sdo.download(0x1000, 0, u32(1))) == 0x06010002
    assert abort_code(lambda: n["akd"].sdo.download(0x2026, 2, b"x")) == 0x06010002


def test_object_and_sub_index_that_do_not_exist(nodes):
    _, n = nodes
    assert abort_code(lambda: n["drvi"].sdo.upload(0x5FFF, 0)) == 0x06020000
    assert abort_code(lambda: n["drvi"].sdo.download(0x5FFF, 0, u32(0))) == 0x06020000
    assert abort_code(lambda: n["drvi"].sdo.upload(0x1018, 9)) == 0x06090011
    assert abort_code(lambda: n["akd"].sdo.download(0x1016, 7, u32(0))) == 0x06090011


def test_wrong_lengths(nodes):
    _, n = nodes
    # 6 bytes for an UNSIGNED32 (segmented, the size announced up front): too long.
    assert abort_code(lambda: n["drvi"].sdo.download(0x6083, 0, b"\x01" * 6)) == 0x06070012
    # 2 bytes for an UNSIGNED32 (expedited): too short.
    assert abort_code(lambda: n["drvi"].sdo.download(0x6083, 0, b"\x01\x00")) == 0x06070013
    # 33 bytes for a 32-byte string.
    assert abort_code(lambda: n["akd"].sdo.download(0x2026, 1, b"A" * 33)) == 0x06070012


def test_values_out_of_range(nodes):
    _, n = nodes
    drvi = n["drvi"]
    assert abort_code(lambda: drvi.sdo.download(0x6071, 0, (15001).to_bytes(2, "little", signed=True))) == 0x06090031
    assert abort_code(lambda: drvi.sdo.download(0x6071, 0, (-15001).to_bytes(2, "little", signed=True))) == 0x06090032
    drvi.sdo[0x6071].raw = 15000  # the limit itself is fine
    # Invalid values: a reserved TPDO transmission type, a 29-bit COB-ID.
    assert abort_code(lambda: drvi.sdo.download(0x1800, 2, bytes([241]))) == 0x06090030
    assert abort_code(lambda: drvi.sdo.download(0x1801, 1, u32(0xA0000282))) == 0x06090030


def test_pdo_mapping_errors(nodes):
    _, n = nodes
    drvi = n["drvi"]
    # TPDO2 (1801h) is not valid by default, so its mapping (1A01h) may be changed.
    assert drvi.sdo[0x1801][1].raw & 0x80000000
    assert abort_code(lambda: drvi.sdo.download(0x1A01, 1, u32(0x10000020))) == 0x06040041  # 1000h: not mappable
    assert abort_code(lambda: drvi.sdo.download(0x1A01, 1, u32(0x60640010))) == 0x06040043  # 16 bits of an I32
    for sub, entry in enumerate([0x60640020, 0x606C0020, 0x607A0020], start=1):
        drvi.sdo[0x1A01][sub].raw = entry
    assert abort_code(lambda: drvi.sdo.download(0x1A01, 0, bytes([3]))) == 0x06040042  # 96 bits
    drvi.sdo[0x1A01][0].raw = 2
    # The mapping of a valid PDO (TPDO1) cannot be changed: unsupported access.
    assert abort_code(lambda: drvi.sdo.download(0x1A00, 1, u32(0x60640020))) == 0x06010000


def test_store_and_restore_with_a_wrong_signature(nodes):
    _, n = nodes
    assert abort_code(lambda: n["drvi"].sdo.download(0x1010, 1, b"sav!")) == 0x08000020
    assert abort_code(lambda: n["akd"].sdo.download(0x1011, 1, b"save")) == 0x08000020
    n["drvi"].sdo.download(0x1010, 1, b"save")  # the right one works


def test_device_state(nodes):
    _, n = nodes
    drcs = n["drcs"]
    drcs.sdo[0x1019].raw = 10  # SYNC counter overflow, allowed while 1006h = 0
    drcs.sdo[0x1006].raw = 1000
    assert abort_code(lambda: drcs.sdo.download(0x1019, 0, bytes([2]))) == 0x08000022
    drcs.sdo[0x1006].raw = 0
    drcs.sdo[0x1019].raw = 2


class Raw:
    """Raw SDO frames to node 2 and its responses."""

    def __init__(self, network, frames):
        self.network = network
        self.seen = frames(network, 0x582)

    def request(self, *data):
        self.seen.clear()
        self.network.send_message(0x602, list(data) + [0] * (8 - len(data)))
        return self.seen.next(0x582, timeout=2)[2]


def abort_frame(index, sub, code):
    return bytes([0x80, index & 0xFF, index >> 8, sub]) + u32(code)


def test_unknown_command_specifier(nodes, frames):
    network, _ = nodes
    raw = Raw(network, frames)
    assert raw.request(0xE0, 0x00, 0x10, 0x00)[4:] == u32(0x05040001)
    # A download segment without a transfer in progress.
    assert raw.request(0x00, 1, 2, 3, 4, 5, 6, 7)[4:] == u32(0x05040001)


def test_toggle_bit_not_alternated(nodes, frames):
    network, _ = nodes
    raw = Raw(network, frames)
    assert raw.request(0x21, 0x83, 0x60, 0x00, 4, 0, 0, 0) == bytes([0x60, 0x83, 0x60, 0x00, 0, 0, 0, 0])
    # First segment with the toggle bit set: 4 bytes (n = 3), last.
    assert raw.request(0x17, 1, 2, 3, 4) == abort_frame(0x6083, 0, 0x05030000)


def test_segment_longer_than_announced(nodes, frames):
    network, _ = nodes
    raw = Raw(network, frames)
    raw.request(0x21, 0x83, 0x60, 0x00, 4, 0, 0, 0)
    assert raw.request(0x01, 1, 2, 3, 4, 5, 6, 7) == abort_frame(0x6083, 0, 0x06070010)


def test_transfer_left_unfinished_times_out(nodes, frames):
    network, _ = nodes
    raw = Raw(network, frames)
    started = time.monotonic()
    assert raw.request(0x21, 0x83, 0x60, 0x00, 4, 0, 0, 0)[0] == 0x60
    # No segment follows: the server aborts by itself after its timeout.
    aborted, _, data = raw.seen.next(0x582, timeout=3)
    assert data == abort_frame(0x6083, 0, 0x05040000)
    assert SDO_TIMEOUT_MS / 1000 - 0.01 <= aborted - started < SDO_TIMEOUT_MS / 1000 + 0.5
    # The server is idle again.
    assert raw.request(0x40, 0x00, 0x10, 0x00)[:4] == bytes([0x43, 0x00, 0x10, 0x00])
