"""Build hook of the agnav-host wheel (the metadata is in pyproject.toml).

An installed agnav_host builds the MAVLink bindings and the SIL libraries on first use from the
repository's sources. The build step copies those sources into the wheel as agnav_host/_data, in
the repository's own layout (protocol/, firmware/, hil/), so the repository stays their only copy.
An editable install reads them in place and gets no copy.
"""

from __future__ import annotations

import shutil
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

ROOT = Path(__file__).resolve().parent
# (folder relative to the repository, file patterns): what the first-use builds read
PACKAGE_SOURCES = [
    ("protocol", ["agnav.xml", "generate.py"]),
    ("firmware/src", ["*.c", "*.h"]),
    ("firmware/lib", ["**/*.c", "**/*.h", "**/*.S", "**/library.json"]),
    ("hil/sil", ["*.c", "*.h"]),
    ("hil/simavr", ["avr_sil.c", "avr_board_model.c", "avr_board_model.h"]),
]


def source_files() -> list[Path]:
    files: set[Path] = set()
    for folder, patterns in PACKAGE_SOURCES:
        for pattern in patterns:
            files.update(p for p in (ROOT / folder).glob(pattern) if p.is_file())
    return sorted(files)


class BuildPyWithSources(build_py):
    """build_py, then the firmware, SIL and dialect sources into agnav_host/_data (not in editable mode)."""

    def run(self) -> None:
        package = Path(self.build_lib) / "agnav_host"
        if not getattr(self, "editable_mode", False) and Path(self.build_lib).resolve().is_relative_to(ROOT / "build"):
            shutil.rmtree(self.build_lib, ignore_errors=True)  # nothing left over from an earlier build
        super().run()
        if getattr(self, "editable_mode", False):
            return
        files = source_files()
        if not any(p.name == "agnav.xml" for p in files):
            raise SystemExit(f"setup.py: protocol/agnav.xml not found under {ROOT}: build from the repository "
                             "or its sdist")
        data = package / "_data"
        for src in files:
            dst = data / src.relative_to(ROOT)
            dst.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dst)


setup(cmdclass={"build_py": BuildPyWithSources},
      options={"build": {"build_base": "build/python"}})
