"""Shared fixtures for tests that run `drive-sim` and talk to it over the socketcand protocol.

* `drive_sim_binary` (session): the path of the `drive-sim` binary: $DRIVE_SIM if set,
  otherwise built with cargo (an incremental no-op when up to date).
* `start_drive_sim` (function): a factory. `start_drive_sim("run", "--device", "drvi", ...)`
  starts the binary with those arguments, waits (bounded) for the line that says it is ready
  (by default `listening on ADDRESS`), and returns a `DriveSim` with `.address`, `.host`,
  `.port` and `.log()`. Every process it started is stopped with SIGTERM at teardown (killed
  if it does not stop within 10 s); the test then fails if one exited with an error or
  panicked.
* `start_shared_drive_sim` (module): the same factory for processes a module's tests share.
* `canopen_network` (function): a factory connecting a python-canopen `Network` to a
  `DriveSim` (or to `(host, port)`) through python-can's `socketcand` interface;
  disconnected at teardown.
* `can_bus` (function): the same for a raw python-can bus.
  Both use `RtrSocketcandBus`, python-can's socketcand bus that also sends remote frames (as
  socketcand's `< sendrtr ID DLC >`; the stock interface drops the RTR bit and sends an empty
  data frame), so python-canopen's node guarding and PDO remote requests reach the device.
* `frames` (function): `frames(network, 0x182, 0x702)` records every frame with those ids
  that reaches a python-canopen `Network` (time received, id, data) and waits for them.
* `wait_until(predicate, timeout)`: polls a predicate (bounded) and returns its first true
  value, failing the test on timeout.
* `device_eds`: the EDS path of each simulated device (`device_eds["drvi"]`).

Outside CI, tests skip with the reason when python-can/python-canopen are missing (use the
python printed by scripts/venv.sh) or the binary cannot be had; with CI=true those are
failures. Everything listens on 127.0.0.1, on ports the OS picks (port 0).
"""

import json
import os
import queue
import select
import shutil
import signal
import subprocess
import tempfile
import threading
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
IN_CI = os.environ.get("CI", "").lower() in ("1", "true", "yes")
START_TIMEOUT = 30.0  # seconds for drive-sim to say it is ready
STOP_TIMEOUT = 10.0  # seconds for drive-sim to stop after SIGTERM


def missing(reason):
    """Skips the test with `reason`, or fails it in CI."""
    if IN_CI:
        pytest.fail(reason)
    pytest.skip(reason)


def _build_with_cargo():
    """Builds drive-sim and returns its path, or None when cargo is unavailable."""
    cargo = shutil.which("cargo")
    if cargo is None:
        return None
    result = subprocess.run(
        [cargo, "build", "-p", "drive", "--bin", "drive-sim", "--message-format=json"],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        timeout=1800,
    )
    if result.returncode != 0:
        pytest.fail(f"cargo build of drive-sim failed:\n{result.stderr[-4000:]}")
    for line in result.stdout.splitlines():
        try:
            message = json.loads(line)
        except ValueError:
            continue
        if message.get("reason") == "compiler-artifact" and message.get("target", {}).get("name") == "drive-sim":
            if message.get("executable"):
                return Path(message["executable"])
    pytest.fail("cargo built drive-sim but did not report its path")


@pytest.fixture(scope="session")
def drive_sim_binary():
    explicit = os.environ.get("DRIVE_SIM")
    if explicit:
        path = Path(explicit)
        if not path.is_file():
            pytest.fail(f"DRIVE_SIM={explicit} is not a file")
        return path
    path = _build_with_cargo()
    if path is None:
        missing("drive-sim not available: set DRIVE_SIM to the binary or put cargo on PATH")
    return path


