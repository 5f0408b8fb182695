#!/usr/bin/env python3
"""Flash and static RAM of the AVR firmware, per module and in total.

    .venv/bin/python tools/fw_size.py [--env megaatmega2560] [--no-build]

Builds the env (unless --no-build). Totals come from that (LTO) ELF. The split
per module comes from a second build of the same env without -flto (into
build/size-nolto/, since LTO merges every module into one object): its linker
map (after --gc-sections, so only what is really linked counts) is summed by
the module each input section came from (firmware/lib/<module>, src,
libc/libgcc). Flash = .text + .progmem + .data (initial values); RAM = .data +
.bss + .noinit. Module figures are of the non-LTO build and add up to a little
more than the LTO total.
"""
import argparse
import os
import re
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
FLASH_LIMIT = 48 * 1024
RAM_LIMIT = 3 * 1024


def module_of(path: str) -> str:
    m = re.search(r"/lib[0-9a-f]+/([^/]+)/", path)
    if m:
        return m.group(1)
    if "/src/" in path:
        return "main"
    if "libgcc" in path or "libc" in path or "libm" in path or "crt" in path:
        return "libc/libgcc"
    return "other"


def parse_map(text: str) -> dict[str, dict[str, int]]:
    out: dict[str, dict[str, int]] = defaultdict(lambda: {"flash": 0, "ram": 0})
    start = text.find("Linker script and memory map")
    lines = text[start:].splitlines()
    pending = None
    for line in lines:
        m = re.match(r"^ (\.[\w.$]+)\s*$", line)
        if m:
            pending = m.group(1)
            continue
        m = re.match(r"^ (\.[\w.$]+)?\s+0x([0-9a-f]+)\s+0x([0-9a-f]+)\s+(\S+\.o\S*)\s*$", line)
        if not m:
            pending = None if not line.startswith("  ") else pending
            continue
        section = m.group(1) or pending
        pending = None
        size = int(m.group(3), 16)
        if section is None or size == 0:
            continue
        mod = module_of(m.group(4))
        if section.startswith((".text", ".progmem", ".vectors", ".init", ".fini", ".trampolines")):
            out[mod]["flash"] += size
        elif section.startswith(".data") or section.startswith(".rodata"):
            out[mod]["flash"] += size
            out[mod]["ram"] += size
        elif section.startswith((".bss", ".noinit", "COMMON")):
            out[mod]["ram"] += size
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--env", default="megaatmega2560")
    ap.add_argument("--no-build", action="store_true")
    args = ap.parse_args(argv)
    build = REPO / ".pio" / "build" / args.env
    nolto_root = REPO / "build" / "size-nolto"
    if not args.no_build:
        env = dict(os.environ, PLATFORMIO_CORE_DIR=str(REPO / ".pio-core"),
                   PLATFORMIO_DISABLE_UPGRADE_CHECK="true")
        pio = str(REPO / ".venv" / "bin" / "pio")
        subprocess.run([pio, "run", "-s", "-e", args.env], cwd=REPO, env=env, check=True)
        subprocess.run([pio, "run", "-s", "-e", args.env], cwd=REPO, check=True,
                       env=dict(env, PLATFORMIO_BUILD_UNFLAGS="-flto", PLATFORMIO_BUILD_DIR=str(nolto_root)))
    map_path = nolto_root / args.env / "firmware.map"
    if not map_path.is_file():
        print(f"fw_size: {map_path} not found; build first", file=sys.stderr)
        return 2
    per = parse_map(map_path.read_text(encoding="utf-8", errors="replace"))
    elf = build / "firmware.elf"
    sizes = subprocess.run(["avr-size", "-A", "-d", str(elf)], capture_output=True, text=True, check=True).stdout
    sec = {m.group(1): int(m.group(2)) for m in re.finditer(r"^(\.\w+)\s+(\d+)", sizes, re.M)}
    flash_total = sec.get(".text", 0) + sec.get(".data", 0)
    ram_total = sec.get(".data", 0) + sec.get(".bss", 0) + sec.get(".noinit", 0)
    print(f"{'module':<14}{'flash B':>10}{'RAM B':>8}")
    for mod, v in sorted(per.items(), key=lambda kv: -kv[1]["flash"]):
        print(f"{mod:<14}{v['flash']:>10}{v['ram']:>8}")
    print(f"{'TOTAL (LTO ELF)':<14}{flash_total:>10}{ram_total:>8}")
    print(f"flash {flash_total} B of target {FLASH_LIMIT} B ({'OK' if flash_total <= FLASH_LIMIT else 'OVER'}); "
          f"static RAM {ram_total} B of target {RAM_LIMIT} B ({'OK' if ram_total <= RAM_LIMIT else 'OVER'})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
