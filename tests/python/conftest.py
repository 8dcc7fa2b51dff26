"""Shared fixtures for tests that run `drive-sim` and talk to it over the socketcand protocol.

* `drive_sim_binary` (session): the path of the `drive-sim` binary: $DRIVE_SIM if set,
  otherwise built with cargo (an incremental no-op when up to date).
* `start_drive_sim` (function): a factory. `start_drive_sim("run", "--device", "drvi", ...)`
  starts the binary with those arguments, waits (bounded) for the line that says it is ready
  (by default `listening on ADDRESS`), and returns a `DriveSim` with `.address`, `.host`,
  `.port` and `.log()`. Every process it started is stopped with SIGTERM at teardown (killed
  if it does not stop within 10 s); the test then fails if one exited with an error or
  panicked.
* `canopen_network` (function): a factory connecting a python-canopen `Network` to a
  `DriveSim` (or to `(host, port)`) through python-can's `socketcand` interface;
  disconnected at teardown.
* `can_bus` (function): the same for a raw python-can bus.

Outside CI, tests skip with the reason when python-can/python-canopen are missing (use the
python printed by scripts/venv.sh) or the binary cannot be had; with CI=true those are
failures. Everything listens on 127.0.0.1, on ports the OS picks (port 0).
"""

import json
import os
import select
import shutil
import signal
import subprocess
import tempfile
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


@pytest.fixture
def start_drive_sim(drive_sim_binary):
    started = []

    def start(*args, ready="listening on "):
        sim = DriveSim(drive_sim_binary, args, ready)
        started.append(sim)
        return sim

    yield start
    problems = []
    # Clients first (processes joined with --bus), then the hubs they joined.
    for sim in reversed(started):
        code = sim.stop()
        text = sim.log()
        if code != 0:
            problems.append(f"drive-sim {' '.join(sim.args)} exited with {code}; log:\n{text}")
        elif "panicked" in text:
            problems.append(f"drive-sim {' '.join(sim.args)} panicked; log:\n{text}")
    if problems:
        pytest.fail("\n\n".join(problems))


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


@pytest.fixture
def canopen_network():
    _python_packages()
    import canopen

    networks = []

    def connect(target, channel="can0"):
        host, port = _host_port(target)
        network = canopen.Network()
        network.connect(interface="socketcand", channel=channel, host=host, port=port)
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
        bus = can.Bus(interface="socketcand", channel=channel, host=host, port=port)
        buses.append(bus)
        return bus

    yield connect
    for bus in buses:
        bus.shutdown()
