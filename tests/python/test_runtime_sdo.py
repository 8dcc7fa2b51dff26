"""SDO transfers between python-canopen's client and the simulated devices: expedited,
segmented and block, in both directions, with the frames on the bus checked to be of the
protocol claimed.

Long values come from a DCF: the DRVI's 1008h (manufacturer device name) is "DRVI" in the EDS,
too short for a segmented upload, so the DCF configures a longer name. The AKD's ASCII
channel command (2026h sub 1, a write-only 32-byte string) takes long downloads."""

import pytest

DCF_NAME = "DRVI simulated by drive-sim"  # 27 bytes: 4 segments of up to 7


def make_dcf(eds_path, tmp_path, values, node_id=None):
    """The EDS with `ParameterValue=` added to the sections named in `values`."""
    lines = []
    for line in eds_path.read_text().splitlines():
        lines.append(line)
        section = line.strip()
        if section.startswith("[") and section[1:-1] in values:
            lines.append(f"ParameterValue={values[section[1:-1]]}")
    if node_id is not None:
        lines += ["", "[DeviceComissioning]", f"NodeID={node_id}", "NodeName=axis", "Baudrate=1000"]
    path = tmp_path / "configured.dcf"
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.fixture
def bus(start_drive_sim, canopen_network, frames, device_eds, tmp_path):
    """A DRVI (node 2, with a DCF) and an AKD (node 4) on one hub; python-canopen nodes for
    both and a recorder of their SDO responses and requests."""
    dcf = make_dcf(device_eds["drvi"], tmp_path, {"1008": DCF_NAME})
    sim = start_drive_sim(
        "run", "--device", "drvi", "--node-id", 2, "--dcf", dcf, "--device", "akd", "--node-id", 4,
        "--listen", "127.0.0.1:0",
    )
    network = canopen_network(sim)
    drvi = network.add_node(2, str(device_eds["drvi"]))
    akd = network.add_node(4, str(device_eds["akd"]))
    seen = frames(network, 0x582, 0x584)
    return drvi, akd, seen


def responses(seen, can_id):
    return [data for _, i, data in seen.all(can_id)]


def test_expedited_upload_and_download(bus):
    drvi, akd, seen = bus
    assert drvi.sdo.upload(0x1000, 0) == (0xFF7A0192).to_bytes(4, "little")
    assert drvi.sdo[0x1018][1].raw == 0x97  # vendor id (DRVI manual)
    # The device serves what its EDS says (python-canopen read the same file).
    for index, sub in [(0x1000, None), (0x1018, 1), (0x1018, 2)]:
        entry = akd.object_dictionary[index] if sub is None else akd.object_dictionary[index][sub]
        value = akd.sdo[index].raw if sub is None else akd.sdo[index][sub].raw
        assert value == entry.default, hex(index)
    drvi.sdo[0x6083].raw = 123456  # UNSIGNED32
    assert drvi.sdo[0x6083].raw == 123456
    drvi.sdo[0x6071].raw = -1000  # INTEGER16, signed
    assert drvi.sdo[0x6071].raw == -1000
    # Every response was expedited: upload 43/47/4B/4F, download 60.
    for data in responses(seen, 0x582):
        assert data[0] in (0x43, 0x47, 0x4B, 0x4F, 0x60), data.hex()


def test_segmented_upload_and_download(bus):
    drvi, akd, seen = bus
    seen.clear()
    assert drvi.sdo.upload(0x1008, 0) == DCF_NAME.encode()
    got = responses(seen, 0x582)
    # Initiate response with size indication (41, size 27), then four segments with
    # alternating toggle bits, the last with c = 1 and 27 - 21 = 6 bytes (n = 1).
    assert got[0][0] == 0x41 and int.from_bytes(got[0][4:8], "little") == len(DCF_NAME)
    assert [d[0] for d in got[1:]] == [0x00, 0x10, 0x00, 0x13]

    seen.clear()
    drvi.sdo.download(0x6083, 0, (0xA5A5).to_bytes(4, "little"), force_segment=True)
    got = responses(seen, 0x582)
    assert [d[0] for d in got] == [0x60, 0x20]  # initiate, one segment
    assert drvi.sdo[0x6083].raw == 0xA5A5

    command = b"DRV.EN; DRV.OPMODE 1; VL.KVFF 0"  # 31 bytes, 5 segments
    seen.clear()
    akd.sdo.download(0x2026, 1, command)
    got = responses(seen, 0x584)
    assert [d[0] for d in got] == [0x60, 0x20, 0x30, 0x20, 0x30, 0x20]


def test_block_upload_and_download(bus):
    drvi, akd, seen = bus
    seen.clear()
    with drvi.sdo.open(0x1008, 0, "rb", block_transfer=True) as stream:
        data = stream.read()
    assert data == DCF_NAME.encode()
    got = responses(seen, 0x582)
    # Initiate block upload response (scs 6, with size and CRC support), the block of
    # segments (sequence numbers 1..4, the last flagged), end (scs 6, cs 1).
    assert got[0][0] & 0xE0 == 0xC0 and got[0][0] & 0x02, got[0].hex()
    assert int.from_bytes(got[0][4:8], "little") == len(DCF_NAME)
    assert [d[0] for d in got[1:5]] == [1, 2, 3, 0x84]
    assert got[5][0] & 0xE3 == 0xC1, got[5].hex()

    seen.clear()
    with drvi.sdo.open(0x6083, 0, "wb", size=4, block_transfer=True) as stream:
        stream.write((77777).to_bytes(4, "little"))
    got = responses(seen, 0x582)
    # Initiate (scs 5, cs 0), block acknowledge, end confirmation (scs 5, cs 1).
    assert [d[0] & 0xE3 for d in got] == [0xA0, 0xA2, 0xA1], [d.hex() for d in got]
    assert drvi.sdo[0x6083].raw == 77777

    command = b"MT.MOVE 0; MT.P 10000; MT.V 50"  # 30 bytes
    seen.clear()
    with akd.sdo.open(0x2026, 1, "wb", size=len(command), block_transfer=True) as stream:
        stream.write(command)
    got = responses(seen, 0x584)
    assert [d[0] & 0xE3 for d in got] == [0xA0, 0xA2, 0xA1], [d.hex() for d in got]


def test_block_download_without_crc(bus):
    drvi, _, _ = bus
    with drvi.sdo.open(0x6083, 0, "wb", size=4, block_transfer=True, request_crc_support=False) as stream:
        stream.write((31337).to_bytes(4, "little"))
    assert drvi.sdo[0x6083].raw == 31337


def test_block_upload_without_crc(bus):
    drvi, _, _ = bus
    with drvi.sdo.open(0x1008, 0, "rb", block_transfer=True, request_crc_support=False) as stream:
        data = stream.read()
    assert data == DCF_NAME.encode()


def test_many_transfers_in_a_row_stay_in_step(bus):
    drvi, akd, _ = bus
    for value in range(0, 200000, 4001):
        drvi.sdo[0x607A].raw = value - 100000  # target position, INTEGER32
        assert drvi.sdo[0x607A].raw == value - 100000
        assert akd.sdo[0x1018][1].raw == akd.sdo[0x1018][1].raw
