"""The Camozzi DRCS end to end: python-canopen (BaseNode402, SDO, PDO, EMCY) drives
`drive-sim run --device drcs --node-id 3` over the TCP hub.

Covered: the CiA 402 state machine to Operation enabled with BaseNode402; homing with methods
17, 18 (with the polarity reversed, so that the positive search meets the actuator's
proximity) and 37 with the statusword bits of chapter 7; an absolute and a relative move in
millimetres, converted with the sidecar's feed-converter formula (3.6.1) from the 2001h values
read from the drive, then in inches after changing 2001h; profile velocity with halt; a target
outside the software limits (error 7320h by EMCY, the motor does not move); the loss of life
guarding (the DRCS has no heartbeat consumer 1016h) causing the quick stop, Fault and a
communication reset; fault reset; 1010h save, restart of drive-sim with --state-dir, values
restored. The Rust tests (drive/tests/drives_drcs*.rs) convert with the generated units module
itself; here the conversion is the sidecar's formula, checked to be the one the sidecar states.
"""

import time
import tomllib
from fractions import Fraction
from pathlib import Path

import pytest
from conftest import node402

NODE = 3
ROOT = Path(__file__).resolve().parents[2]
SIDECAR = tomllib.loads((ROOT / "devices" / "camozzi-drcs.toml").read_text())

FAST = {"acceleration": 1000, "velocity": 200}  # mm/s², mm/s: quick real-time moves


def start(start_drive_sim, *extra):
    return start_drive_sim("run", "--device", "drcs", "--node-id", NODE, *extra, "--listen", "127.0.0.1:0")


def drcs_node(network, device_eds):
    node = node402(NODE, device_eds["drcs"])
    network.add_node(node)
    return node


@pytest.fixture
def drcs(start_drive_sim, canopen_network, device_eds):
    """A started DRCS (NMT operational) with its CiA 402 state machine set up from its PDOs.

    TPDO1 (the statusword, transmission type 255) has no event timer by default (table 3.1):
    it goes out only when the statusword changes, and BaseNode402 knows the state only from
    TPDOs it received. The master therefore gives it an event timer of 50 ms (1800h sub 5)."""
    sim = start(start_drive_sim)
    network = canopen_network(sim)
    node = drcs_node(network, device_eds)
    node.sdo[0x1800][5].raw = 50
    node.nmt.state = "OPERATIONAL"
    node.setup_402_state_machine()
    assert node.tpdo[1].wait_for_reception(timeout=1) is not None, "TPDO1 with the statusword"
    return sim, network, node


def statusword(node):
    return node.sdo[0x6041].raw


def wait_bits(node, mask, value, timeout, wait_until):
    return wait_until(lambda: statusword(node) & mask == value, timeout=timeout, what=f"statusword & {mask:04X}h == {value:04X}h")


def enable(node):
    node.state = "OPERATION ENABLED"
    assert node.state == "OPERATION ENABLED"


def profile(node, velocity=FAST["velocity"], acceleration=FAST["acceleration"]):
    node.sdo[0x6081].raw = velocity
    node.sdo[0x6083].raw = acceleration
    node.sdo[0x6084].raw = acceleration


def home(node, method, wait_until, speeds=(100, 20), offset=0):
    """Homing with `method`: start with controlword bit 4, wait for 011 (completed)."""
    node.op_mode = "HOMING"
    node.sdo[0x6098].raw = method
    node.sdo[0x6099][1].raw = speeds[0]
    node.sdo[0x6099][2].raw = speeds[1]
    node.sdo[0x607C].raw = offset
    profile(node, acceleration=200)
    node.sdo[0x6040].raw = 0x1F
    wait_bits(node, 0x3400, 0x1400, 15, wait_until)
    node.sdo[0x6040].raw = 0x0F


def move(node, target, wait_until, relative=False):
    node.sdo[0x607A].raw = target
    node.sdo[0x6040].raw = 0x5F if relative else 0x1F
    node.sdo[0x6040].raw = 0x4F if relative else 0x0F
    time.sleep(0.02)
    wait_bits(node, 0x1400, 0x0400, 15, wait_until)


# The feed converter (3.6.1) as the sidecar states it.
def emcy(node, code, wait_until, timeout=2):
    """The first EMCY with `code` logged since the last `node.emcy.reset()` (waits for it)."""
    found = wait_until(lambda: [e for e in node.emcy.log if e.code == code], timeout=timeout, what=f"EMCY {code:04X}h")
    return found[0]


def feed_converter(node):
    return node.sdo[0x2001][1].raw, node.sdo[0x2001][2].raw


def round_half_away(x):
    n = abs(x)
    r = int(n) + (1 if n - int(n) >= Fraction(1, 2) else 0)
    return r if x >= 0 else -r


