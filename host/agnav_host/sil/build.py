"""Build the native SIL library (build/sil/libagnav_sil.so) from the firmware sources on demand.

The library is the real firmware (firmware/src/main.c with -DAGNAV_NO_MAIN, every
firmware/lib/<module>/*.c, the simulated HAL) plus hil/sil/sil_api.c, compiled by the host C
compiler (``cc``, or ``$CC``). :func:`build_library` rebuilds only when a source, header or the
MAVLink dialect is newer than the library. The same command line is what ``make sil`` runs.
"""

from __future__ import annotations

import os
import shlex
import subprocess
from pathlib import Path

__all__ = ["REPO_ROOT", "LIB_PATH", "sources", "compile_command", "build_library", "SilBuildError"]

REPO_ROOT = Path(__file__).resolve().parents[3]
FIRMWARE = REPO_ROOT / "firmware"
SIL_DIR = REPO_ROOT / "hil" / "sil"
MAVLINK_C = REPO_ROOT / "build" / "mavlink" / "c"
LIB_PATH = REPO_ROOT / "build" / "sil" / "libagnav_sil.so"
CFLAGS = ["-O2", "-std=gnu11", "-fPIC", "-shared", "-Wall", "-Wextra", "-Wno-address-of-packed-member",
          "-DAGNAV_NO_MAIN", "-DAGNAV_TARGET_NATIVE", "-Wl,-Bsymbolic"]


class SilBuildError(RuntimeError):
    """The SIL library could not be built; the message has the compiler's output."""


def _module_dirs() -> list[Path]:
    return sorted(p for p in (FIRMWARE / "lib").iterdir() if p.is_dir())


def sources() -> list[Path]:
    """C files linked into the library, in a fixed order."""
    files = [FIRMWARE / "src" / "main.c"]
    for d in _module_dirs():
        files += sorted(d.glob("*.c"))
    files += [FIRMWARE / "lib" / "hal" / "sim" / "hal_sim.c", SIL_DIR / "sil_api.c"]
    return files


def _inputs() -> list[Path]:
    out = list(sources())
    for d in _module_dirs():
        out += list(d.rglob("*.h"))
    out += list(SIL_DIR.glob("*.h"))
    out.append(REPO_ROOT / "protocol" / "agnav.xml")
    return out


def compile_command(out: Path = LIB_PATH) -> list[str]:
    cc = shlex.split(os.environ.get("CC", "cc"))
    inc = [f"-I{d}" for d in _module_dirs()] + [f"-I{MAVLINK_C}", f"-I{SIL_DIR}"]
    return [*cc, *CFLAGS, *inc, *(str(s) for s in sources()), "-o", str(out)]


def _stale(out: Path) -> bool:
    if not out.exists():
        return True
    t = out.stat().st_mtime
    return any(p.exists() and p.stat().st_mtime > t for p in _inputs())


def build_library(out: Path = LIB_PATH, force: bool = False) -> Path:
    """(Re)build the library when missing or older than its inputs; return its path."""
    from ..protocol import _generator

    _generator().generate("c", REPO_ROOT / "build" / "mavlink")  # no-op when up to date
    if not force and not _stale(out):
        return out
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + f".tmp{os.getpid()}")
    cmd = compile_command(tmp)
    r = subprocess.run(cmd, cwd=REPO_ROOT, capture_output=True, text=True)
    if r.returncode != 0:
        tmp.unlink(missing_ok=True)
        raise SilBuildError(f"SIL build failed ({shlex.join(cmd)}):\n{r.stderr}")
    os.replace(tmp, out)  # atomic: a concurrent loader never sees a half-written file
    return out


if __name__ == "__main__":  # python -m agnav_host.sil.build [--print]
    import sys

    if "--print" in sys.argv:
        print(shlex.join(compile_command()))
    else:
        print(build_library(force="--force" in sys.argv))
