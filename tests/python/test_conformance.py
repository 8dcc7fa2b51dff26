"""The findings of an outside conformance run (issue 17), with python-canopen as the master:
each test does what the run did and checks what the drive must do instead. Also the machines
(`drive-sim run --machine PRESET|FILE`) for all three drives."""

import time

import pytest
from conftest import node402

NODE = 6
# 6502h as BaseNode402 reads it, where the drive's own is not what it supports (the DRVI's
# bits: pp, pv, tq, hm).
MODES = {"drvi": 0x0001 | 0x0004 | 0x0008 | 0x0020}


def start_node(start_drive_sim, canopen_network, device_eds, kind, *extra):
    """A started drive of `kind` (NMT operational) with BaseNode402 following its TPDO1 (an
    event timer of 50 ms keeps it fresh)."""
    sim = start_drive_sim("run", "--device", kind, "--node-id", NODE, *extra, "--listen", "127.0.0.1:0")
    network = canopen_network(sim)
    node = node402(NODE, device_eds[kind])
    network.add_node(node)
    if kind in MODES:
        node._op_mode_support = MODES[kind]
    node.sdo[0x1800][5].raw = 50
    node.nmt.state = "OPERATIONAL"
    node.setup_402_state_machine()
    assert node.tpdo[1].wait_for_reception(timeout=1) is not None, "TPDO1 with the statusword"
    return sim, network, node


def enable(node):
    node.state = "OPERATION ENABLED"
    assert node.state == "OPERATION ENABLED"


def set_mode(node, mode):
    """6060h, then Operation enabled again: where 6060h is in an RPDO with the controlword
    (the AKD's), BaseNode402 sends that RPDO with the controlword it last knew."""
    node.op_mode = mode
    enable(node)


def statusword(node):
    return node.sdo[0x6041].raw


def emcy_codes(node):
    return [e.code for e in node.emcy.log]


def wait_for(predicate, timeout, what):
    deadline = time.monotonic() + timeout
    while True:
        value = predicate()
        if value:
            return value
        if time.monotonic() > deadline:
            pytest.fail(f"timed out after {timeout} s waiting for {what}")
        time.sleep(0.01)


def run_velocity(node, velocity, acceleration, seconds):
    node.sdo[0x6083].raw = acceleration
    node.sdo[0x6084].raw = acceleration
    set_mode(node, "PROFILED VELOCITY")
    node.sdo[0x60FF].raw = velocity
    time.sleep(seconds)
    return node.sdo[0x6064].raw


# ---- finding 1: homing attained is a completed homing (DRVI, DRCS) -------------------------


@pytest.mark.parametrize("kind", ["drvi", "drcs"])
def test_homing_attained_is_a_completed_homing(start_drive_sim, canopen_network, device_eds, kind):
    """python-canopen's homing() returns when bit 12 (homing attained) arrives; switching to
    profile position at once must find the homing complete: 2004h = 1 and a move accepted
    (the DRCS refused it with FF13h)."""
    _, _, node = start_node(start_drive_sim, canopen_network, device_eds, kind)
    node.sdo[0x6098].raw = 37
    enable(node)
    assert node.homing(timeout=5)
    node.op_mode = "PROFILED POSITION"  # at once, as a master acting on "attained" does
    time.sleep(0.05)
    assert node.sdo[0x2004].raw == 1, "2004h: homing done"
    assert node.sdo[0x6064].raw == 0
    node.emcy.reset()
    velocity, acceleration = (6000, 600) if kind == "drvi" else (50, 100)
    node.sdo[0x6081].raw = velocity
    node.sdo[0x6083].raw = acceleration
    node.sdo[0x6084].raw = acceleration
    node.sdo[0x607A].raw = 5
    node.controlword = 0x0F  # bit 4 is still set from the homing start
    node.controlword = 0x1F
    node.controlword = 0x0F
    wait_for(lambda: statusword(node) & 0x0400 and node.sdo[0x6064].raw == 5, 5, "the move to 5")
    assert 0xFF13 not in emcy_codes(node)


# ---- AKD ----------------------------------------------------------------------------------


