"""Imports the DCFs `odgen dcf --network` writes with python-canopen and compares what it reads
with what our model says they contain.

Usage: import_network.py MANIFEST.json   (written by odgen/tests/it/network_python.rs)

The manifest lists each DCF with the node id and bit rate it was configured for, every
ParameterValue that is an integer, and for each PDO its COB-ID, transmission type, event timer
and mapping. The script imports each file with ``canopen.import_od`` (the node id comes from the
DCF's ``[DeviceComissioning]``), checks the values through ``od[index][sub].value``, then lets
python-canopen read the PDO configuration from the object dictionary the way a master does
before using it (``node.tpdo.read(from_od=True)``, which prefers a DCF's ParameterValue over the
DefaultValue) and compares that too.

Prints one JSON document, ``{"results": [{"path", "checked", "mismatches": [...]}]}``; exits
non-zero only if it cannot run at all.
"""

import json
import sys

import canopen


def entry(od, index, sub):
    obj = od[index]
    if isinstance(obj, canopen.objectdictionary.ODVariable):
        return obj
    return obj[sub]


def check_file(item):
    mismatches = []
    checked = 0

    def expect(what, got, want):
        nonlocal checked
        checked += 1
        if got != want:
            mismatches.append(f"{what}: python-canopen has {got!r}, expected {want!r}")

    try:
        od = canopen.import_od(item["path"])
    except Exception as e:  # noqa: BLE001 - any failure to import is the finding
        return {"path": item["path"], "checked": 0, "mismatches": [f"import failed: {e!r}"]}
    expect("node id", od.node_id, item["node_id"])
    expect("bit rate", od.bitrate, item["bitrate"])
    for index, sub, value in item["values"]:
        try:
            got = entry(od, index, sub).value
        except KeyError:
            got = "<missing>"
        expect(f"0x{index:04X} sub {sub} value", got, value)

    network = canopen.Network()
    node = canopen.RemoteNode(item["node_id"], od)
    network.add_node(node)
    for kind, maps in (("tpdo", node.tpdo), ("rpdo", node.rpdo)):
        maps.read(from_od=True)
        for n, want in item[kind].items():
            pdo = maps[int(n)]
            expect(f"{kind}{n} COB-ID", pdo.cob_id, want["cob_id"])
            expect(f"{kind}{n} enabled", pdo.enabled, want["enabled"])
            expect(f"{kind}{n} transmission type", pdo.trans_type, want["trans_type"])
            if want.get("event_timer") is not None:
                expect(f"{kind}{n} event timer", pdo.event_timer, want["event_timer"])
            got_map = [[v.index, v.subindex, v.length] for v in pdo.map]
            expect(f"{kind}{n} mapping", got_map, want["map"])
    return {"path": item["path"], "checked": checked, "mismatches": mismatches}


def main():
    with open(sys.argv[1], encoding="utf-8") as f:
        manifest = json.load(f)
    print(json.dumps({"results": [check_file(item) for item in manifest["files"]]}))


if __name__ == "__main__":
    main()
