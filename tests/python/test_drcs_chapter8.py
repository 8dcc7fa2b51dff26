"""The Camozzi DRCS manual's chapter 8 ("Programming examples"), replayed frame by frame over
the TCP hub against `drive-sim run --device drcs --node-id 3` (the manual's address 3).

Every request frame of the listing is sent exactly as printed, in the listing's order, with
python-can's socketcand interface, and every response is compared byte for byte with the one
CiA 301 defines for an expedited download (60h, index, sub-index, four zero bytes). Between the
groups the test waits as a master would (for the homing to complete, for the target to be
reached), reading the statusword and the actual values with SDO uploads of its own; those
extra frames only observe. The listing runs without an NMT start, as printed.
"""

import time

import pytest

NODE = 3
REQUEST = 0x600 + NODE
RESPONSE = 0x580 + NODE

# Chapter 8, in order: (group, frame as printed, the manual's description).
LISTING = [
    ("enable", "2B 40 60 00 06 00 00 00", "ready to switch on"),
    ("enable", "2B 40 60 00 07 00 00 00", "Switched on"),
    ("enable", "2B 40 60 00 0F 00 00 00", "Operation enabled"),
    ("homing mode", "2F 60 60 00 06 00 00 00", "set homing mode"),
    ("homing mode", "2F 98 60 00 11 00 00 00", "set homing method to 17"),
    ("homing profile", "23 83 60 00 64 00 00 00", "set acceleration to 100mm/s2"),
    ("homing profile", "23 84 60 00 64 00 00 00", "set deceleration to 100mm/s2"),
    ("homing profile", "23 99 60 01 32 00 00 00", "set fast velocity home to 50mm/s"),
    ("homing profile", "23 99 60 02 32 00 00 00", "set slow velocity home to 50mm/s"),
    ("start homing", "2B 40 60 00 1F 00 00 00", "set start homing"),
    ("start homing", "2B 40 60 00 0F 00 00 00", "reset start command"),
    ("position mode", "2F 60 60 00 01 00 00 00", "set profile position mode"),
    ("motion profile", "23 81 60 00 32 00 00 00", "set velocity to 50mm/s"),
    ("motion profile", "23 83 60 00 64 00 00 00", "set acceleration to 100mm/s2"),
    ("motion profile", "23 84 60 00 64 00 00 00", "set deceleration to 100mm/s2"),
    ("absolute move", "23 7A 60 00 2C 01 00 00", "set target to 300mm"),
    ("absolute move", "2B 40 60 00 1F 00 00 00", "set start command"),
    ("absolute move", "2B 40 60 00 0F 00 00 00", "clear command"),
    ("relative move", "23 7A 60 00 2C 01 00 00", "set target to 300mm"),
    ("relative move", "2B 40 60 00 5F 00 00 00", "set start command"),
    ("relative move", "2B 40 60 00 0F 00 00 00", "clear command"),
    ("velocity mode", "2B 40 60 00 0F 01 00 00", "set motion halted"),
    ("velocity mode", "2F 60 60 00 03 00 00 00", "set profile velocity"),
    ("velocity profile", "23 FF 60 00 32 00 00 00", "set target velocity to 50mm/s"),
    ("velocity profile", "23 83 60 00 64 00 00 00", "set acceleration to 100mm/s2"),
    ("velocity profile", "23 84 60 00 64 00 00 00", "set deceleration to 100mm/s2"),
    ("start/stop", "2B 40 60 00 0F 00 00 00", "set motion start"),
    ("start/stop", "23 FF 60 00 64 00 00 00", "change target velocity to 100mm/s"),
    ("start/stop", "2B 40 60 00 0F 01 00 00", "set motion halted"),
    ("start/stop", "23 FF 60 00 00 00 00 00", "change target velocity to 0mm/s"),
]