def test_akd_limit_switch_stops_the_trajectory(start_drive_sim, canopen_network, device_eds):
    """Finding 2: beyond the positive limit switch (2 turns on the default machine) the move
    stops there with EMCY 8612h, bits 11 and 7, not target reached; a velocity away from the
    switch moves at once."""
    _, _, node = start_node(start_drive_sim, canopen_network, device_eds, "akd")
    node.sdo[0x6092][1].raw = 10  # 10 units per turn
    node.sdo[0x6081].raw = 10  # 1 turn/s
    node.op_mode = "PROFILED POSITION"
    enable(node)
    node.sdo[0x607A].raw = 25
    node.controlword = 0x1F
    node.controlword = 0x0F
    wait_for(lambda: 0x8612 in emcy_codes(node), 5, "EMCY 8612h")
    time.sleep(0.3)
    error = [e for e in node.emcy.log if e.code == 0x8612][0]
    assert error.register == 0x21
    sw = statusword(node)
    assert sw & 0x0C80 == 0x0880, f"warning, internal limit, target not reached: {sw:04X}"
    assert 20 <= node.sdo[0x6064].raw <= 21
    assert node.sdo[0x606B].raw == 0, "the demand stopped"
    set_mode(node, "PROFILED VELOCITY")
    node.sdo[0x60FF].raw = -1
    wait_for(lambda: node.sdo[0x606C].raw < 0, 0.5, "moving away at once")


def test_akd_homing_defaults_are_readable_and_writable(start_drive_sim, canopen_network, device_eds):
    """Findings 3 and 4: 6099h sub 1 reads the 60 rpm it homes with, 6098h's default 0 can be
    written back, and homing method 12 with the default speeds completes."""
    import canopen

    _, _, node = start_node(start_drive_sim, canopen_network, device_eds, "akd")
    assert node.sdo[0x6099][1].raw == 1, "60 rpm: one motor turn per second"
    assert node.sdo[0x6098].raw == 0
    node.sdo[0x6098].raw = 0
    with pytest.raises(canopen.SdoAbortedError) as reserved:
        node.sdo[0x6098].raw = 3
    assert reserved.value.code == 0x06090030
    node.sdo[0x6098].raw = 12
    set_mode(node, "HOMING")
    node.controlword = 0x1F
    wait_for(lambda: statusword(node) & 0x3400 == 0x1400, 10, "homing 12 completed")


def test_akd_velocity_actual_is_rpm_in_a_pdo(start_drive_sim, canopen_network, device_eds):
    """Finding 5: 606Ch in a TPDO (configured with python-canopen's PDO API) is rpm x 1000,
    over SDO user units x 1000: at -1 turn/s, -60000 and -1000."""
    _, network, node = start_node(start_drive_sim, canopen_network, device_eds, "akd")
    node.tpdo.read()
    tpdo = node.tpdo[3]
    tpdo.clear()
    tpdo.add_variable(0x606C)
    tpdo.trans_type = 1
    tpdo.enabled = True
    tpdo.save()
    set_mode(node, "PROFILED VELOCITY")
    node.sdo[0x60FF].raw = -1
    wait_for(lambda: node.sdo[0x606C].raw == -1000, 2, "606Ch over SDO: -1000")
    # The answer to a SYNC may arrive before a wait_for_reception() would start waiting:
    # watch the PDO's reception time instead.
    before = tpdo.timestamp
    network.sync.transmit()
    wait_for(lambda: tpdo.timestamp != before, 2, "the TPDO after the SYNC")
    assert tpdo[0].raw == -60000


def test_akd_error_register_of_a_following_error(start_drive_sim, canopen_network, device_eds, tmp_path):
    """Finding 11: a following error's EMCY (8611h) has 1001h bit 5 (device profile), not bit
    4 (communication). The machine: an end stop at 1 turn the axis runs into."""
    machine = tmp_path / "wall.toml"
    machine.write_text('travel = "linear"\npositive_end_stop = 1.0\n')
    _, _, node = start_node(start_drive_sim, canopen_network, device_eds, "akd", "--machine", str(machine))
    node.sdo[0x6065].raw = 1
    enable(node)
    run_velocity(node, 5, 100, 0.1)
    wait_for(lambda: 0x8611 in emcy_codes(node), 5, "EMCY 8611h")
    error = [e for e in node.emcy.log if e.code == 0x8611][0]
    assert error.register == 0x21
    assert node.sdo[0x1001].raw & 0x10 == 0


# ---- DRVI ---------------------------------------------------------------------------------


def test_drvi_overlong_rpdo_is_emcy_8220(start_drive_sim, canopen_network, device_eds):
    """Finding 8 (table 6.34): 3 bytes for RPDO1's 2-byte controlword: EMCY 8220h, processed."""
    _, network, node = start_node(start_drive_sim, canopen_network, device_eds, "drvi")
    network.send_message(0x200 + NODE, [0x06, 0x00, 0x00])
    wait_for(lambda: 0x8220 in emcy_codes(node), 2, "EMCY 8220h")
    assert node.sdo[0x6040].raw == 0x06


# ---- every drive --------------------------------------------------------------------------