def mm_to_raw(node, mm):
    num, den = feed_converter(node)
    return round_half_away(Fraction(mm) * num / den)


def raw_to_mm(node, raw):
    num, den = feed_converter(node)
    return Fraction(raw) * den / num


def test_the_sidecar_states_the_formula_used_here():
    (fc,) = [s for s in SIDECAR["scaling"] if s["kind"] == "feed_converter"]
    assert fc["object"] == "0x2001" and fc["subs"] == {"numerator": 1, "denominator": 2}
    assert "value_new = value_default * numerator / denominator" in fc["formula"]
    actuator = SIDECAR["unit_system"][0]
    assert actuator["name"] == "actuator" and actuator["units"]["position"]["unit"] == "mm"


def test_state_machine_to_operation_enabled_with_basenode402(drcs):
    _, _, node = drcs
    assert node.state == "SWITCH ON DISABLED"
    assert node.sdo[0x2005].raw == 1, "brake engaged while torqueless"
    node.state = "READY TO SWITCH ON"
    node.state = "SWITCHED ON"
    enable(node)
    assert node.statusword & 0x6F == 0x27
    assert node.sdo[0x2005].raw == 0
    assert node.sdo[0x2003].raw & (1 << 5), "output Ready"
    node.state = "SWITCH ON DISABLED"
    assert node.sdo[0x2005].raw == 1
    # Only modes 1, 3 and 6 (6502h = 25h).
    assert node.is_op_mode_supported("PROFILED POSITION") and node.is_op_mode_supported("HOMING")
    assert not node.is_op_mode_supported("PROFILED TORQUE")


@pytest.mark.parametrize("method", [17, 18, 37])
def test_homing(drcs, method, wait_until):
    _, _, node = drcs
    if method == 18:
        node.sdo[0x607E].raw = 0x80  # the proximity lies in the drive's positive direction
    enable(node)
    assert node.sdo[0x2004].raw == 0
    node.op_mode = "HOMING"
    node.sdo[0x6098].raw = method
    node.sdo[0x6099][1].raw = 100
    node.sdo[0x6099][2].raw = 20
    profile(node, acceleration=200)
    assert statusword(node) & 0x3400 == 0x0400, "homing not started: 001"
    node.sdo[0x6040].raw = 0x1F
    if method != 37:
        time.sleep(0.2)
        assert statusword(node) & 0x3400 == 0x0000, "homing in progress: 000"
        v = node.sdo[0x606C].raw
        assert (v < 0) if method == 17 else (v > 0), f"method {method} searches the right way: {v}"
        assert node.sdo[0x2003].raw & (1 << 1), "output Busy"
    wait_bits(node, 0x3400, 0x1400, 15, wait_until)
    node.sdo[0x6040].raw = 0x0F
    assert node.sdo[0x6064].raw == 0
    assert node.sdo[0x2004].raw == 1
    assert node.sdo[0x2003].raw & (1 << 4), "output Homing ok"
    assert node.sdo[0x1001].raw == 0


def test_absolute_and_relative_moves_in_mm_and_the_feed_converter(drcs, wait_until):
    _, _, node = drcs
    enable(node)
    home(node, 17, wait_until)
    node.op_mode = "PROFILED POSITION"
    profile(node)
    move(node, mm_to_raw(node, 250), wait_until)
    assert raw_to_mm(node, node.sdo[0x6064].raw) == 250
    move(node, mm_to_raw(node, -75), wait_until, relative=True)
    assert raw_to_mm(node, node.sdo[0x6064].raw) == 175
    # 2001h = 10/254: inches by the formula (the manual's 100/254 is off by ten).
    node.sdo[0x2001][1].raw = 10
    node.sdo[0x2001][2].raw = 254
    assert node.sdo[0x6064].raw == 7, "175 mm = 6.89 in"
    assert node.sdo[0x607D][2].raw == 39, "the 1000 mm full scale in inches"
    profile(node, velocity=8, acceleration=40)  # in/s, in/s²
    move(node, mm_to_raw(node, Fraction(254 * 12, 10)), wait_until)  # 12 in = 304.8 mm
    assert node.sdo[0x6064].raw == 12
    assert raw_to_mm(node, node.sdo[0x6064].raw) == Fraction(3048, 10)
    move(node, mm_to_raw(node, Fraction(-254, 10)), wait_until, relative=True)  # -1 in
    assert node.sdo[0x6064].raw == 11
    # The unit is the PDOs' too: TPDO2 with 6064h on SYNC.
    node.tpdo.read()
    t2 = node.tpdo[2]
    t2.clear()
    t2.add_variable(0x6064)
    t2.trans_type = 1
    t2.cob_id = 0x280 + NODE
    t2.enabled = True
    t2.save()
    received = []
    t2.add_callback(lambda m: received.append(m[0x6064].raw))
    node.network.sync.transmit()
    wait_until(lambda: received, timeout=2, what="TPDO2")
    assert received[-1] == 11
    node.sdo[0x2001][1].raw = 1000  # micrometres
    node.sdo[0x2001][2].raw = 1
    node.network.sync.transmit()
    wait_until(lambda: received and received[-1] == 279_400, timeout=2, what="TPDO2 in µm")


