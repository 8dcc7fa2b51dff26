"""The programming examples of the Kollmorgen AKD CANopen manual (Italian, rev. F, chapter 7.2),
replayed frame by frame against `drive-sim run --device akd` over the socketcand hub with a raw
python-can bus.

Frames are written as the manual prints them ("603 2B 40 60 00 06 00 00 00"). Where a listing
has a typo (the decisions of devices/kollmorgen-akd.toml, asserted by devices/tests/it/akd.rs) the
comment says what was fixed. The listings of 7.2.1.5 to 7.2.2.1 remap PDOs that stay valid
(mapping sub 0 = 0, the entries, sub 0 = n, COB-ID bit 31 never set) and so do the replays: the
simulated AKD takes a new mapping as its manual says (6.3.1.2; the sidecar's `[pdo] remapping`).
Where the manual does not say which units the drive was set up with, the replays use the setup
7.2.1.7 names: 10 000 user units (um) per motor turn (6092h sub 1).

The same listings run in virtual time in drive/tests/it/drives_akd.rs (with the EMCY part of
7.2.1.10, which needs a simulated over-temperature that the bus cannot provoke).
"""

import time

import pytest


class Listing:
    """A raw CAN bus replaying a listing: requests, their answers, PDOs."""

    def __init__(self, bus):
        self.bus = bus
        self.pending = []  # frames received while waiting for something else

    @staticmethod
    def parse(text):
        words = text.split()
        return int(words[0], 16), bytes(int(w, 16) for w in words[1:])

    @staticmethod
    def text(can_id, data):
        return " ".join([f"{can_id:03X}"] + [f"{b:02X}" for b in data])

    def send(self, text):
        import can

        can_id, data = self.parse(text)
        self.bus.send(can.Message(arbitration_id=can_id, data=data, is_extended_id=False))

    def _receive(self, timeout):
        message = self.bus.recv(timeout)
        if message is None:
            return None
        return message.arbitration_id, bytes(message.data)

    def wait(self, can_id, timeout=2.0):
        """The next frame with `can_id` (earlier ones kept aside are taken first), as text."""
        for i, (fid, data) in enumerate(self.pending):
            if fid == can_id:
                del self.pending[i]
                return self.text(fid, data)
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            got = self._receive(max(deadline - time.monotonic(), 0.001))
            if got is None:
                continue
            if got[0] == can_id:
                return self.text(*got)
            self.pending.append(got)
        pytest.fail(f"no frame {can_id:03X} within {timeout} s")

    def take(self, can_id, settle=0.05):
        """Every frame with `can_id` received so far (after `settle` seconds), as text."""
        deadline = time.monotonic() + settle
        while True:
            got = self._receive(max(deadline - time.monotonic(), 0.001))
            if got is not None:
                self.pending.append(got)
            elif time.monotonic() >= deadline:
                break
        hits = [self.text(f, d) for f, d in self.pending if f == can_id]
        self.pending = [(f, d) for f, d in self.pending if f != can_id]
        return hits

    def x(self, request, answer):
        """Sends an SDO request and checks the answer the manual prints."""
        can_id, _ = self.parse(request)
        self.send(request)
        assert self.wait(can_id - 0x600 + 0x580) == answer, f"request {request}"

    def put(self, text, settle=0.02):
        """Sends a frame (NMT, PDO, SYNC) and gives the drive a moment."""
        self.send(text)
        time.sleep(settle)

    def read(self, node, index, sub):
        """An expedited SDO upload, as an int (little-endian, unsigned)."""
        self.send(f"{0x600 + node:03X} 40 {index & 0xFF:02X} {index >> 8:02X} {sub:02X} 00 00 00 00")
        data = bytes(int(w, 16) for w in self.wait(0x580 + node).split()[1:])
        assert data[0] & 0xE0 == 0x40, data.hex()
        return int.from_bytes(data[4:8], "little")

    def write32(self, node, index, sub, value):
        v = (value & 0xFFFFFFFF).to_bytes(4, "little")
        where = f"{index & 0xFF:02X} {index >> 8:02X} {sub:02X}"
        request = f"{0x600 + node:03X} 23 {where} " + " ".join(f"{b:02X}" for b in v)
        self.x(request, f"{0x580 + node:03X} 60 {where} 00 00 00 00")

    def wait_value(self, node, index, sub, predicate, timeout=5.0):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            value = self.read(node, index, sub)
            if predicate(value):
                return value
            time.sleep(0.01)
        pytest.fail(f"{index:04X} sub {sub} = {value} after {timeout} s")

    def wait_status(self, node, mask, value, timeout=10.0):
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            sw = self.read(node, 0x6041, 0)
            if sw & mask == value:
                return sw
            time.sleep(0.01)
        pytest.fail(f"statusword {sw:04X} & {mask:04X} != {value:04X}")