@pytest.mark.parametrize("kind,index,sub", [("akd", 0x608F, 1), ("drvi", 0x2001, 2), ("drcs", 0x2001, 2)])
def test_a_length_error_wins_over_the_value(start_drive_sim, canopen_network, device_eds, kind, index, sub):
    """Finding 10: 2 bytes to an UNSIGNED32 are 0607 0013h, whether the value would be refused
    (0 divides by zero) or not."""
    import canopen

    _, _, node = start_node(start_drive_sim, canopen_network, device_eds, kind)
    for data in (b"\x00\x00", b"\x10\x00"):
        with pytest.raises(canopen.SdoAbortedError) as abort:
            node.sdo.download(index, sub, data)
        assert abort.value.code == 0x06070013, data


MEASURED = {"drvi": {(0x6041, 0)}, "drcs": {(0x6041, 0), (0x2002, 0), (0x2005, 0)}, "akd": {(0x6041, 0), (0x1002, 0)}}


@pytest.mark.parametrize("kind", ["drvi", "drcs", "akd"])
def test_power_on_values_are_the_eds_defaults(start_drive_sim, canopen_network, device_eds, kind):
    """Finding 12: a master reads every entry with a default and compares it with the EDS;
    only the values the drive measures differ (statusword, inputs, brake, status register)."""
    import canopen

    sim = start_drive_sim("run", "--device", kind, "--node-id", NODE, "--listen", "127.0.0.1:0")
    network = canopen_network(sim)
    node = canopen.RemoteNode(NODE, str(device_eds[kind]))
    network.add_node(node)
    time.sleep(0.1)
    differ = []
    for obj in node.object_dictionary.values():
        variables = obj.values() if hasattr(obj, "values") else [obj]
        for var in variables:
            if "r" not in var.access_type or var.default is None or (var.index, var.subindex) in MEASURED[kind]:
                continue
            if var.data_type in (canopen.objectdictionary.DOMAIN,):
                continue
            value = var.decode_raw(node.sdo.upload(var.index, var.subindex))
            if value != var.default:
                differ.append((hex(var.index), var.subindex, var.default, value))
    assert differ == []


# ---- machines -----------------------------------------------------------------------------


def test_drvi_starts_as_a_free_motor(start_drive_sim, canopen_network, device_eds):
    """Finding 7: the DRVI's default "only motor" is a bare motor: profile velocity at 60 rpm
    runs past the former end stop at 1500 deg without a fault."""
    _, _, node = start_node(start_drive_sim, canopen_network, device_eds, "drvi")
    enable(node)
    p = run_velocity(node, 6000, 600, 5.5)
    assert p > 150_000, p
    assert node.state == "OPERATION ENABLED"
    assert emcy_codes(node) == []


@pytest.mark.parametrize(
    "kind,machine,velocity,acceleration,end",
    [
        # positions in each drive's power-on unit: AKD turns (6064h), DRVI 0.01 deg, DRCS mm
        ("akd", 'travel = "linear"\npositive_end_stop = 1.4\n', 2, 100, 1),
        ("drvi", 'travel = "linear"\npositive_end_stop = 9000.0\nload_inertia = 4.0\n', 6000, 600, 9000),
        ("drcs", 'travel = "linear"\nstroke = 500.0\nnegative_end_stop = -20.0\npositive_end_stop = 150.0\n', 100, 500, 150),
    ],
)
def test_a_machine_file_for_every_drive(
    start_drive_sim, canopen_network, device_eds, tmp_path, kind, machine, velocity, acceleration, end
):
    """`drive-sim run --machine FILE`: the drive runs into the file's end stop."""
    path = tmp_path / f"{kind}.toml"
    path.write_text(machine)
    _, _, node = start_node(start_drive_sim, canopen_network, device_eds, kind, "--machine", str(path))
    enable(node)
    if kind == "drcs":
        assert node.sdo[0x607D][2].raw == 500, "the stroke is the full scale"
        node.sdo[0x6098].raw = 37  # the DRCS moves only after a homing
        assert node.homing(timeout=5)
    p = run_velocity(node, velocity, acceleration, 3)
    assert abs(p - end) <= max(1, end // 100), (p, end)


@pytest.mark.parametrize(
    "kind,preset,velocity,acceleration,beyond",
    [("akd", "free", 5, 100, 5), ("drvi", "drvi-actuator", 6000, 600, None), ("drcs", "free", 360, 1000, 1000)],
)
def test_presets(start_drive_sim, canopen_network, device_eds, kind, preset, velocity, acceleration, beyond):
    """`--machine PRESET`: the AKD and DRCS `free` machines turn on past anything the default
    would stop at; the DRVI's `drvi-actuator` ends on its end stop at 1500 deg."""
    _, _, node = start_node(start_drive_sim, canopen_network, device_eds, kind, "--machine", preset)
    enable(node)
    if kind == "drcs":
        node.sdo[0x6098].raw = 37
        assert node.homing(timeout=5)
    p = run_velocity(node, velocity, acceleration, 4.5)
    if beyond is None:
        assert 149_000 <= p <= 150_000, p
    else:
        assert p > beyond, p
