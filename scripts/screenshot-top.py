#!/usr/bin/env python3
"""The README's screenshots of `od-master top`, made from a real terminal: `drive-sim hub` with
the three simulated drives (DRVI node 2, DRCS node 3, AKD node 4), `od-master top
networks/example.toml` in tmux (80x24), the network booted with `od-master boot`, the DRVI
turning, the DRCS refusing to move before homing (its EMCY), then the DRVI's plot. Each screen
is captured with its colours (`tmux capture-pane -e -p`) and drawn into a PNG: the text in DejaVu
Sans Mono, box lines, block elements and Braille dots drawn as shapes (so that lines join and the
plots look as in a terminal, whatever the font has).

    cargo build -p od-master-cli -p drive --bin drive-sim
    python3 -m venv target/docs-venv && target/docs-venv/bin/pip install -r requirements-docs.txt
    target/docs-venv/bin/python scripts/screenshot-top.py [DRIVE_SIM OD_MASTER]

writes docs/top.png (the nodes, events and frames) and docs/top-plot.png (a plot of three
values). Needs tmux and Pillow (requirements-docs.txt).
"""
import os
import re
import select
import shutil
import subprocess
import sys
import time
import uuid
from pathlib import Path

try:
    from PIL import Image, ImageDraw, ImageFont
except ImportError:
    sys.exit("screenshot-top: Pillow is missing: pip install -r requirements-docs.txt (see this script's doc)")

ROOT = Path(__file__).resolve().parent.parent
SIM = Path(sys.argv[1] if len(sys.argv) > 1 else ROOT / "target" / "debug" / "drive-sim")
TOP = Path(sys.argv[2] if len(sys.argv) > 2 else ROOT / "target" / "debug" / "od-master")
NETWORK = ROOT / "networks" / "example.toml"
COLS, ROWS = 80, 24
FONT_DIRS = ["/usr/share/fonts", "/usr/local/share/fonts", os.path.expanduser("~/.fonts"), "/Library/Fonts"]
FONT_SIZE = 15

# A dark terminal's palette (the 16 ANSI colours), default foreground and background.
PALETTE = [
    (0x1D, 0x1F, 0x21), (0xCC, 0x66, 0x66), (0xB5, 0xBD, 0x68), (0xF0, 0xC6, 0x74),
    (0x81, 0xA2, 0xBE), (0xB2, 0x94, 0xBB), (0x8A, 0xBE, 0xB7), (0xC5, 0xC8, 0xC6),
    (0x96, 0x98, 0x96), (0xF2, 0x77, 0x7A), (0xD0, 0xE0, 0x8A), (0xFF, 0xE0, 0x8A),
    (0xA3, 0xC4, 0xE8), (0xD8, 0xB0, 0xE0), (0x9F, 0xE0, 0xD8), (0xFF, 0xFF, 0xFF),
]
FG, BG = (0xC5, 0xC8, 0xC6), (0x1D, 0x1F, 0x21)


def fail(message):
    sys.exit(f"screenshot-top: {message}")


def find_font(name):
    for d in FONT_DIRS:
        for root, _, files in os.walk(d):
            if name in files:
                return os.path.join(root, name)
    fail(f"no {name} under {', '.join(FONT_DIRS)} (install fonts-dejavu-core)")