def signed(value, bits=32):
    return value - (1 << bits) if value & (1 << (bits - 1)) else value


@pytest.fixture
def listing(start_drive_sim, can_bus):
    """One AKD (node 3) and a raw bus to it."""
    sim = start_drive_sim("run", "--device", "akd", "--node-id", 3, "--listen", "127.0.0.1:0")
    return Listing(can_bus(sim))


def resolution_10000(lst, node=3):
    lst.write32(node, 0x6092, 1, 10000)


def enable_by_sdo(lst):
    lst.x("603 2B 40 60 00 06 00 00 00", "583 60 40 60 00 00 00 00 00")
    lst.x("603 2B 40 60 00 07 00 00 00", "583 60 40 60 00 00 00 00 00")
    lst.x("603 2B 40 60 00 0F 00 00 00", "583 60 40 60 00 00 00 00 00")


def disable_unused_pdos(lst):
    lst.x("603 2F 00 18 02 01 00 00 00", "583 60 00 18 02 00 00 00 00")
    lst.x("603 23 01 18 01 83 02 00 80", "583 60 01 18 01 00 00 00 00")
    lst.x("603 23 02 18 01 83 03 00 80", "583 60 02 18 01 00 00 00 00")
    lst.x("603 23 03 18 01 83 04 00 80", "583 60 03 18 01 00 00 00 00")
    lst.x("603 23 01 14 01 03 03 00 80", "583 60 01 14 01 00 00 00 00")
    lst.x("603 23 02 14 01 03 04 00 80", "583 60 02 14 01 00 00 00 00")
    lst.x("603 23 03 14 01 03 05 00 80", "583 60 03 14 01 00 00 00 00")


def test_7_2_1_2_state_machine(listing):
    listing.x("603 40 41 60 00 00 00 00 00", "583 4B 41 60 00 40 02 00 00")
    listing.x("603 2B 40 60 00 06 00 00 00", "583 60 40 60 00 00 00 00 00")
    listing.x("603 2B 40 60 00 07 00 00 00", "583 60 40 60 00 00 00 00 00")
    listing.x("603 40 41 60 00 00 00 00 00", "583 4B 41 60 00 33 02 00 00")


def test_7_2_1_3_profile_velocity_by_sdo(listing):
    resolution_10000(listing)
    listing.x("603 2F 60 60 00 03 00 00 00", "583 60 60 60 00 00 00 00 00")
    listing.x("603 23 FF 60 00 00 00 00 00", "583 60 FF 60 00 00 00 00 00")
    enable_by_sdo(listing)
    listing.x("603 23 FF 60 00 00 41 00 00", "583 60 FF 60 00 00 00 00 00")
    # 606Ch is 1000:1 (7.1.4): 1000 x 16 640 um/s, to within the internal rounding.
    listing.wait_value(3, 0x606C, 0, lambda v: abs(signed(v) - 16_640_000) < 1000)
    assert listing.read(3, 0x6041, 0) & 0x0400, "velocity reached"
    listing.x("603 2B 40 60 00 0F 01 00 00", "583 60 40 60 00 00 00 00 00")  # halt
    time.sleep(0.3)
    assert listing.read(3, 0x606C, 0) == 0


