"""Build the native SIL library (libagnav_sil.so) from the firmware sources on demand.

The library is the real firmware (firmware/src/main.c with -DAGNAV_NO_MAIN, every
firmware/lib/<module>/*.c, the simulated HAL) plus hil/sil/sil_api.c, compiled by the host C
compiler (``cc``, or ``$CC``). In a source checkout it is build/sil/libagnav_sil.so, rebuilt by
:func:`build_library` when a source, header or the MAVLink dialect is newer (the same command line
is what ``make sil`` runs); an installed package compiles the sources it ships once into the user
cache, ``<cache>/sil-<hash of sources, compiler and flags>/libagnav_sil.so`` (agnav_host._paths).
"""

from __future__ import annotations

import os
import shlex
import shutil
import subprocess
from pathlib import Path

from .._paths import CHECKOUT_ROOT, SOURCE_ROOT, keyed_dir
from ..protocol import BINDING_INPUTS, _pymavlink_version, bindings_dir, generate_bindings

__all__ = ["SOURCE_ROOT", "LIB_PATH", "sources", "compile_command", "build_library", "library_path",
           "compiler", "SilBuildError", "CompilerMissing"]

FIRMWARE = SOURCE_ROOT / "firmware"
SIL_DIR = SOURCE_ROOT / "hil" / "sil"
MAVLINK_C = bindings_dir() / "c"
CFLAGS = ["-O2", "-std=gnu11", "-fPIC", "-shared", "-Wall", "-Wextra", "-Wno-address-of-packed-member",
          "-DAGNAV_NO_MAIN", "-DAGNAV_TARGET_NATIVE", "-Wl,-Bsymbolic"]


class SilBuildError(RuntimeError):
    """The SIL library could not be built; the message has the compiler's output."""


class CompilerMissing(SilBuildError):
    """The C compiler a first-use build needs is not installed; the message names the Debian package."""


def compiler(what: str) -> list[str]:
    """The C compiler's command (``$CC`` or ``cc``); CompilerMissing when it is not installed."""
    cc = shlex.split(os.environ.get("CC", "cc")) or ["cc"]
    if shutil.which(cc[0]) is None:
        raise CompilerMissing(f"building {what} needs a C compiler, and {cc[0]!r} is not installed: install the "
                              "Debian package gcc (sudo apt-get install gcc), or set CC to a C compiler")
    return cc


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
    out.append(SOURCE_ROOT / "protocol" / "agnav.xml")
    return out


def library_path() -> Path:
    """Where the library is (or is built): build/sil in a checkout, the keyed cache folder when installed."""
    if CHECKOUT_ROOT is not None:
        return CHECKOUT_ROOT / "build" / "sil" / "libagnav_sil.so"
    key = [os.environ.get("CC", "cc"), *CFLAGS, f"pymavlink {_pymavlink_version()}"]
    return keyed_dir("sil", [*_inputs(), *BINDING_INPUTS], key) / "libagnav_sil.so"


LIB_PATH = library_path()


def compile_command(out: Path | None = None) -> list[str]:
    cc = shlex.split(os.environ.get("CC", "cc"))
    inc = [f"-I{d}" for d in _module_dirs()] + [f"-I{bindings_dir() / 'c'}", f"-I{SIL_DIR}"]
    return [*cc, *CFLAGS, *inc, *(str(s) for s in sources()), "-o", str(out or library_path())]


def _stale(out: Path) -> bool:
    if not out.exists():
        return True
    if CHECKOUT_ROOT is None:  # a keyed cache folder: its name changes with any input
        return False
    t = out.stat().st_mtime
    return any(p.exists() and p.stat().st_mtime > t for p in _inputs())


def build_library(out: Path | None = None, force: bool = False) -> Path:
    """(Re)build the library when missing or older than its inputs; return its path."""
    out = out or library_path()
    if CHECKOUT_ROOT is not None:
        generate_bindings("c")  # no-op when up to date
    if not force and not _stale(out):
        return out
    compiler("the SIL library (the firmware for the PC)")
    if CHECKOUT_ROOT is None:
        generate_bindings("c")  # once per keyed folder
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + f".tmp{os.getpid()}")
    cmd = compile_command(tmp)
    r = subprocess.run(cmd, cwd=SOURCE_ROOT, capture_output=True, text=True)
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
        try:
            print(build_library(force="--force" in sys.argv))
        except SilBuildError as e:
            print(f"agnav_host.sil.build: {e}", file=sys.stderr)
            sys.exit(1)