class DriveSim:
    """A running drive-sim process."""

    def __init__(self, binary, args, ready):
        self.args = [str(a) for a in args]
        self._log = tempfile.TemporaryFile(mode="w+")
        self.process = subprocess.Popen(
            [str(binary), *self.args],
            stdout=subprocess.PIPE,
            stderr=self._log,
            stdin=subprocess.DEVNULL,
            text=True,
        )
        self.address = self._wait_ready(ready)
        host, _, port = self.address.rpartition(":")
        self.host = host or None
        self.port = int(port) if port.isdigit() else None
        self.exit_code = None

    def _wait_ready(self, ready):
        deadline = time.monotonic() + START_TIMEOUT
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                self.stop()
                pytest.fail(f"drive-sim {' '.join(self.args)} was not ready within {START_TIMEOUT} s; log:\n{self.log()}")
            readable, _, _ = select.select([self.process.stdout], [], [], left)
            if not readable:
                continue
            line = self.process.stdout.readline()
            if line == "":
                code = self.process.wait(timeout=STOP_TIMEOUT)
                pytest.fail(f"drive-sim {' '.join(self.args)} exited with {code} before it was ready; log:\n{self.log()}")
            if line.startswith(ready):
                return line[len(ready):].strip()

    def log(self):
        """Everything the process wrote to stderr so far."""
        self._log.flush()
        self._log.seek(0)
        text = self._log.read()
        self._log.seek(0, os.SEEK_END)
        return text

    def bus_spec(self, channel="can0"):
        """The `--bus` argument for another drive-sim joining this one's hub."""
        return f"tcp://{self.address}/{channel}"

    def signal(self, signum):
        if self.process.poll() is None:
            self.process.send_signal(signum)

    def stop(self):
        """Stops the process with SIGTERM (SIGKILL after STOP_TIMEOUT) and returns its exit code."""
        if self.exit_code is not None:
            return self.exit_code
        if self.process.poll() is None:
            self.process.send_signal(signal.SIGTERM)
        try:
            self.exit_code = self.process.wait(timeout=STOP_TIMEOUT)
        except subprocess.TimeoutExpired:
            self.process.kill()
            self.process.wait()
            self.exit_code = "killed: did not stop within 10 s of SIGTERM"
        if self.process.stdout:
            self.process.stdout.close()
        return self.exit_code


class _Starter:
    """Starts drive-sim processes and stops them all at the end, reporting failures."""

    def __init__(self, binary):
        self.binary = binary
        self.started = []

    def __call__(self, *args, ready="listening on "):
        sim = DriveSim(self.binary, args, ready)
        self.started.append(sim)
        return sim

    def finish(self):
        problems = []
        # Clients first (processes joined with --bus), then the hubs they joined.
        for sim in reversed(self.started):
            code = sim.stop()
            text = sim.log()
            if code != 0:
                problems.append(f"drive-sim {' '.join(sim.args)} exited with {code}; log:\n{text}")
            elif "panicked" in text:
                problems.append(f"drive-sim {' '.join(sim.args)} panicked; log:\n{text}")
        if problems:
            pytest.fail("\n\n".join(problems))


@pytest.fixture
def start_drive_sim(drive_sim_binary):
    starter = _Starter(drive_sim_binary)
    yield starter
    starter.finish()


@pytest.fixture(scope="module")
def start_shared_drive_sim(drive_sim_binary):
    """Like `start_drive_sim`, for processes shared by the tests of a module (started by a
    module-scoped fixture, stopped after the module's last test)."""
    starter = _Starter(drive_sim_binary)
    yield starter
    starter.finish()


def _python_packages():
    try:
        import can  # noqa: F401
        import canopen  # noqa: F401
    except ImportError as error:
        missing(f"{error}; run the tests with the python printed by scripts/venv.sh")


def _host_port(target):
    if isinstance(target, DriveSim):
        return target.host, target.port
    return target


def rtr_socketcand_bus(channel, host, port):
    """A python-can socketcand bus whose `send` also carries remote frames (see the module doc)."""
    from can.interfaces.socketcand.socketcand import SocketCanDaemonBus

    class RtrSocketcandBus(SocketCanDaemonBus):
        def send(self, msg, timeout=None):
            if not msg.is_remote_frame:
                return super().send(msg, timeout)
            width = 8 if msg.is_extended_id else 3
            self._tcp_send(f"< sendrtr {msg.arbitration_id:0{width}X} {msg.dlc} >")

    return RtrSocketcandBus(channel=channel, host=host, port=port)


@pytest.fixture
def canopen_network():
    _python_packages()
    import canopen

    # python-canopen waits 0.3 s for an SDO response and then aborts the transfer. The test
    # files run six at a time beside the Rust tests, both cores busy: a simulator or the hub
    # scheduled out for longer than that made a read fail now and then (test_drvi_e2e.py, a
    # fresh clone, 2026-12-07: "No SDO response received" in the middle of a move). Sized
    # like `node402`'s waits: a device that does not answer still fails the read, after 1 s.
    # A test that waits for silence on purpose sets its node's own (test_runtime_nmt.py).
    canopen.sdo.SdoClient.RESPONSE_TIMEOUT = 1.0

    networks = []

    def connect(target, channel="can0"):
        host, port = _host_port(target)
        network = canopen.Network(rtr_socketcand_bus(channel, host, port))
        network.connect()
        networks.append(network)
        return network

    yield connect
    for network in networks:
        network.disconnect()