def test_7_2_1_4_torque_by_sdo(listing):
    listing.x("603 2F 60 60 00 04 00 00 00", "583 60 60 60 00 00 00 00 00")
    listing.x("603 2B 71 60 00 00 00 00 00", "583 60 71 60 00 00 00 00 00")
    enable_by_sdo(listing)
    # 400: per mille of rated torque (6.7.2.3; the listing says mA, sidecar decision).
    listing.x("603 2B 71 60 00 90 01 00 00", "583 60 71 60 00 00 00 00 00")
    time.sleep(0.1)
    assert listing.read(3, 0x6077, 0) == 400
    listing.x("603 2B 40 60 00 0F 01 00 00", "583 60 40 60 00 00 00 00 00")


def test_7_2_1_5_velocity_by_pdo(listing):
    resolution_10000(listing)
    listing.x("603 2F 60 60 00 03 00 00 00", "583 60 60 60 00 00 00 00 00")
    listing.x("603 2F 00 16 00 00 00 00 00", "583 60 00 16 00 00 00 00 00")
    listing.x("603 23 00 16 01 20 00 FF 60", "583 60 00 16 01 00 00 00 00")
    listing.x("603 2F 00 16 00 01 00 00 00", "583 60 00 16 00 00 00 00 00")
    listing.x("603 2F 00 1A 00 00 00 00 00", "583 60 00 1A 00 00 00 00 00")
    listing.x("603 23 00 1A 01 20 00 64 60", "583 60 00 1A 01 00 00 00 00")
    # Commented as a position: 606Ch is the velocity actual value.
    listing.x("603 23 00 1A 02 20 00 6C 60", "583 60 00 1A 02 00 00 00 00")
    listing.x("603 2F 00 1A 00 02 00 00 00", "583 60 00 1A 00 00 00 00 00")
    disable_unused_pdos(listing)
    listing.put("000 01 03")
    enable_by_sdo(listing)
    # Printed "203 00 40" (2 bytes) for the 32-bit 60FFh: 4 bytes.
    listing.put("203 00 40 00 00", settle=0.3)
    listing.take(0x183)
    listing.put("080")
    data = bytes.fromhex(listing.wait(0x183).replace(" ", "")[3:])
    assert len(data) == 8
    position = int.from_bytes(data[:4], "little", signed=True)
    velocity = int.from_bytes(data[4:], "little", signed=True)
    assert position > 0
    # 606Ch in a PDO is rpm x 1000 (6.6.2.1): 16 384 um/s at 10 000 um per turn, 98.304 rpm.
    assert abs(velocity - 98_304) < 1000
    listing.x("603 2B 40 60 00 0F 01 00 00", "583 60 40 60 00 00 00 00 00")


@pytest.fixture
def listing_blocked(start_drive_sim, can_bus, tmp_path):
    """One AKD (node 3) whose axis runs into an end stop with no limit switch before it (the
    default machine's switch would stop a torque-driven axis): the torque stands as
    commanded."""
    machine = tmp_path / "blocked.toml"
    machine.write_text('travel = "linear"\nnegative_end_stop = -2.0\npositive_end_stop = 0.1\n')
    sim = start_drive_sim("run", "--device", "akd", "--node-id", 3, "--machine", str(machine), "--listen", "127.0.0.1:0")
    return Listing(can_bus(sim))


def test_7_2_1_6_torque_by_pdo(listing_blocked):
    listing = listing_blocked
    listing.x("603 2F 60 60 00 04 00 00 00", "583 60 60 60 00 00 00 00 00")
    listing.x("603 2F 00 16 00 00 00 00 00", "583 60 00 16 00 00 00 00 00")
    listing.x("603 23 00 16 01 10 00 71 60", "583 60 00 16 01 00 00 00 00")
    listing.x("603 2F 00 16 00 01 00 00 00", "583 60 00 16 00 00 00 00 00")
    listing.x("603 2F 00 1A 00 00 00 00 00", "583 60 00 1A 00 00 00 00 00")
    listing.x("603 23 00 1A 01 10 00 77 60", "583 60 00 1A 01 00 00 00 00")
    listing.x("603 2F 00 1A 00 01 00 00 00", "583 60 00 1A 00 00 00 00 00")
    disable_unused_pdos(listing)
    listing.put("000 01 03")
    enable_by_sdo(listing)
    listing.put("203 12 02", settle=0.1)  # 530 per mille (commented mA)
    listing.take(0x183)
    listing.put("080")
    # The manual's axis answered 537; the model gives the torque commanded.
    assert listing.wait(0x183) == "183 12 02"
    listing.x("603 2B 40 60 00 0F 01 00 00", "583 60 40 60 00 00 00 00 00")


