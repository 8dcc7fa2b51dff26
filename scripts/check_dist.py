"""Checks the odgen binary that scripts/odgen-dist.sh built (a step of scripts/test-all.sh).

Usage: check_dist.py DIST_ODGEN TEST_ODGEN

- On Linux with glibc the binary is linked statically: its ELF header has no interpreter
  (PT_INTERP), so no dynamic loader runs before it does.
- It gives the same output and exit code as the test build (TEST_ODGEN) for `odgen check` of
  the bundled devices and, when $EDS_CORPUS_DIR is set, of the corpus, in every format.
"""

import os
import platform
import struct
import subprocess
import sys

PT_INTERP = 3


def interpreter(path):
    """Whether the ELF file at `path` names a program interpreter (is dynamically linked)."""
    with open(path, "rb") as f:
        head = f.read(64)
        if head[:4] != b"\x7fELF" or head[4] != 2:
            raise SystemExit(f"{path}: not a 64-bit ELF file")
        endian = "<" if head[5] == 1 else ">"
        phoff, = struct.unpack_from(endian + "Q", head, 0x20)
        phentsize, phnum = struct.unpack_from(endian + "HH", head, 0x36)
        f.seek(phoff)
        table = f.read(phentsize * phnum)
    return any(struct.unpack_from(endian + "I", table, i * phentsize)[0] == PT_INTERP for i in range(phnum))


def main():
    dist, test = sys.argv[1], sys.argv[2]
    glibc = platform.system() == "Linux" and platform.libc_ver()[0] == "glibc"
    if glibc and interpreter(dist):
        raise SystemExit(f"{dist} is dynamically linked; scripts/odgen-dist.sh links it statically on Linux with glibc")
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    devices = sorted(os.path.join(root, "devices", f) for f in os.listdir(os.path.join(root, "devices"))
                     if f.endswith((".eds", ".dcf")))
    inputs = [devices]
    corpus = os.environ.get("EDS_CORPUS_DIR")
    if corpus and os.path.isdir(corpus):
        inputs.append([corpus])
    checked = 0
    for paths in inputs:
        for extra in ([], ["--notes"], ["--jobs", "1"], ["--format", "json"], ["--format", "sarif"], ["--strict"]):
            runs = [subprocess.run([exe, "check", *extra, *paths], capture_output=True) for exe in (dist, test)]
            if (runs[0].returncode, runs[0].stdout, runs[0].stderr) != (runs[1].returncode, runs[1].stdout, runs[1].stderr):
                raise SystemExit(f"odgen check {' '.join(extra)} on {len(paths)} path(s): the dist build and the test build differ")
            checked += 1
    print(f"dist odgen: {'static, ' if glibc else ''}the same output as the test build in {checked} runs")


if __name__ == "__main__":
    main()
