#!/usr/bin/env python3
"""Peak memory of every `odgen` command on large and hostile inputs, against the budget
"10 x the input size + 64 MB".

    scripts/peak_rss.py [ODGEN] [--corpus DIR] [--small]

ODGEN defaults to target/release/odgen. The inputs are built in a temporary directory (the
shapes an outside robustness run found: 700k junk lines, 7.5k CompactSubObj=255 arrays, a 50 MB
OCTET_STRING, 50M blank lines, 80k unknown sections, a CR-only file of many problems, a UTF-16
file); `--corpus DIR` adds the largest file of a corpus; `--small` makes the inputs ten times
smaller. Each command runs as a child process; its peak resident set size is the child's
`ru_maxrss` from wait4(2), its time the wall time. Output is written to a file, as a user
would redirect it. Prints one line per run and exits 1 when a run is over budget, crashes or
times out (120 s).
"""
import os
import shutil
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def build_inputs(d, scale):
    base = open(os.path.join(ROOT, "eds/tests/fixtures/base.eds")).read()
    n = lambda x: max(1, x // scale)  # noqa: E731
    inputs = {}

    def put(name, text, encoding="utf-8"):
        p = os.path.join(d, name)
        with open(p, "w", encoding=encoding, newline="") as f:
            f.write(text)
        inputs[name] = p

    put("junk-lines.eds", base + "[Tools]\n" + "jnk\n" * n(700_000))
    put("compact-arrays.eds", base + "".join(
        f"[{0x3000 + i:04X}]\nParameterName=A{i}\nObjectType=0x8\nDataType=0x0007\nAccessType=rw\n"
        f"CompactSubObj=255\nPDOMapping=0\n\n" for i in range(n(7_500))))
    put("octet-string.eds", base + "[2100]\nParameterName=Blob\nObjectType=0x7\nDataType=0x000A\n"
        "AccessType=rw\nDefaultValue=" + "AB" * n(25_000_000) + "\nPDOMapping=0\n")
    put("blank-lines.eds", base + "\n" * n(50_000_000))
    put("unknown-sections.eds", base + "".join(f"[Foo{i}]\nKey=v\n" for i in range(n(80_000))))
    put("cr-only.eds", (base + "".join(f"junk {i}\n" for i in range(n(20_000)))).replace("\n", "\r"))
    put("utf16.eds", "\ufeff" + base * 1, encoding="utf-16-le")
    return inputs


COMMANDS = [
    ["check"],
    ["check", "--notes"],
    ["check", "--strict", "--format", "json"],
    ["check", "--format", "sarif"],
    ["dump"],
    ["dump", "--format", "json"],
    ["dcf", "--node-id", "5", "-o", "{out}.dcf"],
    ["fmt", "--check"],
    ["fmt"],
]


def run(odgen, args, path, out_dir):
    args = [a.replace("{out}", os.path.join(out_dir, "out")) for a in args]
    target = path
    if args[0] == "fmt" and "--check" not in args:
        # fmt rewrites its input: give it a copy.
        target = os.path.join(out_dir, "copy-" + os.path.basename(path))
        shutil.copyfile(path, target)  # (streamed: this process must stay small, see main)
    with open(os.path.join(out_dir, "stdout"), "wb") as out, open(os.path.join(out_dir, "stderr"), "wb") as err:
        start = time.monotonic()
        p = subprocess.Popen([odgen] + args + [target], stdout=out, stderr=err)
        deadline = start + 120
        while True:
            pid, status, usage = os.wait4(p.pid, os.WNOHANG)
            if pid:
                break
            if time.monotonic() > deadline:
                p.kill()
                pid, status, usage = os.wait4(p.pid, 0)
                return None, time.monotonic() - start, usage.ru_maxrss * 1024, os.stat(out.name).st_size
            time.sleep(0.005)
        seconds = time.monotonic() - start
    code = os.waitstatus_to_exitcode(status)
    return code, seconds, usage.ru_maxrss * 1024, os.path.getsize(os.path.join(out_dir, "stdout"))


def main():
    argv = sys.argv[1:]
    odgen = os.path.join(ROOT, "target/release/odgen")
    corpus = None
    scale = 1
    while argv:
        a = argv.pop(0)
        if a == "--corpus":
            corpus = argv.pop(0)
        elif a == "--small":
            scale = 10
        else:
            odgen = a
    bad = 0
    with tempfile.TemporaryDirectory() as d:
        # Built in a child process: a child forked from this one later would start with this
        # one's resident pages counted in its own peak (fork copies the page tables), so this
        # process must stay small.
        pid = os.fork()
        if pid == 0:
            build_inputs(d, scale)
            os._exit(0)
        os.waitpid(pid, 0)
        inputs = {name: os.path.join(d, name) for name in sorted(os.listdir(d))}
        if corpus:
            files = [os.path.join(corpus, f) for f in os.listdir(corpus)]
            largest = max(files, key=os.path.getsize)
            inputs["corpus-largest:" + os.path.basename(largest)] = largest
        out_dir = os.path.join(d, "out")
        os.mkdir(out_dir)
        print(f"{'input':<28} {'size MB':>8} {'command':<34} {'exit':>4} {'s':>6} {'peak MB':>8} "
              f"{'budget MB':>9} {'out MB':>8}")
        for name, path in inputs.items():
            size = os.path.getsize(path)
            budget = 10 * size + 64 * 2**20
            for args in COMMANDS:
                code, seconds, peak, out_size = run(odgen, args, path, out_dir)
                ok = code is not None and code >= 0 and peak <= budget
                bad += not ok
                shown = " ".join(args).replace("{out}", "OUT")
                print(f"{name[:28]:<28} {size / 2**20:8.2f} {shown:<34} {'T/O' if code is None else code:>4} "
                      f"{seconds:6.2f} {peak / 2**20:8.1f} {budget / 2**20:9.1f} {out_size / 2**20:8.2f}"
                      f"{'' if ok else '  OVER BUDGET' if code is not None and code >= 0 else '  FAILED'}",
                      flush=True)
    print(f"{bad} run(s) over budget or failed")
    sys.exit(1 if bad else 0)


if __name__ == "__main__":
    main()