def test_7_2_1_7_homing_by_sdo(listing):
    # The listing starts with the boot-up message: reset the node to see it.
    listing.put("000 81 03", settle=0.0)
    assert listing.wait(0x703) == "703 00"
    resolution_10000(listing)
    listing.x("603 40 41 60 00 00 00 00 00", "583 4B 41 60 00 40 02 00 00")
    listing.x("603 23 99 60 01 10 27 00 00", "583 60 99 60 01 00 00 00 00")
    listing.x("603 23 99 60 02 88 13 00 00", "583 60 99 60 02 00 00 00 00")
    listing.x("603 23 9A 60 00 10 27 00 00", "583 60 9A 60 00 00 00 00 00")  # 10 000, commented 1000
    listing.x("603 23 7C 60 00 A8 61 00 00", "583 60 7C 60 00 00 00 00 00")
    # The "Homing type (6098h)" table lacks its 6098h write: method 1 (negative limit switch,
    # then the zero mark), as the speeds' comments describe.
    listing.x("603 2F 98 60 00 01 00 00 00", "583 60 98 60 00 00 00 00 00")
    listing.x("603 2F 60 60 00 06 00 00 00", "583 60 60 60 00 00 00 00 00")
    listing.x("603 40 41 60 00 00 00 00 00", "583 4B 41 60 00 40 02 00 00")  # commented 0250h
    enable_by_sdo(listing)
    listing.x("603 40 41 60 00 00 00 00 00", "583 4B 41 60 00 37 02 00 00")
    listing.x("603 2B 40 60 00 1F 00 00 00", "583 60 40 60 00 00 00 00 00")
    listing.x("603 40 41 60 00 00 00 00 00", "583 4B 41 60 00 37 02 00 00")  # not finished
    listing.wait_status(3, 0x1400, 0x1400, timeout=15)
    listing.x("603 40 41 60 00 00 00 00 00", "583 4B 41 60 00 37 16 00 00")  # finished
    assert listing.read(3, 0x6064, 0) == 25000  # HOME.P


