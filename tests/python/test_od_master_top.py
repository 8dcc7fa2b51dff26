"""`od-master top` in a real terminal (tmux) against the real `drive-sim hub` with the three
simulated drives (DRVI node 2, DRCS node 3, AKD node 4) joined from a `drive-sim run --bus`
process: the nodes appear with their names, NMT state, heartbeat and CiA 402 state; keys select
a node, filter and pause the frames; `q` quits and the terminal is restored (the alternate
screen left, the shell's next line printed).

tmux is installed by scripts/test-all.sh (apt-get); without it the test fails in CI and is
skipped elsewhere, saying so. OD_MASTER points at the od-master binary (otherwise
target/debug/od-master); DRIVE_SIM at drive-sim (see conftest.py)."""

import os
import shutil
import subprocess
import time
import uuid
from pathlib import Path

import pytest

from conftest import ROOT, missing

DRIVES = [("drvi", 2), ("drcs", 3), ("akd", 4)]
EDS = {2: "camozzi-drvi.eds", 3: "camozzi-drcs.eds", 4: "kollmorgen-akd.eds"}


@pytest.fixture
def od_master():
    path = Path(os.environ.get("OD_MASTER") or ROOT / "target" / "debug" / "od-master")
    if not path.is_file():
        missing(f"od-master binary not found at {path} (set OD_MASTER or run `cargo build -p od-master-cli`)")
    return path


@pytest.fixture
def bus(start_drive_sim):
    hub = start_drive_sim("hub", "--listen", "127.0.0.1:0", "--quiet")
    args = ["run", "--bus", hub.bus_spec()]
    for device, node in DRIVES:
        args += ["--device", device, "--node-id", str(node)]
    start_drive_sim(*args, ready="running on ")
    return f"socketcand://{hub.address}/can0"


class Tmux:
    """A tmux server of its own (its own socket), one session of 80x24."""

    def __init__(self):
        self.socket = f"od-top-{uuid.uuid4().hex[:8]}"

    def run(self, *args, check=True):
        return subprocess.run(["tmux", "-L", self.socket, *args], capture_output=True, text=True, check=check)

    def screen(self):
        return self.run("capture-pane", "-p", "-t", "top").stdout

    def keys(self, *keys):
        self.run("send-keys", "-t", "top", *keys)

    def wait_for(self, predicate, what, timeout=15.0):
        end = time.monotonic() + timeout
        while time.monotonic() < end:
            screen = self.screen()
            if predicate(screen):
                return screen
            time.sleep(0.1)
        pytest.fail(f"{what} not on the screen within {timeout} s:\n{self.screen()}")

    def kill(self):
        self.run("kill-server", check=False)


@pytest.fixture
def tmux():
    if shutil.which("tmux") is None:
        missing("tmux is not installed (apt-get install tmux; scripts/test-all.sh installs it)")
    t = Tmux()
    yield t
    t.kill()


