"""python-canopen imports the EDS that `object_dictionary!` writes for an inline dictionary.

The device is examples/inline-macro-user: its object dictionary is declared in Rust, and the
macro writes the matching EDS into the generated module (`io::EDS`), which the binary prints
with `--eds`. python-canopen must read that file as meaning what the declaration says.

The binary comes from $INLINE_MACRO_USER if set; otherwise it is built with cargo (a no-op when
up to date). Outside CI the tests skip, with the reason, when python-canopen is missing (use the
python printed by scripts/venv.sh) or the binary cannot be had; in CI (CI=true) those are
failures.
"""

import json
import os
import shutil
import subprocess
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
IN_CI = os.environ.get("CI", "").lower() in ("1", "true", "yes")
NODE_ID = 0x22

try:
    import canopen
    from canopen.objectdictionary import ODArray, ODRecord, ODVariable
except ImportError as missing:  # pragma: no cover - depends on the environment
    if IN_CI:
        raise
    pytest.skip(
        f"{missing}; run the tests with the python printed by scripts/venv.sh",
        allow_module_level=True,
    )


def _unavailable(message):
    if IN_CI:
        pytest.fail(message)
    pytest.skip(message)


def _build_with_cargo():
    """Builds the example and returns its path, or None when cargo is unavailable."""
    cargo = shutil.which("cargo")
    if cargo is None:
        return None
    result = subprocess.run(
        [cargo, "build", "-p", "inline-macro-user", "--bin", "inline-macro-user", "--message-format=json"],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        timeout=1800,
    )
    if result.returncode != 0:
        pytest.fail(f"cargo build of inline-macro-user failed:\n{result.stderr[-4000:]}")
    for line in result.stdout.splitlines():
        try:
            message = json.loads(line)
        except ValueError:
            continue
        if message.get("reason") == "compiler-artifact" and message.get("target", {}).get("name") == "inline-macro-user":
            if message.get("executable"):
                return Path(message["executable"])
    pytest.fail("cargo built inline-macro-user but did not report its path")


@pytest.fixture(scope="module")
def eds_path(tmp_path_factory):
    explicit = os.environ.get("INLINE_MACRO_USER")
    if explicit:
        binary = Path(explicit)
        if not binary.is_file():
            pytest.fail(f"INLINE_MACRO_USER={explicit} is not a file")
    else:
        binary = _build_with_cargo()
        if binary is None:
            _unavailable("inline-macro-user not available: set INLINE_MACRO_USER to the binary or put cargo on PATH")
    result = subprocess.run([str(binary), "--eds"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, timeout=60)
    assert result.returncode == 0, result.stderr.decode(errors="replace")
    text = result.stdout.decode("utf-8")
    assert text.startswith("[FileInfo]"), text[:200]
    path = tmp_path_factory.mktemp("macro_eds") / "io.eds"
    path.write_bytes(result.stdout)
    return path


@pytest.fixture(scope="module")
def od(eds_path):
    return canopen.import_od(str(eds_path), node_id=NODE_ID)


def test_device_information(od):
    info = od.device_information
    assert info.vendor_name == "Example Automation"
    assert info.vendor_number == 0xABC
    assert info.product_name == "Inline I/O module"
    assert info.product_number == 0x401
    assert info.revision_number == 0x00010002
    assert info.order_code == "IO-8DI-8DO"
    assert info.allowed_baudrates == {125_000, 250_000, 500_000, 1_000_000}
    assert info.nr_of_RXPDO == 1
    assert info.nr_of_TXPDO == 1


def test_every_declared_object_is_there(od):
    declared = {0x1000, 0x1001, 0x1017, 0x1018, 0x1200, 0x1400, 0x1600, 0x1800, 0x1A00,
                0x2000, 0x2001, 0x2002, 0x2003, 0x6000, 0x6200}
    assert set(od.indices) == declared
    assert isinstance(od[0x1018], ODRecord)
    assert isinstance(od[0x6000], ODArray)
    assert isinstance(od[0x2002], ODVariable)


def test_identity_record(od):
    identity = od[0x1018]
    assert identity.name == "Identity object"
    assert identity[0].default == 4
    assert identity[1].name == "Vendor-ID"
    assert identity[1].default == 0xABC
    assert identity[4].default == 0x2A2A
    assert identity[1].data_type == canopen.objectdictionary.UNSIGNED32
    assert identity[1].access_type == "ro"


def test_node_id_relative_defaults_resolve(od):
    assert od[0x1200][1].default == 0x600 + NODE_ID
    assert od[0x1200][2].default == 0x580 + NODE_ID
    assert od[0x1400][1].default == 0x200 + NODE_ID
    assert od[0x1800][1].default == 0x180 + NODE_ID


def test_values_limits_and_types(od):
    filter_time = od[0x2001]
    assert (filter_time.default, filter_time.min, filter_time.max) == (10, 1, 1000)
    assert filter_time.access_type == "rw"
    temperature = od[0x2002]
    assert temperature.data_type == canopen.objectdictionary.REAL32
    assert temperature.default == pytest.approx(21.5)
    assert temperature.pdo_mappable
    assert od[0x2003].default == "cabinet 1"
    assert od[0x6200][2].name == "Output 2"
    assert od[0x6200][2].access_type == "rww"
    assert od[0x6000][1].pdo_mappable


def test_default_pdo_mappings(od):
    rpdo = od[0x1600]
    assert rpdo[0].default == 2
    assert [rpdo[k].default for k in range(1, 9)] == [0x62000108, 0x62000208] + [0] * 6
    tpdo = od[0x1A00]
    assert tpdo[0].default == 3
    assert [tpdo[k].default for k in range(1, 4)] == [0x60000108, 0x60000208, 0x10010008]
    assert od[0x1800][2].default == 1  # synchronous