def test_7_2_1_8_profile_position(listing):
    listing.x("603 2F 01 16 00 00 00 00 01", "583 60 01 16 00 00 00 00 00")
    listing.x("603 23 01 16 01 20 00 7A 60", "583 60 01 16 01 00 00 00 00")
    listing.x("603 23 01 16 02 20 00 81 60", "583 60 01 16 02 00 00 00 00")
    listing.x("603 2F 01 16 00 02 00 00 00", "583 60 01 16 00 00 00 00 00")
    listing.x("603 2F 00 1A 00 00 00 00 01", "583 60 00 1A 00 00 00 00 00")
    listing.x("603 23 00 1A 01 10 00 41 60", "583 60 00 1A 01 00 00 00 00")
    listing.x("603 2F 00 1A 00 01 00 00 00", "583 60 00 1A 00 00 00 00 00")
    listing.x("603 2F 01 1A 00 00 00 00 01", "583 60 01 1A 00 00 00 00 00")
    listing.x("603 23 01 1A 01 20 00 64 60", "583 60 01 1A 01 00 00 00 00")
    listing.x("603 23 01 1A 02 20 00 6C 60", "583 60 01 1A 02 00 00 00 00")
    listing.x("603 2F 01 1A 00 02 00 00 00", "583 60 01 1A 00 00 00 00 00")
    listing.x("603 2F 01 18 02 01 00 00 00", "583 60 01 18 02 00 00 00 00")
    listing.x("603 23 02 18 01 83 03 00 80", "583 60 02 18 01 00 00 00 00")
    listing.x("603 23 03 18 01 83 04 00 80", "583 60 03 18 01 00 00 00 00")
    listing.x("603 23 02 14 01 03 04 00 80", "583 60 02 14 01 00 00 00 00")
    listing.x("603 23 03 14 01 03 05 00 80", "583 60 03 14 01 00 00 00 00")
    # 6093h is not in this dictionary (sidecar decision): "object does not exist".
    listing.x("603 23 93 60 01 00 00 10 00", "583 80 93 60 01 00 00 02 06")
    listing.x("603 23 93 60 02 A0 8C 00 00", "583 80 93 60 02 00 00 02 06")
    listing.put("000 01 03")
    assert listing.wait(0x183) == "183 40 02"
    listing.x("603 2F 60 60 00 06 00 00 00", "583 60 60 60 00 00 00 00 00")
    listing.x("603 2F 98 60 00 0C 00 00 00", "583 60 98 60 00 00 00 00 00")
    # 72 000 units/s in the units in force (one unit = one turn): "value too high".
    listing.x("603 23 99 60 01 40 19 01 00", "583 80 99 60 01 31 00 09 06")
    listing.x("603 2B 40 60 00 06 00 00 00", "583 60 40 60 00 00 00 00 00")
    assert listing.wait(0x183) == "183 31 02"  # printed 0221h (bit 4 missing; 7.2.2.1 prints 0231h)
    listing.x("603 2B 40 60 00 07 00 00 00", "583 60 40 60 00 00 00 00 00")
    assert listing.wait(0x183) == "183 33 02"
    listing.x("603 2B 40 60 00 0F 00 00 00", "583 60 40 60 00 00 00 00 00")
    assert listing.wait(0x183) == "183 37 02"
    listing.x("603 2B 40 60 00 1F 00 00 00", "583 60 40 60 00 00 00 00 00")
    assert listing.wait(0x183, timeout=20) == "183 37 06"  # target reached
    assert listing.wait(0x183) == "183 37 16"  # homing attained
    listing.put("203 0F 00")
    # What the 6093h lines meant: 36 000 user units per turn, the feed constant 6092h.
    listing.write32(3, 0x6092, 1, 36000)
    listing.x("603 2F 60 60 00 01 00 00 00", "583 60 60 60 00 00 00 00 00")
    listing.x("603 23 83 60 00 32 00 00 00", "583 60 83 60 00 00 00 00 00")
    listing.x("603 23 84 60 00 32 00 00 00", "583 60 84 60 00 00 00 00 00")
    # "50 ms" ramps for 20 000 units/s: 400 000 units/s^2.
    listing.write32(3, 0x6083, 0, 400000)
    listing.write32(3, 0x6084, 0, 400000)
    listing.take(0x183)
    listing.take(0x283)
    # RPDO2 is 607Ah + 6081h, 8 bytes (printed with 4): 36 000 units, 20 000 units/s.
    listing.put("303 A0 8C 00 00 20 4E 00 00")
    listing.put("080")
    assert listing.wait(0x283) == "283 00 00 00 00 00 00 00 00"  # at home, standing
    listing.put("203 1F 00", settle=0.0)
    assert listing.wait(0x183) == "183 37 12"  # set-point acknowledge
    listing.put("203 0F 00", settle=0.0)
    assert listing.wait(0x183) == "183 37 02"
    assert listing.wait(0x183, timeout=5) == "183 37 06"  # target reached
    listing.put("080")
    assert listing.wait(0x283) == "283 A0 8C 00 00 00 00 00 00"


