# Dumps what python-canopen reads from EDS/DCF files: for each file, every variable with its
# data type and its default value with $NODEID resolved for the node id given first.
# Used by eds/tests/it/corpus_canopen.rs; prints JSON on stdout.
import sys, json, math
import canopen
node = int(sys.argv[1])
out = []
for path in sys.argv[2:]:
    try:
        od = canopen.import_od(path, node)
    except Exception as e:
        out.append({"file": path, "error": f"{type(e).__name__}: {e}"})
        continue
    entries = []
    def emit(var):
        d = var.default
        if isinstance(d, (bytes, bytearray)):
            d = {"bytes": d.hex()}
        elif isinstance(d, bool):
            d = {"int": str(int(d))}
        elif isinstance(d, int):
            d = {"int": str(d)}
        elif isinstance(d, float):
            d = {"real": repr(d)}
        elif isinstance(d, str):
            d = {"text": d}
        else:
            d = None
        entries.append({"index": var.index, "sub": var.subindex, "type": var.data_type, "default": d,
                        "raw": getattr(var, "default_raw", None)})
    for index in od:
        obj = od[index]
        if isinstance(obj, canopen.objectdictionary.ODVariable):
            emit(obj)
        else:
            for sub in obj:
                emit(obj[sub])
    out.append({"file": path, "entries": entries})
json.dump(out, sys.stdout)