@pytest.fixture
def can_bus():
    _python_packages()
    import can

    buses = []

    def connect(target, channel="can0"):
        host, port = _host_port(target)
        bus = rtr_socketcand_bus(channel, host, port)
        buses.append(bus)
        return bus

    yield connect
    for bus in buses:
        bus.shutdown()


DEVICE_EDS = {
    "drvi": ROOT / "devices" / "camozzi-drvi.eds",
    "drcs": ROOT / "devices" / "camozzi-drcs.eds",
    "akd": ROOT / "devices" / "kollmorgen-akd.eds",
}


@pytest.fixture(scope="session")
def device_eds():
    return dict(DEVICE_EDS)


def node402(node_id, eds):
    """python-canopen's CiA 402 node, with its waits sized for a loaded test machine.

    BaseNode402 gives a periodic TPDO 0.2 s to arrive after each command (TIMEOUT_CHECK_TPDO)
    and a state change 0.8 s: with six test files and their simulators sharing two cores, a
    TPDO on a 50-100 ms event timer came 0.2 s late now and then ("Timeout waiting for updated
    statusword"). A drive that stops sending still fails each wait, only later."""
    import canopen

    node = canopen.BaseNode402(node_id, str(eds))
    node.TIMEOUT_CHECK_TPDO = 1.0
    node.TIMEOUT_SWITCH_OP_MODE = 2.0
    node.TIMEOUT_SWITCH_STATE_SINGLE = 1.0
    node.TIMEOUT_SWITCH_STATE_FINAL = 3.0
    node.TIMEOUT_RESET_FAULT = 1.0
    return node


def _wait_until(predicate, timeout=5.0, interval=0.01, what=None):
    deadline = time.monotonic() + timeout
    while True:
        value = predicate()
        if value:
            return value
        if time.monotonic() > deadline:
            pytest.fail(f"timed out after {timeout} s waiting for {what or predicate}")
        time.sleep(interval)


@pytest.fixture(scope="session")
def wait_until():
    return _wait_until


class Frames:
    """Frames with chosen ids seen by a python-canopen Network, in arrival order."""

    def __init__(self, network, ids):
        self._lock = threading.Lock()
        self._frames = []
        self._queue = queue.Queue()
        for can_id in ids:
            network.subscribe(can_id, self._on_frame)

    def _on_frame(self, can_id, data, timestamp):
        entry = (time.monotonic(), can_id, bytes(data))
        with self._lock:
            self._frames.append(entry)
        self._queue.put(entry)

    def all(self, can_id=None):
        """Every frame so far as (time, id, data), optionally only those with `can_id`."""
        with self._lock:
            return [f for f in self._frames if can_id is None or f[1] == can_id]

    def clear(self):
        with self._lock:
            self._frames.clear()
        while True:
            try:
                self._queue.get_nowait()
            except queue.Empty:
                return

    def next(self, can_id=None, timeout=5.0):
        """The next frame (with `can_id`, skipping others) received from now on or already
        queued, as (time, id, data); fails the test after `timeout` seconds."""
        deadline = time.monotonic() + timeout
        while True:
            left = deadline - time.monotonic()
            try:
                entry = self._queue.get(timeout=max(left, 0))
            except queue.Empty:
                pytest.fail(f"no frame{'' if can_id is None else f' with id {can_id:#x}'} within {timeout} s")
            if can_id is None or entry[1] == can_id:
                return entry

    def none(self, can_id=None, within=0.3):
        """Asserts that no frame (with `can_id`) arrives within `within` seconds."""
        deadline = time.monotonic() + within
        while True:
            left = deadline - time.monotonic()
            if left <= 0:
                return
            try:
                entry = self._queue.get(timeout=left)
            except queue.Empty:
                return
            assert can_id is not None and entry[1] != can_id, f"unexpected frame {entry[1]:#x} {entry[2].hex()}"


@pytest.fixture
def frames():
    def record(network, *ids):
        return Frames(network, ids)

    return record