def test_7_2_1_9_ascii_channel(start_drive_sim, can_bus):
    sim = start_drive_sim("run", "--device", "akd", "--node-id", 1, "--listen", "127.0.0.1:0")
    lst = Listing(can_bus(sim))
    lst.x("601 23 26 20 01 44 52 56 2E", "581 60 26 20 01 00 00 00 00")  # "DRV."
    lst.x("601 23 26 20 01 46 41 55 4C", "581 60 26 20 01 00 00 00 00")  # "FAUL"
    lst.x("601 23 26 20 01 54 53 0D 0A", "581 60 26 20 01 00 00 00 00")  # "TS\r\n"
    # Each upload of sub 2 is expedited and hands out the next 4 characters (typos of the
    # listing fixed: "ctiv" is 63 74 69 76, "e" 65); after the end, sub 2 is empty.
    chunks = ["3E 4E 6F 20", "66 61 75 6C", "74 73 20 61", "63 74 69 76", "65 0A 0D 0A"]
    answer = b""
    for chunk in chunks:
        lst.x("601 40 26 20 02 00 00 00 00", f"581 43 26 20 02 {chunk}")
        answer += bytes.fromhex(chunk.replace(" ", ""))
    assert answer == b">No faults active\n\r\n"


def test_7_2_1_10_sync_test(listing):
    listing.x("603 2F 01 16 00 00 00 00 00", "583 60 01 16 00 00 00 00 00")
    listing.x("603 23 01 16 01 20 00 7A 60", "583 60 01 16 01 00 00 00 00")
    listing.x("603 23 01 16 02 20 00 81 60", "583 60 01 16 02 00 00 00 00")
    listing.x("603 2F 01 16 00 02 00 00 00", "583 60 01 16 00 00 00 00 00")
    listing.x("603 2F 00 1A 00 00 00 00 00", "583 60 00 1A 00 00 00 00 00")
    listing.x("603 23 00 1A 01 20 00 64 60", "583 60 00 1A 01 00 00 00 00")
    listing.x("603 2F 00 1A 00 01 00 00 00", "583 60 00 1A 00 00 00 00 00")
    listing.x("603 2F 00 18 02 02 00 00 00", "583 60 00 18 02 00 00 00 00")
    listing.x("603 2F 01 1A 00 00 00 00 00", "583 60 01 1A 00 00 00 00 00")
    listing.x("603 23 01 1A 01 10 00 41 60", "583 60 01 1A 01 00 00 00 00")
    listing.x("603 23 01 1A 02 20 00 02 10", "583 60 01 1A 02 00 00 00 00")
    # Printed as 1601h sub 0 (accepted: RPDO2 has two entries); the TPDO2 count is 1A01h sub 0.
    listing.x("603 2F 01 16 00 02 00 00 00", "583 60 01 16 00 00 00 00 00")
    listing.x("603 2F 01 1A 00 02 00 00 00", "583 60 01 1A 00 00 00 00 00")
    listing.x("603 2F 01 18 02 03 00 00 00", "583 60 01 18 02 00 00 00 00")
    listing.put("000 01 03", settle=0.1)  # not in the listing: PDOs need Operational
    listing.take(0x183)
    listing.take(0x283)
    seen = []
    for n in range(1, 7):
        listing.put("080", settle=0.05)
        t1 = listing.take(0x183, settle=0.0)
        t2 = listing.take(0x283, settle=0.0)
        for f in t2:
            assert len(f.split()) == 7, f"6041h + 1002h: {f}"
        seen.append((n, bool(t1), bool(t2)))
    # The comments name 181h/281h: node 3 sends 183h/283h.
    assert seen == [
        (1, False, False),
        (2, True, False),
        (3, False, True),
        (4, True, False),
        (5, False, False),
        (6, True, True),
    ]


