#!/usr/bin/env python3
"""Generate the AgNav MAVLink bindings from protocol/agnav.xml with pymavlink's mavgen.

    python protocol/generate.py [--lang c|python|all] [--out build/mavlink]

Output (never committed):
    <out>/c/agnav/mavlink.h ...   C headers, wire protocol 2.0
    <out>/python/agnav.py         Python module
Generation is skipped when the outputs are newer than agnav.xml and this script.
common.xml and the files it includes are taken from the installed pymavlink.
"""
from __future__ import annotations

import argparse
import os
import re
import shutil
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
DIALECT_XML = HERE / "agnav.xml"
DEFAULT_OUT = HERE.parent / "build" / "mavlink"


def _pymavlink_xml_dir() -> Path:
    import pymavlink

    return Path(pymavlink.__file__).resolve().parent / "dialects" / "v20"


def _includes(xml_path: Path) -> list[str]:
    return re.findall(r"<include>\s*([^<\s]+)\s*</include>", xml_path.read_text(encoding="utf-8"))


def stage_xml(out: Path) -> Path:
    """Copy agnav.xml and every XML it includes (recursively) into out/xml."""
    xml_dir = out / "xml"
    xml_dir.mkdir(parents=True, exist_ok=True)
    src_dir = _pymavlink_xml_dir()
    shutil.copyfile(DIALECT_XML, xml_dir / DIALECT_XML.name)
    pending = _includes(DIALECT_XML)
    seen: set[str] = set()
    while pending:
        name = pending.pop()
        if name in seen:
            continue
        seen.add(name)
        src = src_dir / name
        if not src.is_file():
            raise SystemExit(f"generate: {name} (included by the dialect) not found in {src_dir}")
        shutil.copyfile(src, xml_dir / name)
        pending.extend(_includes(src))
    return xml_dir / DIALECT_XML.name


def _stale(target: Path) -> bool:
    if not target.exists():
        return True
    newest_input = max(DIALECT_XML.stat().st_mtime, Path(__file__).stat().st_mtime)
    return target.stat().st_mtime < newest_input


def generate(lang: str = "all", out: Path = DEFAULT_OUT, quiet: bool = True) -> dict[str, Path]:
    from pymavlink.generator import mavgen

    out = Path(out)
    results: dict[str, Path] = {}
    wanted = ["c", "python"] if lang == "all" else [lang]
    for one in wanted:
        marker = out / "c" / "agnav" / "mavlink.h" if one == "c" else out / "python" / "agnav.py"
        results[one] = marker
        if not _stale(marker):
            continue
        xml = stage_xml(out)
        opts = mavgen.Opts(
            output=str(out / "c") if one == "c" else str(marker),
            wire_protocol="2.0",
            language="C" if one == "c" else "Python3",
            validate=True,
            strict_units=False,
        )
        if one == "python":
            marker.parent.mkdir(parents=True, exist_ok=True)
        if quiet:
            devnull = open(os.devnull, "w")
            saved, sys.stdout = sys.stdout, devnull
        try:
            ok = mavgen.mavgen(opts, [str(xml)])
        finally:
            if quiet:
                sys.stdout = saved
                devnull.close()
        if ok is False or not marker.exists():
            raise SystemExit(f"generate: mavgen failed for {one}")
        marker.touch()
    return results


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--lang", choices=["c", "python", "all"], default="all")
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT)
    args = ap.parse_args(argv)
    for lang, path in generate(args.lang, args.out).items():
        print(f"{lang}: {path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