def test_profile_velocity_with_halt(drcs, wait_until):
    _, _, node = drcs
    enable(node)
    home(node, 37, wait_until)
    node.sdo[0x606D].raw = 2  # window 2 mm/s
    node.sdo[0x606E].raw = 20  # for 20 ms
    node.sdo[0x606F].raw = 1  # zero speed below 1 mm/s
    node.sdo[0x6070].raw = 20
    node.sdo[0x6040].raw = 0x10F  # halted
    node.op_mode = "PROFILED VELOCITY"
    profile(node, acceleration=500)
    node.sdo[0x60FF].raw = 100
    time.sleep(0.3)
    assert node.sdo[0x606C].raw == 0, "halted: no motion"
    node.sdo[0x6040].raw = 0x0F
    wait_bits(node, 0x1400, 0x0400, 3, wait_until)  # target reached, moving (bit 12 = 0)
    assert node.sdo[0x606C].raw == 100
    node.sdo[0x6040].raw = 0x10F
    time.sleep(0.05)
    assert statusword(node) & 0x0400 == 0, "decelerating: bit 10 = 0"
    wait_bits(node, 0x1400, 0x1400, 3, wait_until)  # stopped, zero speed
    assert node.sdo[0x606C].raw == 0
    stopped = node.sdo[0x6064].raw
    time.sleep(0.2)
    assert node.sdo[0x6064].raw == stopped
    # Released: it runs again; a negative target velocity reverses.
    node.sdo[0x6040].raw = 0x0F
    node.sdo[0x60FF].raw = -50
    wait_bits(node, 0x1400, 0x0400, 3, wait_until)
    assert node.sdo[0x606C].raw == -50
    node.sdo[0x60FF].raw = 0
    wait_bits(node, 0x1000, 0x1000, 3, wait_until)


def test_software_limit_violation_is_the_manuals_emcy(drcs, wait_until):
    _, _, node = drcs
    enable(node)
    home(node, 17, wait_until)
    node.op_mode = "PROFILED POSITION"
    profile(node)
    assert (node.sdo[0x607D][1].raw, node.sdo[0x607D][2].raw) == (0, 1000)
    move(node, 900, wait_until)
    node.emcy.reset()
    node.sdo[0x607A].raw = 1200
    node.sdo[0x6040].raw = 0x1F
    node.sdo[0x6040].raw = 0x0F
    limit = emcy(node, 0x7320, wait_until)  # "Positioning out of software limits error"
    assert limit.register == 0x01
    time.sleep(0.3)
    assert node.sdo[0x6064].raw == 900, "the motor does not move"
    assert node.sdo[0x606C].raw == 0
    assert statusword(node) & 0x6F == 0x27, "still Operation enabled"
    assert statusword(node) & 0x80, "warning bit 7"
    assert node.sdo[0x1003][1].raw & 0xFFFF == 0x7320
    assert node.sdo[0x603F].raw == 0x7320
    # Relative too.
    node.emcy.reset()
    node.sdo[0x607A].raw = 150
    node.sdo[0x6040].raw = 0x5F
    node.sdo[0x6040].raw = 0x4F
    assert emcy(node, 0x7320, wait_until) is not None
    # A valid target: accepted, the error reset EMCY.
    node.emcy.reset()
    move(node, 1000, wait_until)
    assert node.sdo[0x6064].raw == 1000
    assert emcy(node, 0x0000, wait_until) is not None
    assert statusword(node) & 0x80 == 0
    assert node.sdo[0x1001].raw == 0