def test_7_2_2_1_two_axes_share_one_rpdo(start_drive_sim, can_bus):
    sim = start_drive_sim(
        "run", "--device", "akd", "--node-id", 1, "--device", "akd", "--node-id", 2, "--listen", "127.0.0.1:0"
    )
    lst = Listing(can_bus(sim))
    # "The axes are homed before": method 35 at the power-up position.
    for node in (1, 2):
        rq, rs = f"{0x600 + node:03X}", f"{0x580 + node:03X}"
        lst.x(f"{rq} 2F 60 60 00 06 00 00 00", f"{rs} 60 60 60 00 00 00 00 00")
        lst.x(f"{rq} 2F 98 60 00 23 00 00 00", f"{rs} 60 98 60 00 00 00 00 00")
        for cw in ("06", "07", "0F", "1F", "00"):
            lst.x(f"{rq} 2B 40 60 00 {cw} 00 00 00", f"{rs} 60 40 60 00 00 00 00 00")
            time.sleep(0.01)
    lst.x("601 2F 01 16 00 00 00 00 00", "581 60 01 16 00 00 00 00 00")
    lst.x("601 23 01 16 01 20 01 C1 60", "581 60 01 16 01 00 00 00 00")  # set-point
    lst.x("601 23 01 16 02 20 00 00 21", "581 60 01 16 02 00 00 00 00")  # 4-byte dummy
    lst.x("601 2F 01 16 00 02 00 00 00", "581 60 01 16 00 00 00 00 00")
    # Axis 2 (sub-indices swapped: the listing writes the dummy to sub 2 and the set-point to
    # sub 1, while its comments and the text put the set-point in bytes 4..7).
    lst.x("602 2F 01 16 00 00 00 00 00", "582 60 01 16 00 00 00 00 00")
    lst.x("602 23 01 16 01 20 00 00 21", "582 60 01 16 01 00 00 00 00")
    lst.x("602 23 01 16 02 20 01 C1 60", "582 60 01 16 02 00 00 00 00")
    lst.x("602 2F 01 16 00 02 00 00 00", "582 60 01 16 00 00 00 00 00")
    # "Same COB-ID as axis 1", printed as 1601h sub 1: it is 1401h sub 1, and the valid PDO
    # takes the new CAN-ID as the listing's answer says.
    lst.x("602 23 01 14 01 01 03 00 00", "582 60 01 14 01 00 00 00 00")
    for node in (1, 2):
        rq, rs = f"{0x600 + node:03X}", f"{0x580 + node:03X}"
        lst.x(f"{rq} 2F 01 1A 00 00 00 00 00", f"{rs} 60 01 1A 00 00 00 00 00")
        lst.x(f"{rq} 23 01 1A 01 20 00 63 60", f"{rs} 60 01 1A 01 00 00 00 00")
        lst.x(f"{rq} 23 01 1A 02 20 00 02 10", f"{rs} 60 01 1A 02 00 00 00 00")
        lst.x(f"{rq} 2F 01 1A 00 02 00 00 00", f"{rs} 60 01 1A 00 00 00 00 00")
        lst.x(f"{rq} 2F 01 14 02 01 00 00 00", f"{rs} 60 01 14 02 00 00 00 00")
        lst.x(f"{rq} 2F 01 18 02 01 00 00 00", f"{rs} 60 01 18 02 00 00 00 00")
        lst.x(f"{rq} 23 02 18 01 {0x80 + node:02X} 03 00 80", f"{rs} 60 02 18 01 00 00 00 00")
        lst.x(f"{rq} 23 03 18 01 {0x80 + node:02X} 04 00 80", f"{rs} 60 03 18 01 00 00 00 00")
        lst.x(f"{rq} 2F 60 60 00 07 00 00 00", f"{rs} 60 60 60 00 00 00 00 00")
        lst.x(f"{rq} 2F C2 60 01 01 00 00 00", f"{rs} 60 C2 60 01 00 00 00 00")
        # 60C2h sub 2 is INTEGER16: the printed 1-byte write is refused, FD FF is -3.
        lst.x(f"{rq} 2F C2 60 02 FD 00 00 00", f"{rs} 80 C2 60 02 13 00 07 06")
        lst.x(f"{rq} 2B C2 60 02 FD FF 00 00", f"{rs} 60 C2 60 02 00 00 00 00")
    lst.put("000 01 00", settle=0.1)
    lst.take(0x181)
    lst.take(0x182)
    for cw, sw in (("06 00", "31 02"), ("07 00", "33 02"), ("0F 00", "37 02"), ("1F 00", "37 12")):
        for node in (1, 2):
            lst.put(f"{0x200 + node:03X} {cw}", settle=0.0)
            assert lst.wait(0x180 + node) == f"{0x180 + node:03X} {sw}", f"axis {node}, controlword {cw}"
    lst.take(0x281, settle=0.0)
    lst.take(0x282, settle=0.0)
    # One RPDO for both: 500 increments for axis 1, 1000 for axis 2, taken at the next SYNC.
    # The manual shows the TPDO2 answers on 181h/182h: they are 281h/282h.
    lst.put("301 F4 01 00 00 E8 03 00 00")
    lst.put("080", settle=0.05)
    lst.take(0x281, settle=0.0)
    lst.take(0x282, settle=0.0)
    lst.put("080")
    a1, a2 = lst.wait(0x281), lst.wait(0x282)
    assert a1.startswith("281 F4 01 00 00"), a1
    assert a2.startswith("282 E8 03 00 00"), a2
    for answer in (a1, a2):
        status = int.from_bytes(bytes.fromhex("".join(answer.split()[5:9])), "little")
        assert status & (1 << 14), f"power stage enabled: {status:08X}"
        assert status & (1 << 1), f"homed: {status:08X}"


