#!/usr/bin/env python3
"""Compares the writes `od-master boot` makes for a network with the concise DCFs Lely's
`dcfgen` generates for the same network.

    scripts/dcfgen-compare.py [networks/example.toml]

Needs `dcfgen` (Lely's dcf-tools, from the Python registry: `pip install dcf-tools`; the
test venv of scripts/venv.sh has it, or set DCFGEN), and the `odgen` and `od-master` binaries
(ODGEN, OD_MASTER; default target/debug/). It

1. writes the network's DCFs with `odgen dcf --network` and translates the description into
   dcfgen's YAML: each node's EDS, node id, `heartbeat_producer`, each PDO the file configures
   (`cob_id: auto`, transmission type, inhibit time and event timer as the file sets them, the
   mapping as the DCF has it) and every other parameter as an `sdo` entry;
2. runs dcfgen and reads each node's `.bin` (CiA 302-3: a u32 count, then u16 index, u8
   sub-index, u32 size and the bytes);
3. reads `od-master boot --plan --json` (the writes od-master makes, without a bus);
4. prints, per node, the writes only one of them makes, and whether the writes both make come
   in the same order. Exit code 0 when the only differences are those listed in KNOWN.

The agreed set is pinned by od-codegen's test `concise::example_network_writes`, which does not
need Lely installed; this script is how it was checked and how to check it again.
"""

import configparser
import json
import os
import shutil
import struct
import subprocess
import sys
import tempfile
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

# The differences understood (see networks/README.md, "What boot writes"):
# - dcfgen rewrites the whole mapping of every PDO it is given (sub 0 = 0, the entries, sub 0 =
#   n), even when the mapping equals the device's default; od-master writes a mapping only when
#   an entry of it differs, so a PDO whose mapping is already right gets only its COB-ID and
#   communication parameters.
# - dcfgen writes every `sdo` entry it is given; od-master writes a parameter only when it
#   differs from the EDS default (the rule of a concise DCF; dcfgen applies it to the
#   heartbeat, the PDO communication parameters and the other named settings).
# - od-master disables every PDO it rewrites, also one whose default COB-ID is disabled
#   already (dcfgen leaves that write out): a node configured by an earlier boot runs the PDO
#   and would refuse the new mapping.
KNOWN = {"mapping equal to the default", "parameter equal to the default", "PDO disabled by default"}


def tool(env, name):
    path = os.environ.get(env)
    if path:
        return path
    local = ROOT / "target" / "debug" / name
    if local.exists():
        return str(local)
    found = shutil.which(name) or (Path(sys.executable).parent / name)
    return str(found)


def read_ini(path):
    ini = configparser.ConfigParser(strict=False, interpolation=None)
    ini.optionxform = str
    ini.read(path, encoding="latin-1")
    return ini


def entry_value(ini, index, sub, key):
    for section in (f"{index:04X}sub{sub:X}", f"{index:04x}sub{sub:x}") + ((f"{index:04X}",) if sub == 0 else ()):
        if ini.has_section(section) and ini.has_option(section, key):
            return ini.get(section, key)
    return None


def as_int(text, node_id):
    text = text.strip().upper().replace("$NODEID", str(node_id))
    total = 0
    for part in text.split("+"):
        part = part.strip()
        total += int(part, 0)
    return total


def yaml_config(network_path, dcf_dir):
    net = tomllib.loads(network_path.read_text())
    lines = ["master:", "  node_id: 1", f"  baudrate: {net['network']['baud_rate']}"]
    for name, node in net["nodes"].items():
        node_id = node["node_id"]
        eds = (network_path.parent / node["device"]).resolve()
        dcf = read_ini(dcf_dir / f"{name}.dcf")
        lines += [f"{name}:", f'  dcf: "{eds}"', f"  node_id: {node_id}"]
        params = dict(node.get("parameters", {}))
        hb = params.pop("producer_heartbeat_time", None)
        if hb is not None:
            lines.append(f"  heartbeat_producer: {hb}")
        for kind, comm_base in (("rpdo", 0x1400), ("tpdo", 0x1800)):
            pdos = {int(k[4:]): v for k, v in node.items() if k.startswith(kind)}
            if not pdos:
                continue
            lines.append(f"  {kind}:")
            for n, spec in sorted(pdos.items()):
                spec = spec if isinstance(spec, dict) else {"map": spec}
                comm, mapping = comm_base + n - 1, comm_base + n - 1 + 0x200
                lines += [f"    {n}:", "      enabled: true", "      cob_id: auto"]
                for key, sub, yaml_key in (("transmission_type", 2, "transmission"), ("inhibit_time", 3, "inhibit_time"),
                                           ("event_timer", 5, "event_timer")):
                    if key in spec:
                        lines.append(f"      {yaml_key}: {spec[key]}")
                count = as_int(entry_value(dcf, mapping, 0, "ParameterValue"), node_id)
                lines.append("      mapping:")
                for sub in range(1, count + 1):
                    v = as_int(entry_value(dcf, mapping, sub, "ParameterValue"), node_id)
                    lines.append(f"        - {{index: 0x{v >> 16:04X}, sub_index: {(v >> 8) & 0xFF}}}")
        if params:
            # The other parameters by index: the DCF's configured entries outside 1017h and
            # the PDO objects.
            lines.append("  sdo:")
            for key, value in params.items():
                index, sub = resolve_param(dcf, key)
                v = as_int(entry_value(dcf, index, sub, "ParameterValue"), node_id)
                lines.append(f"    - {{index: 0x{index:04X}, sub_index: {sub}, value: {v}}}")
    return "\n".join(lines) + "\n"