def colour_256(n):
    if n < 16:
        return PALETTE[n]
    if n < 232:
        n -= 16
        steps = [0, 95, 135, 175, 215, 255]
        return steps[n // 36], steps[n // 6 % 6], steps[n % 6]
    v = 8 + 10 * (n - 232)
    return v, v, v


class Cell:
    __slots__ = ("ch", "fg", "bg", "bold", "dim", "reverse")


def parse(text):
    """The screen of `capture-pane -e -p`: ROWS lines of COLS cells, each a character and its
    style (SGR sequences: colours 16, 256 and RGB, bold, dim, reverse)."""
    screen = []
    style = dict(fg=None, bg=None, bold=False, dim=False, reverse=False)
    for line in text.split("\n")[:ROWS]:
        row = []
        for token in re.finditer(r"\x1b\[([0-9;:]*)m|\x1b[^m]*?[A-Za-z]|(.)", line):
            if token.group(2) is not None:
                c = Cell()
                c.ch = token.group(2)
                for k, v in style.items():
                    setattr(c, k, v)
                row.append(c)
                continue
            if token.group(1) is None:
                continue  # another escape sequence: nothing to draw
            codes = [int(x) if x else 0 for x in re.split("[;:]", token.group(1))] or [0]
            i = 0
            while i < len(codes):
                n = codes[i]
                if n == 0:
                    style = dict(fg=None, bg=None, bold=False, dim=False, reverse=False)
                elif n == 1:
                    style["bold"] = True
                elif n == 2:
                    style["dim"] = True
                elif n == 22:
                    style["bold"] = style["dim"] = False
                elif n == 7:
                    style["reverse"] = True
                elif n == 27:
                    style["reverse"] = False
                elif 30 <= n <= 37 or 90 <= n <= 97:
                    style["fg"] = PALETTE[n - 30 if n < 90 else n - 90 + 8]
                elif 40 <= n <= 47 or 100 <= n <= 107:
                    style["bg"] = PALETTE[n - 40 if n < 100 else n - 100 + 8]
                elif n == 39:
                    style["fg"] = None
                elif n == 49:
                    style["bg"] = None
                elif n in (38, 48) and i + 1 < len(codes):
                    key = "fg" if n == 38 else "bg"
                    if codes[i + 1] == 5 and i + 2 < len(codes):
                        style[key] = colour_256(codes[i + 2])
                        i += 2
                    elif codes[i + 1] == 2 and i + 4 < len(codes):
                        style[key] = tuple(codes[i + 2 : i + 5])
                        i += 4
                i += 1
        screen.append(row)
    return screen


# Box drawing: which of (up, down, left, right) each character joins.
BOX = {
    "─": "lr", "│": "ud", "┌": "dr", "┐": "dl", "└": "ur", "┘": "ul", "├": "udr", "┤": "udl",
    "┬": "dlr", "┴": "ulr", "┼": "udlr", "╭": "dr", "╮": "dl", "╰": "ur", "╯": "ul",
}
# Block elements: the part of the cell filled, as fractions (x0, y0, x1, y1).
BLOCKS = {"█": (0, 0, 1, 1), "▀": (0, 0, 1, 0.5), "▄": (0, 0.5, 1, 1), "▌": (0, 0, 0.5, 1), "▐": (0.5, 0, 1, 1)}
# Braille: bit -> (column, row) of the dot in the 2x4 grid.
BRAILLE = [(0, 0), (0, 1), (0, 2), (1, 0), (1, 1), (1, 2), (0, 3), (1, 3)]


def render(screen, path):
    regular = ImageFont.truetype(find_font("DejaVuSansMono.ttf"), FONT_SIZE)
    bold = ImageFont.truetype(find_font("DejaVuSansMono-Bold.ttf"), FONT_SIZE)
    w = round(regular.getlength("M"))
    ascent, descent = regular.getmetrics()
    h = ascent + descent
    pad = 10
    image = Image.new("RGB", (COLS * w + 2 * pad, ROWS * h + 2 * pad), BG)
    draw = ImageDraw.Draw(image)
    for y, row in enumerate(screen):
        for x, c in enumerate(row[:COLS]):
            fg, bg = c.fg or FG, c.bg or BG
            if c.reverse:
                fg, bg = bg, fg
            if c.dim:
                fg = tuple((a + b) // 2 for a, b in zip(fg, bg))
            x0, y0 = pad + x * w, pad + y * h
            if bg != BG:
                draw.rectangle([x0, y0, x0 + w - 1, y0 + h - 1], fill=bg)
            ch = c.ch
            if ch == " ":
                continue
            if ch in BOX:
                cx, cy = x0 + w // 2, y0 + h // 2
                joins = BOX[ch]
                if "l" in joins:
                    draw.line([x0, cy, cx, cy], fill=fg)
                if "r" in joins:
                    draw.line([cx, cy, x0 + w - 1, cy], fill=fg)
                if "u" in joins:
                    draw.line([cx, y0, cx, cy], fill=fg)
                if "d" in joins:
                    draw.line([cx, cy, cx, y0 + h - 1], fill=fg)
            elif ch in BLOCKS:
                a, b, c2, d = BLOCKS[ch]
                draw.rectangle([x0 + a * w, y0 + b * h, x0 + c2 * w - 1, y0 + d * h - 1], fill=fg)
            elif 0x2800 <= ord(ch) <= 0x28FF:
                bits = ord(ch) - 0x2800
                for bit, (col, line) in enumerate(BRAILLE):
                    if bits >> bit & 1:
                        px = x0 + (col * 2 + 1) * w / 4
                        py = y0 + (line * 2 + 1) * h / 8
                        draw.ellipse([px - 1.5, py - 1.5, px + 1.5, py + 1.5], fill=fg)
            else:
                draw.text((x0, y0), ch, font=bold if c.bold else regular, fill=fg)
    image = image.quantize(colors=64, dither=Image.Dither.NONE)
    image.save(path, optimize=True)
    return path.stat().st_size


class Proc:
    """A drive-sim process, ready once it prints `ready` on its standard output."""

    def __init__(self, args, ready):
        self.p = subprocess.Popen([str(SIM), *args], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        end = time.monotonic() + 15
        while time.monotonic() < end:
            if select.select([self.p.stdout], [], [], end - time.monotonic())[0]:
                line = self.p.stdout.readline()
                if not line:
                    break
                if ready in line:
                    self.line = line.strip()
                    return
        self.p.kill()
        fail(f"drive-sim {' '.join(args)} did not start")

    def stop(self):
        self.p.terminate()
        try:
            self.p.wait(5)
        except subprocess.TimeoutExpired:
            self.p.kill()


def main():
    for tool, what in ((SIM, "drive-sim"), (TOP, "od-master")):
        if not tool.is_file():
            fail(f"{what} not found at {tool} (cargo build -p od-master-cli -p drive --bin drive-sim)")
    if shutil.which("tmux") is None:
        fail("tmux is not installed")
    tmux = ["tmux", "-L", f"shot-top-{uuid.uuid4().hex[:8]}"]
    procs = []
    try:
        hub = Proc(["hub", "--listen", "127.0.0.1:0", "--quiet"], "listening on ")
        procs.append(hub)
        bus = f"socketcand://{hub.line.split()[-1]}/can0"
        args = ["run", "--bus", bus]
        for device, node in (("drvi", 2), ("drcs", 3), ("akd", 4)):
            args += ["--device", device, "--node-id", str(node)]
        procs.append(Proc(args, "running on "))

        def cli(*args):
            out = subprocess.run([str(TOP), "--bus", bus, *args], capture_output=True, text=True, timeout=60)
            if out.returncode != 0:
                fail(f"od-master {' '.join(args)}: {out.stderr.strip()}")

        def keys(*k):
            subprocess.run(tmux + ["send-keys", "-t", "top", *k], check=True)

        def capture():
            return subprocess.run(tmux + ["capture-pane", "-e", "-p", "-t", "top"], capture_output=True, text=True).stdout

        def wait_for(text):
            end = time.monotonic() + 15
            while time.monotonic() < end:
                if text in re.sub(r"\x1b\[[0-9;:]*m", "", capture()):
                    return
                time.sleep(0.1)
            fail(f"`{text}` not on the screen:\n{capture()}")

        command = f"cd {ROOT} && exec {TOP} --bus {bus} top networks/example.toml"
        subprocess.run(
            tmux + ["new-session", "-d", "-s", "top", "-x", str(COLS), "-y", str(ROWS), "-e", "TERM=xterm-256color", command],
            check=True,
        )
        wait_for("x_axis")
        cli("boot", str(NETWORK))
        wait_for("alive")
        # The DRVI turning; the DRCS asked to move before homing: its EMCY.
        for obj in ("0x6083", "0x6084"):
            cli("write", "2", obj, "u32:50000")
        cli("axis", "2", "enable")
        cli("axis", "2", "velocity", "5000")
        cli("axis", "3", "enable")
        cli("write", "3", "0x6060", "i8:1")
        cli("write", "3", "0x6081", "u32:50")
        cli("write", "3", "0x607A", "i32:100")
        cli("write", "3", "0x6040", "u16:0x1F")
        wait_for("FF13h")
        time.sleep(2)
        cli("axis", "2", "velocity", "12000")
        time.sleep(2)
        cli("axis", "2", "velocity", "-6000")
        time.sleep(2)
        keys("Down")
        wait_for("node 3, ")
        time.sleep(0.3)
        docs = ROOT / "docs"
        size = render(parse(capture()), docs / "top.png")
        print(f"docs/top.png: {size} bytes")
        # The DRVI's position and velocity, and its statusword added.
        keys("Up")
        wait_for("node 2, ")
        keys("g")
        wait_for("Plot: 2 series")
        keys("Left", "Space")
        wait_for("Plot: 3 series")
        time.sleep(0.3)
        size = render(parse(capture()), docs / "top-plot.png")
        print(f"docs/top-plot.png: {size} bytes")
        keys("q")
    finally:
        subprocess.run(tmux + ["kill-server"], capture_output=True)
        for p in reversed(procs):
            p.stop()


if __name__ == "__main__":
    main()
