"""Our LSS slave (CiA 305) against a master the project did not write: python-canopen's
`LssMaster`, every service it has, over `drive-sim hub`: switch state global and selective,
configure node-ID and bit timing, activate bit timing, store, inquire identity and node-ID,
identify remote slave, identify non-configured remote slave, fastscan. The drive is a DRVI
started without a node-ID (`--node-id none`) and with its own serial number (`--serial`);
what it stores survives a restart of its process (`--state-dir`).
"""

import time

import pytest

# The DRVI's identity (its EDS), with the serial number the test gives it.
VENDOR, PRODUCT, REVISION, SERIAL = 0x97, 0x5A, 0x1, 1001
# python-canopen waits 0.5 s for every LSS answer; a fastscan step nobody answers costs that
# (dozens per scan). The hub answers within milliseconds; 0.25 s leaves room for a loaded machine.
STEP_TIMEOUT = 0.25


@pytest.fixture
def unconfigured(start_drive_sim, canopen_network, tmp_path):
    hub = start_drive_sim("hub", "--listen", "127.0.0.1:0")
    args = ["run", "--device", "drvi", "--node-id", "none", "--serial", SERIAL, "--state-dir", tmp_path]
    args += ["--bus", hub.bus_spec()]
    sim = start_drive_sim(*args, ready="running on ")
    network = canopen_network(hub)
    time.sleep(0.3)  # python-can's socketcand reader is running before the first request
    network.lss.RESPONSE_TIMEOUT = STEP_TIMEOUT
    return hub, sim, network, args


def test_fastscan_configure_store_and_restart(unconfigured, start_drive_sim, frames, wait_until):
    from canopen.lss import LssError

    hub, sim, network, args = unconfigured
    lss = network.lss
    seen = frames(network, 0x705, 0x7E4)
    # No boot-up, no heartbeat, no SDO server without a node-ID.
    seen.none(0x705, within=0.3)

    found, identity = lss.fast_scan()
    assert found, "fastscan found no device"
    assert identity == [VENDOR, PRODUCT, REVISION, SERIAL]
    # Found: in configuration. A bit rate outside the CiA 305 table is refused (error code 1).
    with pytest.raises(LssError, match="LSS Error: 1"):
        lss.configure_bit_timing(5)
    with pytest.raises(LssError, match="LSS Error: 1"):
        lss.configure_node_id(128)
    lss.configure_bit_timing(0)  # 1000 kbit/s
    lss.configure_node_id(5)
    assert lss.inquire_node_id() == 0xFF, "the new node-ID is pending until the switch to waiting"
    # A store writes and flushes a file (fsync): give it longer than a step.
    lss.RESPONSE_TIMEOUT = 2.0
    t0 = time.monotonic()
    lss.store_configuration()
    print(f"store answered after {time.monotonic() - t0:.3f} s")
    lss.RESPONSE_TIMEOUT = STEP_TIMEOUT
    lss.send_switch_state_global(lss.WAITING_STATE)
    assert seen.next(0x705)[2] == b"\x00", "boot-up with the new node-ID"
    node = network.add_node(5)
    assert node.sdo.upload(0x1018, 4) == SERIAL.to_bytes(4, "little")

    # A restart of the process (a power cycle): the stored node-ID is there at once.
    sim.stop()
    seen.clear()
    start_drive_sim(*args, ready="running on ")
    assert seen.next(0x705, timeout=10)[2] == b"\x00"
    assert node.sdo.upload(0x1018, 1) == VENDOR.to_bytes(4, "little")
    # It takes no part in a fastscan now.
    found, _ = lss.fast_scan()
    assert not found


def test_selective_inquire_identify_and_bit_timing(unconfigured, frames):
    _, _, network, _ = unconfigured
    lss = network.lss
    seen = frames(network, 0x7E4)

    # Identify non-configured remote slave: answered with 50h.
    lss.send_identify_non_configured_remote_slave()
    assert seen.next(0x7E4)[2] == bytes([0x50, 0, 0, 0, 0, 0, 0, 0])
    # Identify remote slave: answered with 4Fh when the identity is in the ranges, else not.
    lss.send_identify_remote_slave(VENDOR, PRODUCT, 0, 10, 1000, 2000)
    assert seen.next(0x7E4)[2] == bytes([0x4F, 0, 0, 0, 0, 0, 0, 0])
    lss.send_identify_remote_slave(VENDOR, PRODUCT, 0, 10, 1002, 2000)
    seen.none(0x7E4, within=0.3)

    # Switch state selective: only the full identity.
    assert not _selective(lss, VENDOR, PRODUCT, REVISION, SERIAL + 1)
    assert _selective(lss, VENDOR, PRODUCT, REVISION, SERIAL)
    from canopen.lss import (
        CS_INQUIRE_PRODUCT_CODE,
        CS_INQUIRE_REVISION_NUMBER,
        CS_INQUIRE_SERIAL_NUMBER,
        CS_INQUIRE_VENDOR_ID,
    )

    assert lss.inquire_lss_address(CS_INQUIRE_VENDOR_ID) == VENDOR
    assert lss.inquire_lss_address(CS_INQUIRE_PRODUCT_CODE) == PRODUCT
    assert lss.inquire_lss_address(CS_INQUIRE_REVISION_NUMBER) == REVISION
    assert lss.inquire_lss_address(CS_INQUIRE_SERIAL_NUMBER) == SERIAL
    assert lss.inquire_node_id() == 0xFF
    lss.configure_bit_timing(2)  # 500 kbit/s
    lss.activate_bit_timing(10)  # no answer; the device reports it
    lss.send_switch_state_global(lss.WAITING_STATE)
    # Back in waiting: the configuration services are not served.
    from canopen.lss import LssError

    with pytest.raises(LssError):
        lss.inquire_node_id()
    # Switch state global to configuration: served again.
    lss.send_switch_state_global(lss.CONFIGURATION_STATE)
    assert lss.inquire_node_id() == 0xFF
    lss.send_switch_state_global(lss.WAITING_STATE)


def _selective(lss, vendor, product, revision, serial):
    from canopen.lss import LssError

    try:
        return lss.send_switch_state_selective(vendor, product, revision, serial)
    except LssError:
        return False
