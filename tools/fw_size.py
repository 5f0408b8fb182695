#!/usr/bin/env python3
"""Flash and static RAM of the AVR firmware, per module and in total.

    .venv/bin/python tools/fw_size.py [--env megaatmega2560] [--no-build]

Builds the env (unless --no-build) into $PLATFORMIO_BUILD_DIR (default .pio/build;
several engineers build in one checkout). Totals come from that (LTO) ELF. The split
per module comes from a second build of the same env without -flto (into
<build dir>-size-nolto/ next to it, since LTO merges every module into one object): its linker
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


def build_dirs() -> tuple[Path, Path]:
    """The LTO build dir (PLATFORMIO_BUILD_DIR or .pio/build) and the non-LTO one beside it."""
    build = Path(os.environ.get("PLATFORMIO_BUILD_DIR", str(REPO / ".pio" / "build")))
    return build, build.parent / (build.name + "-size-nolto")


def build(env_name: str) -> None:
    build_dir, nolto_dir = build_dirs()
    env = dict(os.environ, PLATFORMIO_CORE_DIR=os.environ.get("PLATFORMIO_CORE_DIR", str(REPO / ".pio-core")),
               PLATFORMIO_DISABLE_UPGRADE_CHECK="true", PLATFORMIO_BUILD_DIR=str(build_dir))
    pio = str(REPO / ".venv" / "bin" / "pio")
    subprocess.run([pio, "run", "-s", "-e", env_name], cwd=REPO, env=env, check=True, stdout=subprocess.DEVNULL)
    subprocess.run([pio, "run", "-s", "-e", env_name], cwd=REPO, check=True, stdout=subprocess.DEVNULL,
                   env=dict(env, PLATFORMIO_BUILD_UNFLAGS="-flto", PLATFORMIO_BUILD_DIR=str(nolto_dir)))


def totals(elf: Path) -> tuple[int, int]:
    """Flash (.text + .data) and static RAM (.data + .bss + .noinit) of an ELF, bytes."""
    sizes = subprocess.run(["avr-size", "-A", "-d", str(elf)], capture_output=True, text=True, check=True).stdout
    sec = {m.group(1): int(m.group(2)) for m in re.finditer(r"^(\.\w+)\s+(\d+)", sizes, re.M)}
    return sec.get(".text", 0) + sec.get(".data", 0), sec.get(".data", 0) + sec.get(".bss", 0) + sec.get(".noinit", 0)


def table(env_name: str) -> str | None:
    """The per-module table and the totals of an already built env; None if not built."""
    build_dir, nolto_dir = build_dirs()
    map_path = nolto_dir / env_name / "firmware.map"
    if not map_path.is_file():
        print(f"fw_size: {map_path} not found; build first", file=sys.stderr)
        return None
    per = parse_map(map_path.read_text(encoding="utf-8", errors="replace"))
    flash_total, ram_total = totals(build_dir / env_name / "firmware.elf")
    rows = [f"{'module':<14}{'flash B':>10}{'RAM B':>8}"]
    for mod, v in sorted(per.items(), key=lambda kv: -kv[1]["flash"]):
        rows.append(f"{mod:<14}{v['flash']:>10}{v['ram']:>8}")
    rows.append(f"{'TOTAL (LTO ELF)':<14}{flash_total:>10}{ram_total:>8}")
    rows.append(f"flash {flash_total} B of target {FLASH_LIMIT} B ({'OK' if flash_total <= FLASH_LIMIT else 'OVER'}); "
                f"static RAM {ram_total} B of target {RAM_LIMIT} B ({'OK' if ram_total <= RAM_LIMIT else 'OVER'})")
    return "\n".join(rows)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--env", default="megaatmega2560")
    ap.add_argument("--no-build", action="store_true")
    args = ap.parse_args(argv)
    if not args.no_build:
        build(args.env)
    text = table(args.env)
    if text is None:
        return 2
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