def resolve_param(dcf, key):
    if key.lower().startswith("0x"):
        index, sub = key.lower()[2:].split("sub")
        return int(index, 16), int(sub, 16)
    # A name: the entry whose ParameterName, in snake_case, is the key.
    for section in dcf.sections():
        name = dcf.get(section, "ParameterName", fallback="")
        snake = "".join(c if c.isalnum() else "_" for c in name.lower()).strip("_")
        while "__" in snake:
            snake = snake.replace("__", "_")
        if snake == key and dcf.has_option(section, "DataType"):
            head = section.lower()
            if "sub" in head:
                index, sub = head.split("sub")
                return int(index, 16), int(sub, 16)
            return int(head, 16), 0
    raise KeyError(key)


def read_bin(path):
    data = path.read_bytes()
    (count,) = struct.unpack_from("<I", data, 0)
    at, out = 4, []
    for _ in range(count):
        index, sub, size = struct.unpack_from("<HBI", data, at)
        at += 7
        out.append((index, sub, data[at:at + size].hex()))
        at += size
    return out


def main():
    network = Path(sys.argv[1] if len(sys.argv) > 1 else ROOT / "networks" / "example.toml").resolve()
    odgen, od_master, dcfgen = tool("ODGEN", "odgen"), tool("OD_MASTER", "od-master"), tool("DCFGEN", "dcfgen")
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        subprocess.run([odgen, "dcf", "--network", str(network), "-o", str(tmp)], check=True, capture_output=True)
        (tmp / "out").mkdir()
        config = tmp / "master.yml"
        config.write_text(yaml_config(network, tmp))
        made = subprocess.run([dcfgen, "-d", str(tmp / "out"), str(config)], capture_output=True, text=True)
        if made.returncode != 0:
            print(config.read_text(), made.stdout, made.stderr, sep="\n")
            return 2
        plan = subprocess.run([od_master, "--json", "boot", "--plan", str(network)], check=True, capture_output=True,
                              text=True).stdout
        ours = {}
        for line in plan.splitlines():
            obj = json.loads(line)
            ours[obj["name"]] = [(w["index"], w["sub"], bytes(w["data"]).hex(), w["role"]) for w in obj["writes"]]
        unexplained = 0
        for name, writes in ours.items():
            lely = read_bin(tmp / "out" / f"{name}.bin")
            mine = [(i, s, d) for i, s, d, _ in writes]
            print(f"{name}: od-master {len(mine)} writes, dcfgen {len(lely)}")
            only_lely = [w for w in lely if w not in mine]
            only_ours = [w for w in mine if w not in lely]
            for index, sub, data in only_lely:
                why = explain(index, sub, lely, writes)
                unexplained += why not in KNOWN
                print(f"  only dcfgen:   {index:04X}h sub {sub} = {data}  ({why})")
            roles = {(i, s, d): r for i, s, d, r in writes}
            for index, sub, data in only_ours:
                why = "PDO disabled by default" if roles[(index, sub, data)] == "pdo_disable" else "unexplained"
                unexplained += why not in KNOWN
                print(f"  only od-master: {index:04X}h sub {sub} = {data}  ({why})")
            common = [w for w in lely if w in mine]
            if common != [w for w in mine if w in lely]:
                unexplained += 1
                print("  the writes both make come in another order")
            else:
                print(f"  {len(common)} writes in common, in the same order")
        print("every difference is understood" if not unexplained else f"{unexplained} differences not understood")
        return 1 if unexplained else 0


def explain(index, sub, lely, ours):
    if 0x1600 <= index <= 0x17FF or 0x1A00 <= index <= 0x1BFF:
        if not any(i == index for i, _, _, _ in ours):
            return "mapping equal to the default"
    if index >= 0x2000 or index == 0x1017:
        return "parameter equal to the default"
    return "unexplained"


if __name__ == "__main__":
    sys.exit(main())