def test_life_guarding_loss_causes_the_quick_stop(drcs, frames, wait_until):
    _, network, node = drcs
    import canopen

    with pytest.raises(canopen.SdoAbortedError) as no_consumer:
        node.sdo.upload(0x1016, 1)
    assert no_consumer.value.code == 0x06020000, "the DRCS has no heartbeat consumer (1016h)"
    enable(node)
    home(node, 37, wait_until)
    node.op_mode = "PROFILED VELOCITY"
    profile(node, acceleration=100)
    node.sdo[0x60FF].raw = 100
    time.sleep(1.2)
    assert node.sdo[0x606C].raw == 100
    seen = frames(network, 0x700 + NODE)
    node.sdo[0x100C].raw = 100  # guard time 100 ms
    node.sdo[0x100D].raw = 3  # life time factor: 300 ms
    node.nmt.start_node_guarding(0.05)  # python-canopen's guarding master (RTR frames)
    try:
        replies = [seen.next(0x700 + NODE, timeout=2)[2] for _ in range(6)]
        assert all(r[0] & 0x7F == 5 for r in replies), "guarding answered: operational"
        assert len({r[0] & 0x80 for r in replies}) == 2, "toggle bit"
        node.emcy.reset()
    finally:
        node.nmt.stop_node_guarding()
    # The master is gone: 8130h (generic + communication), a quick stop on 6084h (1 s from
    # 100 mm/s), Fault, then the communication resets (boot-up, pre-operational).
    lost_emcy = emcy(node, 0x8130, wait_until)
    assert lost_emcy.register == 0x11
    lost = time.monotonic()
    time.sleep(0.3)
    v = node.sdo[0x606C].raw
    assert 0 < v < 100, f"ramping down on the quick stop ramp: {v}"
    seen.clear()
    boot = seen.next(0x700 + NODE, timeout=3)
    assert boot[2] == b"\x00", "boot-up after the communication reset"
    assert 0.8 < boot[0] - lost < 1.8, f"after the 1 s ramp: {boot[0] - lost:.2f} s"
    assert node.sdo[0x606C].raw == 0
    assert statusword(node) & 0x4F == 0x08, "Fault"
    assert node.sdo[0x603F].raw == 0x8130


def test_fault_reset(drcs, wait_until):
    _, _, node = drcs
    enable(node)
    node.op_mode = "HOMING"
    node.sdo[0x6099][1].raw = 0  # zero homing speeds: homing error 8613h, a soft error
    node.emcy.reset()
    node.sdo[0x6040].raw = 0x1F
    assert emcy(node, 0x8613, wait_until) is not None
    wait_until(lambda: node.is_faulted() or statusword(node) & 0x4F == 0x08, timeout=2, what="Fault")
    assert statusword(node) & 0x2000, "homing error bit 13"
    assert node.sdo[0x2003].raw & 1, "output Alarm"
    # 0 into 1003h sub 0 clears the history, nothing more on the DRCS.
    node.sdo[0x1003][0].raw = 0
    assert node.sdo[0x1003][0].raw == 0
    assert statusword(node) & 0x4F == 0x08
    # Controlword bit 7, 0 -> 1.
    node.emcy.reset()
    node.sdo[0x6040].raw = 0x0F
    node.sdo[0x6040].raw = 0x8F
    assert emcy(node, 0x0000, wait_until) is not None
    wait_until(lambda: statusword(node) & 0x4F == 0x40, timeout=2, what="Switch on disabled")
    assert node.sdo[0x603F].raw == 0
    assert node.sdo[0x2003].raw & 1 == 0
    enable(node)
    home(node, 37, wait_until)


def test_save_restart_restored(start_drive_sim, canopen_network, device_eds, tmp_path):
    state = tmp_path / "state"
    sim = start(start_drive_sim, "--state-dir", state)
    node = drcs_node(canopen_network(sim), device_eds)
    values = {
        (0x2001, 1): 25,
        (0x2001, 2): 2,
        (0x6081, 0): 123,
        (0x6083, 0): 456,
        (0x6098, 0): 18,
        (0x6099, 1): 40,
        (0x607C, 0): -7,
        (0x606D, 0): 3,
        (0x1017, 0): 250,
    }
    for (index, sub), value in values.items():
        (node.sdo[index] if sub == 0 else node.sdo[index][sub]).raw = value
    node.sdo[0x6060].raw = 3  # not in the manual's store list
    node.store()  # 1010h sub 1 "save"
    sim.stop()
    assert sim.exit_code == 0
    assert any(state.iterdir()), "something was saved"

    sim = start(start_drive_sim, "--state-dir", state)
    node = drcs_node(canopen_network(sim), device_eds)
    for (index, sub), value in values.items():
        assert (node.sdo[index] if sub == 0 else node.sdo[index][sub]).raw == value, f"{index:04X}h/{sub}"
    assert node.sdo[0x6060].raw == 0
    assert node.sdo[0x607D][2].raw == 12_500, "the restored 2001h is in force"
    # 1011h "load": the defaults from the next restart on.
    node.restore()
    sim.stop()
    sim = start(start_drive_sim, "--state-dir", state)
    node = drcs_node(canopen_network(sim), device_eds)
    assert node.sdo[0x2001][1].raw == 1
    assert node.sdo[0x6081].raw == 0
    assert node.sdo[0x1017].raw == 0