def done(request):
    """The success answer to an SDO download (7.2.2.2 prints the requests only)."""
    words = request.split()
    return f"{int(words[0], 16) - 0x80:03X} 60 {words[2]} {words[3]} {words[4]} 00 00 00 00"


def test_7_2_2_2_pvt_pdo_mapping(start_drive_sim, can_bus):
    """Steps 1 to 3 of 7.2.2.2: RPDO2 and RPDO3 remapped in CiA 301's order (COB-ID bit 31
    first), which the AKD takes too; then a PVT segment through them at a SYNC."""
    sim = start_drive_sim("run", "--device", "akd", "--node-id", 1, "--listen", "127.0.0.1:0")
    lst = Listing(can_bus(sim))
    for request in (
        "601 23 01 14 01 01 03 00 80",
        "601 2F 01 16 00 00 00 00 00",
        "601 23 01 16 01 20 01 C1 60",
        "601 23 01 16 02 20 02 C1 60",
        "601 2F 01 16 00 02 00 00 00",
        "601 23 01 14 01 01 03 00 00",
        "601 23 02 14 01 01 04 00 80",
        "601 2F 02 16 00 00 00 00 00",
        "601 23 02 16 01 20 03 C1 60",  # commented "60C1 sub2": sub 3, the velocity
        "601 2F 02 16 00 01 00 00 00",
        "601 23 02 14 01 01 04 00 00",
    ):
        lst.x(request, done(request))
    # Step 2, printed as 4-byte writes (23) to the UNSIGNED8 sub 2: refused for their length.
    lst.x("601 23 01 14 02 01 00 00 00", "581 80 01 14 02 12 00 07 06")
    lst.x("601 2F 01 14 02 01 00 00 00", "581 60 01 14 02 00 00 00 00")
    lst.x("601 2F 02 14 02 01 00 00 00", "581 60 02 14 02 00 00 00 00")
    for request in (
        "601 23 00 18 01 81 02 00 80",
        "601 23 01 18 01 81 02 00 80",
        "601 23 02 18 01 81 03 00 80",
        "601 23 03 18 01 81 04 00 80",
    ):
        lst.x(request, done(request))
    assert [lst.read(1, 0x1601, sub) for sub in range(3)] == [2, 0x60C10120, 0x60C10220]
    assert [lst.read(1, 0x1602, sub) for sub in range(2)] == [1, 0x60C10320]
    # A segment through both RPDOs, applied at the SYNC (transmission type 1).
    lst.put("000 01 01", settle=0.1)
    lst.put("301 00 00 04 00 64 00 00 00")
    lst.put("401 00 00 50 00")
    assert lst.read(1, 0x60C1, 1) != 0x40000
    lst.put("080", settle=0.1)
    assert [lst.read(1, 0x60C1, sub) for sub in (1, 2, 3)] == [0x40000, 100, 0x500000]

