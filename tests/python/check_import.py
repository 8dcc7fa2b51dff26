"""Checks that python-canopen reads the EDS/DCF files we write as meaning what our model says.

Usage: check_import.py MANIFEST.json  (written by eds/tests/it/python_interop.rs)

The manifest lists files and, for each, our model's view: objects, entries, typed values, the
node id. This script imports each file with ``canopen.import_od`` and compares. It prints one
JSON document: ``{"results": [{"path", "checked", "mismatches": [...]}]}``; the Rust test asserts
on it. It exits non-zero only if it cannot run at all.

python-canopen 2.4.1 reads some things differently from CiA 306 (and from us). Each rule below is
what its ``canopen/objectdictionary/eds.py`` does; the expectations are adjusted for it, so a
mismatch here is a real disagreement, not a known quirk:

1. Numbers go through ``int(text, 0)``: CiA 306 octal (``017``) raises ValueError, which
   python-canopen swallows, leaving the value unset (``None``). ``00`` is still 0.
2. ``$NODEID`` is removed with a regex and the rest added to the node id given to ``import_od``
   (or the DCF's ``NodeID`` when none is given). In limits it is not handled at all: None.
3. ``LowLimit``/``HighLimit`` are ``int(text, 0)`` (two's complement wrap for signed types):
   a REAL limit is only kept when it is written as an integer.
4. Values pass configparser with ``inline_comment_prefixes=(';',)``: a ``;`` preceded by white
   space starts a comment, also inside names and strings.
5. ``DataType`` above 0x1B (complex and manufacturer types) becomes DOMAIN unless a section
   ``[<hex>sub1]`` names a basic type (never the case for what we write); values are then
   ``bytes.fromhex`` of the text, so we skip value checks for those entries.
6. A compact ARRAY (``CompactSubObj``) gets a synthetic sub 0 ("Number of entries", no default)
   and sub-objects 1..N copied from the object section with names from ``[xxxxName]``;
   ``[xxxxValue]`` is ignored, so every sub-object has the object's DefaultValue and no
   ParameterValue. A compact RECORD (not CiA 306, but files have them) gets no sub-objects.
7. Objects whose ObjectType is not VAR, DOMAIN, ARRAY or RECORD (NULL, DEFTYPE, DEFSTRUCT) are
   skipped; a sub-section of a skipped object makes the import fail with KeyError.
8. ``[DummyUsage]`` must list all of Dummy0001..Dummy0007 or the import fails.
9. Limits of INTEGER24/40/48/56 are dropped (its two's complement helper knows 8/16/32/64 only).
10. OCTET_STRING and DOMAIN values are ``bytes.fromhex`` of the text: a DOMAIN value we keep as
    text (a file name, ``0``) is None there.

A corpus file that python-canopen cannot import in its original form either is not held
against us when our rewrite fails the same way.
"""

import json
import math
import struct
import sys

import canopen
from canopen.objectdictionary import ODArray, ODRecord, ODVariable


def strip_inline_comment(text):
    """What configparser's inline comment handling leaves of a value (rule 4)."""
    if text is None:
        return None
    for i, ch in enumerate(text):
        if ch == ";" and i > 0 and text[i - 1].isspace():
            return text[:i].strip()
    return text


def int0(text):
    try:
        return int(text.replace(" ", "").upper(), 0)
    except ValueError:
        return None


def expected_value(v, data_type, node_id):
    """What python-canopen makes of one of our DefaultValue/ParameterValue values (rules 1, 2)."""
    if v is None:
        return None
    kind = v["kind"]
    if kind == "int":
        if v["radix"] == "oct" and v["value"] != 0:
            return None
        return v["value"]
    if kind == "nodeid":
        if v["radix"] == "oct" and v["value"] != 0:
            return None
        return None if node_id is None else v["value"] + node_id
    if kind == "real":
        # Our model's number (JSON has no NaN/inf: those come as text only).
        return float(v["value"]) if v.get("value") is not None else float(v["text"])
    if kind == "text":
        if data_type in (0x0A, 0x0F):  # rule 10
            try:
                return bytes.fromhex(v["value"])
            except ValueError:
                return None
        return strip_inline_comment(v["value"])
    if kind == "bytes":
        return bytes.fromhex(v["value"])
    raise AssertionError(f"unknown value kind {kind}")


def expected_limit(v, data_type):
    """What python-canopen makes of a LowLimit/HighLimit (rules 1-3, 9)."""
    if v is None or data_type in (0x10, 0x12, 0x13, 0x14):
        return None
    if v["kind"] in ("int",):
        if v["radix"] == "oct" and v["value"] != 0:
            return None
        return v["value"]
    if v["kind"] == "nodeid":
        return None
    return int0(v["text"])


def same(a, b, data_type):
    if isinstance(a, float) and isinstance(b, float):
        if math.isnan(a) and math.isnan(b):
            return True
        if data_type == 0x08:  # REAL32: compare as the device stores it
            return struct.pack("<f", a) == struct.pack("<f", b)
    return a == b


