"""The SIL's world-side C kernels (world_kernels.c -> libagnav_world.so: build/sil in a source checkout, the
keyed cache folder ``<cache>/world-<hash>`` in an installed package), built on demand with the host C compiler
(``cc`` or ``$CC``) like the SIL library itself. :func:`kernels` returns None when no compiler is available;
callers then use their numpy form (same results)."""

from __future__ import annotations

import ctypes as C
import os
import shlex
import subprocess
from pathlib import Path

from .._paths import CHECKOUT_ROOT, keyed_dir
from .build import compiler

__all__ = ["KERNELS_SRC", "KERNELS_LIB", "kernels"]

KERNELS_SRC = Path(__file__).with_name("world_kernels.c")
# no fast-math and no FMA contraction: the kernels must round exactly as numpy's element-wise ops
CFLAGS = ["-O2", "-std=gnu11", "-fPIC", "-shared", "-Wall", "-Wextra", "-ffp-contract=off", "-fno-fast-math"]
KERNELS_LIB = (CHECKOUT_ROOT / "build" / "sil" if CHECKOUT_ROOT is not None
               else keyed_dir("world", [KERNELS_SRC], [os.environ.get("CC", "cc"), *CFLAGS])) / "libagnav_world.so"

_lib: C.CDLL | None = None
_tried = False


def _build() -> Path:
    out = KERNELS_LIB
    if out.exists() and (CHECKOUT_ROOT is None or out.stat().st_mtime >= KERNELS_SRC.stat().st_mtime):
        return out
    cc = compiler("the world kernels")
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + f".tmp{os.getpid()}")
    cmd = [*cc, *CFLAGS, str(KERNELS_SRC), "-o", str(tmp), "-lm"]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        tmp.unlink(missing_ok=True)
        raise RuntimeError(f"building {out.name} failed ({shlex.join(cmd)}):\n{r.stderr}")
    os.replace(tmp, out)
    return out


def kernels() -> C.CDLL | None:
    """The loaded kernel library (built when missing or older than its source), or None."""
    global _lib, _tried
    if _tried:
        return _lib
    _tried = True
    if os.environ.get("AGNAV_SIL_NO_KERNELS"):
        return None
    try:
        lib = C.CDLL(str(_build()))
    except (OSError, RuntimeError, FileNotFoundError):
        return None
    d, i = C.c_double, C.c_int
    lib.agnav_sonar_cast.restype = None
    lib.agnav_sonar_cast.argtypes = [i, i, d, d, d, C.c_void_p, C.c_void_p, i, C.c_void_p, i, C.c_void_p, d, C.c_void_p]
    lib.agnav_encoder_edges.restype = C.c_long
    lib.agnav_encoder_edges.argtypes = [C.c_void_p, i, C.c_void_p, C.c_void_p, C.c_void_p, C.c_void_p, C.c_uint64,
                                        C.c_uint64, C.c_void_p, C.c_void_p, C.c_uint32]
    _lib = lib
    return lib
