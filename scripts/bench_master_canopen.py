"""python-canopen's side of `scripts/bench-master.sh`: expedited SDO reads of 1000h, back to
back, to one node over python-can's socketcand interface; one JSON line with reads per second.

    .venv/bin/python scripts/bench_master_canopen.py HOST:PORT NODE SECONDS
"""
import json
import sys
import time

import can
import canopen

host, port = sys.argv[1].rsplit(":", 1)
node_id = int(sys.argv[2])
seconds = float(sys.argv[3])

network = canopen.Network(can.Bus(interface="socketcand", host=host, port=int(port), channel="can0"))
network.connect()
try:
    node = canopen.RemoteNode(node_id, canopen.ObjectDictionary())
    network.add_node(node)
    node.sdo.upload(0x1000, 0)  # the node answers
    n = 0
    start = time.perf_counter()
    cpu = time.process_time()
    while time.perf_counter() - start < seconds:
        node.sdo.upload(0x1000, 0)
        n += 1
    elapsed = time.perf_counter() - start
    cpu = time.process_time() - cpu
finally:
    network.disconnect()
print(json.dumps({"bench": "python-canopen reads", "nodes": 1, "seconds": round(elapsed, 3), "reads": n,
                  "reads_per_s": round(n / elapsed), "cpu_seconds": round(cpu, 3)}))