def check_file(f):
    mismatches = []
    checked = 0

    def mismatch(where, what, ours, theirs):
        mismatches.append({"where": where, "what": what, "ours": repr(ours), "python": repr(theirs)})

    try:
        od = canopen.import_od(f["path"], f["node_id_arg"])
    except Exception as e:  # noqa: BLE001 - any failure is a finding
        if f["expect_import_error"]:
            return {"path": f["path"], "checked": 1, "mismatches": []}
        if f.get("original"):
            try:
                canopen.import_od(f["original"], f["node_id_arg"])
            except Exception as orig:  # noqa: BLE001
                if type(orig) is type(e):
                    return {"path": f["path"], "checked": 1, "mismatches": [],
                            "note": f"the original fails too: {type(e).__name__}: {e}"}
        return {"path": f["path"], "checked": 0,
                "mismatches": [{"where": "file", "what": "import failed", "ours": "importable",
                                "python": f"{type(e).__name__}: {e}"}]}
    if f["expect_import_error"]:
        return {"path": f["path"], "checked": 0,
                "mismatches": [{"where": "file", "what": "import should fail (see rules 7, 8)",
                                "ours": f["expect_import_error"], "python": "imported"}]}

    node_id = f["resolve_node_id"]
    if od.node_id != f["od_node_id"]:
        mismatch("file", "node id", f["od_node_id"], od.node_id)
    checked += 1
    if f["bitrate"]:
        checked += 1
        if od.bitrate != f["bitrate"] * 1000:
            mismatch("file", "bit rate", f["bitrate"] * 1000, od.bitrate)
    if f["comments"]:
        checked += 1
        if od.comments != "\n".join(strip_inline_comment(c) for c in f["comments"]):
            mismatch("file", "comments", f["comments"], od.comments)
    dev = f["device"]
    di = od.device_information
    for key, theirs in [("vendor_name", di.vendor_name), ("vendor_number", di.vendor_number),
                        ("product_name", di.product_name), ("product_number", di.product_number),
                        ("revision_number", di.revision_number)]:
        ours = dev[key]
        if isinstance(ours, str):
            ours = strip_inline_comment(ours)
        if ours is not None:
            checked += 1
            if ours != theirs:
                mismatch("[DeviceInfo]", key, ours, theirs)
    rates = {r * 1000 for r in dev["baud_rates"]}
    checked += 1
    if rates != set(di.allowed_baudrates):
        mismatch("[DeviceInfo]", "baud rates", sorted(rates), sorted(di.allowed_baudrates))

    for obj in f["objects"]:
        index = obj["index"]
        where = f"0x{index:04X}"
        if obj["object_type"] not in (0x2, 0x7, 0x8, 0x9):
            checked += 1
            if index in od and not (1 <= index <= 7):
                mismatch(where, "python-canopen should skip this object type", obj["object_type"], od[index])
            continue
        if index not in od:
            mismatch(where, "object missing", obj["name"], None)
            continue
        if obj["compact"] and obj["object_type"] != 0x8:
            checked += 1
            if len(od[index].subindices) != 0:
                mismatch(where, "compact RECORD should have no sub-objects (rule 6)", 0, len(od[index].subindices))
            continue
        o = od[index]
        checked += 1
        want_class = ODVariable if obj["object_type"] in (0x2, 0x7) else (ODArray if obj["object_type"] == 0x8 else ODRecord)
        if not isinstance(o, want_class):
            mismatch(where, "object class", want_class.__name__, type(o).__name__)
            continue
        if o.name != strip_inline_comment(obj["name"]):
            mismatch(where, "object name", obj["name"], o.name)
        for e in obj["entries"]:
            sub = e["sub"]
            w = f"{where} sub {sub}"
            if isinstance(o, ODVariable):
                var = o
            else:
                if obj["compact"] and sub == 0:
                    continue  # rule 6: synthetic sub 0
                var = o.subindices.get(sub)
                if var is None:
                    mismatch(w, "entry missing", e["name"], None)
                    continue
            checked += 1
            if var.name != strip_inline_comment(e["name"]):
                mismatch(w, "name", e["name"], var.name)
            dt = e["data_type"]
            complex_type = dt > 0x1B
            want_dt = 0x0F if complex_type else dt
            if var.data_type != want_dt:
                mismatch(w, "data type", want_dt, var.data_type)
            if var.access_type != e["access"]:
                mismatch(w, "access", e["access"], var.access_type)
            if var.pdo_mappable != e["pdo_mapping"]:
                mismatch(w, "PDO mapping", e["pdo_mapping"], var.pdo_mappable)
            if complex_type:
                continue  # rule 5
            default = e["default"]
            value = e["parameter_value"]
            if obj["compact"]:
                default = obj["compact_default"]  # rule 6
                value = None
            want = expected_value(default, dt, node_id)
            if not same(want, var.default, dt):
                mismatch(w, "default", want, var.default)
            want = expected_value(value, dt, node_id)
            if not same(want, getattr(var, "value", None), dt):
                mismatch(w, "ParameterValue", want, getattr(var, "value", None))
            for key, attr in (("low_limit", "min"), ("high_limit", "max")):
                want = expected_limit(e[key], dt)
                if want != getattr(var, attr):
                    mismatch(w, key, want, getattr(var, attr))
    return {"path": f["path"], "checked": checked, "mismatches": mismatches}


def main():
    with open(sys.argv[1], encoding="utf-8") as fh:
        manifest = json.load(fh)
    results = [check_file(f) for f in manifest["files"]]
    json.dump({"canopen_version": canopen.__version__, "results": results}, sys.stdout)


if __name__ == "__main__":
    main()