class Sdo:
    """Expedited SDO requests on a raw python-can bus, one at a time."""

    def __init__(self, bus):
        self.bus = bus
        self.sent = 0

    def exchange(self, data, timeout=2.0):
        import can

        self.bus.send(can.Message(arbitration_id=REQUEST, data=bytes(data), is_extended_id=False))
        self.sent += 1
        deadline = time.monotonic() + timeout
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                pytest.fail(f"no response to {bytes(data).hex(' ')}")
            msg = self.bus.recv(timeout=left)
            if msg is not None and msg.arbitration_id == RESPONSE:
                return bytes(msg.data)

    def upload(self, index, sub, signed=False):
        answer = self.exchange([0x40, index & 0xFF, index >> 8, sub, 0, 0, 0, 0])
        assert answer[0] & 0xE3 == 0x43, f"upload {index:04X}h/{sub}: {answer.hex(' ')}"
        size = 4 - ((answer[0] >> 2) & 3)
        return int.from_bytes(answer[4 : 4 + size], "little", signed=signed)

    def statusword(self):
        return self.upload(0x6041, 0)

    def wait_statusword(self, mask, value, timeout):
        deadline = time.monotonic() + timeout
        while True:
            sw = self.statusword()
            if sw & mask == value:
                return sw
            if time.monotonic() > deadline:
                pytest.fail(f"statusword {sw:04X}h: bits {mask:04X}h never became {value:04X}h")
            time.sleep(0.02)


def test_chapter_8_programming_examples_frame_by_frame(start_drive_sim, can_bus):
    sim = start_drive_sim("run", "--device", "drcs", "--node-id", NODE, "--listen", "127.0.0.1:0")
    sdo = Sdo(can_bus(sim))
    replayed = []

    def run(group):
        for g, text, what in LISTING:
            if g != group:
                continue
            request = bytes.fromhex(text)
            response = sdo.exchange(request)
            expected = bytes([0x60, request[1], request[2], request[3], 0, 0, 0, 0])
            assert response == expected, f'"{what}" ({text}): {response.hex(" ")}'
            replayed.append(text)

    # Enable the motor to execute the commands.
    run("enable")
    assert sdo.statusword() & 0x6F == 0x27, "Operation enabled"
    assert sdo.upload(0x2005, 0) == 0, "brake released with torque"
    # Switch to the homing mode, set its profile, start it.
    run("homing mode")
    assert sdo.upload(0x6061, 0, signed=True) == 6
    run("homing profile")
    assert sdo.upload(0x2004, 0) == 0, "not homed at start-up"
    run("start homing")
    time.sleep(0.2)
    assert sdo.upload(0x606C, 0, signed=True) < 0, "method 17 searches in the negative direction"
    assert sdo.wait_statusword(0x3400, 0x1400, 15) & 0x3400 == 0x1400, "homing completed: 011"
    assert sdo.upload(0x2004, 0) == 1
    assert sdo.upload(0x6064, 0, signed=True) == 0
    # Profile position: absolute 300 mm, then 300 mm relative.
    run("position mode")
    run("motion profile")
    started = time.monotonic()
    run("absolute move")
    time.sleep(0.5)
    assert sdo.statusword() & 0x1400 == 0x1000, "bit 12 high while the positioning runs"
    sdo.wait_statusword(0x0400, 0x0400, 15)
    took = time.monotonic() - started
    assert 6.3 < took < 8.0, f"300 mm at 50 mm/s with 100 mm/s² takes 6.5 s, took {took:.2f} s"
    assert sdo.upload(0x6064, 0, signed=True) == 300
    assert sdo.statusword() & 0x1000 == 0, "bit 12 low: ready for a new command"
    run("relative move")
    sdo.wait_statusword(0x1400, 0x0400, 15)
    assert sdo.upload(0x6064, 0, signed=True) == 600
    # Profile velocity: halted while configured, then started, changed, halted, zeroed.
    run("velocity mode")
    assert sdo.upload(0x6061, 0, signed=True) == 3
    run("velocity profile")
    time.sleep(0.3)
    assert sdo.upload(0x606C, 0, signed=True) == 0, "halted"
    for g, text, what in LISTING:
        if g != "start/stop":
            continue
        request = bytes.fromhex(text)
        assert sdo.exchange(request) == bytes([0x60, request[1], request[2], request[3], 0, 0, 0, 0]), what
        replayed.append(text)
        if what == "set motion start":
            time.sleep(1.0)
            assert sdo.upload(0x606C, 0, signed=True) == 50
            assert sdo.statusword() & 0x1000 == 0, "moving: bit 12 (zero speed) clear"
        elif what.startswith("change target velocity to 100"):
            time.sleep(1.0)
            assert sdo.upload(0x606C, 0, signed=True) == 100
        elif what == "set motion halted":
            sdo.wait_statusword(0x0400, 0x0400, 5)
            assert sdo.upload(0x606C, 0, signed=True) == 0
    assert sdo.upload(0x60FF, 0, signed=True) == 0
    # The listing is complete, and nothing went wrong on the way.
    assert replayed == [text for _, text, _ in LISTING]
    assert sdo.upload(0x1001, 0) == 0
    assert sdo.upload(0x1003, 0) == 0