def cli(od_master, bus, *args):
    out = subprocess.run([str(od_master), "--bus", bus, *args], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, f"{args}: exit {out.returncode}\n{out.stderr}"


def test_top_shows_the_drives_follows_keys_and_restores_the_terminal(od_master, bus, tmux):
    eds = []
    for node, file in EDS.items():
        eds += ["--eds", f"{node}={ROOT / 'devices' / file}"]
    command = " ".join([str(od_master), "--bus", bus, *eds, "top"])
    # A shell in the pane: after top quits, its exit status and the prompt must come back.
    tmux.run("new-session", "-d", "-s", "top", "-x", "80", "-y", "24", "sh")
    tmux.keys(f"{command}; echo top-exited-$?", "Enter")
    tmux.wait_for(lambda s: "od-master top" in s and "Nodes" in s, "the view")
    assert tmux.run("display", "-p", "-t", "top", "#{alternate_on}").stdout.strip() == "1"

    # Heartbeats every 100 ms and the nodes started: the drives appear, alive and operational.
    for node in (2, 3, 4):
        cli(od_master, bus, "write", str(node), "0x1017", "u16:100")
    cli(od_master, bus, "nmt", "start", "all")
    screen = tmux.wait_for(
        lambda s: all(n in s for n in ("DRVI", "DRCS", "AKD")) and s.count(" oper ") >= 3 and s.count("alive") >= 3,
        "three drives alive and operational",
    )
    assert "sw-on disabled" in screen, screen

    # Select node 3: its CiA 402 state in full below the table.
    tmux.keys("Down")
    tmux.wait_for(lambda s: "node 3, Switch on disabled" in s, "node 3 selected")

    # The frames pane: filtered to node 4's heartbeats, then paused.
    tmux.keys("Tab", "Tab", "/")
    tmux.wait_for(lambda s: "filter (node id, kind)" in s, "the filter prompt")
    tmux.keys("4 heartbeat", "Enter")
    screen = tmux.wait_for(lambda s: "filter: node 4 heartbeat" in s, "the filter")
    frames = screen.split("Frames", 1)[1]
    assert "heartbeat node 4: operational" in frames, screen
    assert "node 2" not in frames and "node 3" not in frames, screen
    tmux.keys("p")
    tmux.wait_for(lambda s: "PAUSED" in s, "paused")

    # q quits; the shell's line comes back and the alternate screen is gone.
    tmux.keys("q")
    screen = tmux.wait_for(lambda s: "top-exited-0" in s, "top's exit")
    assert tmux.run("display", "-p", "-t", "top", "#{alternate_on}").stdout.strip() == "0"
    assert "Nodes" not in screen, screen
    # The terminal is back in cooked mode: a line typed is echoed and run.
    tmux.keys("echo cooked-$((20+22))", "Enter")
    tmux.wait_for(lambda s: "cooked-42" in s, "the shell answering")


def test_top_lists_a_network_description_and_plots_several_values(od_master, bus, tmux):
    """`top networks/example.toml`: the described nodes listed under their names before they are
    heard; booted with `od-master boot` of the same file, they come alive; the DRVI turning, its
    plot opens on position and velocity (two units, two panels) and a third value is added."""
    network = ROOT / "networks" / "example.toml"
    command = " ".join([str(od_master), "--bus", bus, "top", str(network)])
    tmux.run("new-session", "-d", "-s", "top", "-x", "80", "-y", "24", "sh")
    tmux.keys(f"{command}; echo top-exited-$?", "Enter")
    screen = tmux.wait_for(lambda s: all(n in s for n in ("x_axis", "y_axis", "z_axis")), "the described nodes")
    assert screen.count("not heard") == 3, screen

    cli(od_master, bus, "boot", str(network))
    tmux.wait_for(lambda s: s.count(" oper ") >= 3 and s.count("alive") >= 3, "the network booted and alive")
    for accel in ("0x6083", "0x6084"):  # profile acceleration and deceleration
        cli(od_master, bus, "write", "2", accel, "u32:50000")
    cli(od_master, bus, "axis", "2", "enable")
    cli(od_master, bus, "axis", "2", "velocity", "5000")
    tmux.wait_for(lambda s: "op enabled" in s and "50.00rpm" in s, "x_axis turning at 50 rpm")

    # g: the selected node's (x_axis, node 2) position and velocity, one panel each.
    tmux.keys("g")
    screen = tmux.wait_for(lambda s: "Plot: 2 series" in s, "the plot")
    assert "[deg]" in screen and "2 position" in screen, screen
    assert "[rpm]" in screen and "2 velocity" in screen, screen
    # The picker one back (its statusword, which the configured TPDO1 carries), Space adds it.
    tmux.keys("Left")
    tmux.wait_for(lambda s: "node 2 statusword [raw]  (Space adds)" in s, "the statusword picked")
    tmux.keys("Space")
    screen = tmux.wait_for(lambda s: "Plot: 3 series" in s, "three series")
    assert "[raw]" in screen and "2 statusword" in screen, screen
    tmux.keys("Escape")
    tmux.wait_for(lambda s: "Events" in s, "the events back")
    tmux.keys("q")
    tmux.wait_for(lambda s: "top-exited-0" in s, "top's exit")
    assert tmux.run("display", "-p", "-t", "top", "#{alternate_on}").stdout.strip() == "0"
