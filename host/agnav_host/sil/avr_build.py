"""Build the AVR SIL pieces on demand: the real ATmega2560 firmware ELF (PlatformIO, env
``megaatmega2560``, copied to build/sil/agnav_megaatmega2560.elf) and ``build/sil/libagnav_avr_sil.so`` (hil/simavr/avr_sil.c: the C API of
hil/sil/sil_api.h backed by libsimavr running that ELF). An installed package builds the library from the
sources it ships into the user cache (``<cache>/avr-<hash>``, agnav_host._paths); the ELF needs PlatformIO and
the firmware's project, so there it is the file named by ``$AGNAV_AVR_ELF`` (built in a checkout).

    python -m agnav_host.sil.avr_build [--force] [--print]

:func:`build_avr_library` rebuilds the library when avr_sil.c or sil_api.h is newer;
:func:`build_avr_elf` runs ``pio run -e megaatmega2560`` when a firmware source, header,
platformio.ini or the MAVLink dialect is newer than the copy (PlatformIO itself decides what to
recompile). Both need ``cc``, libsimavr-dev and libelf-dev (``make setup`` installs them).
"""

from __future__ import annotations

import os
import shlex
import shutil
import subprocess
from pathlib import Path

from .._paths import CHECKOUT_ROOT, SOURCE_ROOT, cache_dir, keyed_dir
from .build import SilBuildError, compiler

__all__ = ["AVR_LIB_PATH", "AVR_ELF_PATH", "PIO_ELF_PATH", "avr_compile_command", "build_avr_library", "build_avr_elf"]

REPO_ROOT = SOURCE_ROOT  # the PlatformIO project (a checkout) or the package's copy of the sources
AVR_SRC = SOURCE_ROOT / "hil" / "simavr" / "avr_sil.c"
AVR_MODEL_SRC = SOURCE_ROOT / "hil" / "simavr" / "avr_board_model.c"  # simavr corrections, shared with avr_harness
SIL_DIR = SOURCE_ROOT / "hil" / "sil"
CFLAGS = ["-O2", "-std=gnu11", "-fPIC", "-shared", "-Wall", "-Wextra", "-Wl,-Bsymbolic"]
LIBS = ["-lsimavr", "-lelf"]
_LIB_INPUTS = [AVR_SRC, AVR_MODEL_SRC, AVR_MODEL_SRC.with_suffix(".h"), SIL_DIR / "sil_api.h", SIL_DIR / "sil_events.h",
               SIL_DIR / "sil_eeprom_map.h"]
AVR_LIB_PATH = (CHECKOUT_ROOT / "build" / "sil" if CHECKOUT_ROOT is not None
                else keyed_dir("avr", _LIB_INPUTS, [os.environ.get("CC", "cc"), *CFLAGS, *LIBS])) / "libagnav_avr_sil.so"
PIO_ELF_PATH = REPO_ROOT / ".pio" / "build" / "megaatmega2560" / "firmware.elf"
# A private copy: `pio test -e megaatmega2560` links its Unity test programs to PIO_ELF_PATH too,
# so that file is not always the firmware.
AVR_ELF_PATH = (REPO_ROOT / "build" / "sil" / "agnav_megaatmega2560.elf" if CHECKOUT_ROOT is not None
                else Path(os.environ.get("AGNAV_AVR_ELF") or cache_dir() / "agnav_megaatmega2560.elf"))


def avr_compile_command(out: Path = AVR_LIB_PATH) -> list[str]:
    cc = shlex.split(os.environ.get("CC", "cc"))
    return [*cc, *CFLAGS, f"-I{SIL_DIR}", str(AVR_SRC), str(AVR_MODEL_SRC), "-o", str(out), *LIBS]


def _newer(out: Path, inputs: list[Path]) -> bool:
    if not out.exists():
        return True
    t = out.stat().st_mtime
    return any(p.exists() and p.stat().st_mtime > t for p in inputs)


def build_avr_library(out: Path = AVR_LIB_PATH, force: bool = False) -> Path:
    """(Re)build the simavr-backed SIL library when missing or older than its sources."""
    if not force and not _newer(out, _LIB_INPUTS if CHECKOUT_ROOT is not None else []):
        return out
    compiler("the AVR SIL library")
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(out.name + f".tmp{os.getpid()}")
    cmd = avr_compile_command(tmp)
    r = subprocess.run(cmd, cwd=SOURCE_ROOT, capture_output=True, text=True)
    if r.returncode != 0:
        tmp.unlink(missing_ok=True)
        missing_dev = any(k in r.stderr for k in ("simavr", "-lelf", "libelf", "gelf.h"))
        hint = ("\n(simavr's and libelf's headers and libraries come from the Debian packages libsimavr-dev and "
                "libelf-dev: sudo apt-get install libsimavr-dev libelf-dev)") if missing_dev else ""
        raise SilBuildError(f"AVR SIL build failed ({shlex.join(cmd)}):\n{r.stderr}{hint}")
    os.replace(tmp, out)
    return out


def _firmware_inputs() -> list[Path]:
    fw = REPO_ROOT / "firmware"
    out = [p for d in (fw / "src", fw / "lib") for p in d.rglob("*") if p.suffix in (".c", ".h", ".S")]
    out += [REPO_ROOT / "platformio.ini", REPO_ROOT / "protocol" / "agnav.xml"]
    return out


def pio_elf_path() -> Path:
    """Where ``pio run -e megaatmega2560`` puts the ELF: PIO_ELF_PATH, or under $PLATFORMIO_BUILD_DIR."""
    bd = os.environ.get("PLATFORMIO_BUILD_DIR")
    return Path(bd) / "megaatmega2560" / "firmware.elf" if bd else PIO_ELF_PATH


def build_avr_elf(force: bool = False) -> Path:
    """The ATmega2560 firmware ELF (a copy in build/sil/), rebuilt with ``pio run`` when older than
    the firmware sources (PlatformIO recompiles only what changed, and relinks the firmware after
    ``pio test`` left a test program in its build directory). An installed package has no PlatformIO project:
    there the ELF is ``$AGNAV_AVR_ELF`` (or ``<cache>/agnav_megaatmega2560.elf``), and SilBuildError says so when
    it is missing."""
    if CHECKOUT_ROOT is None:
        if AVR_ELF_PATH.is_file():
            return AVR_ELF_PATH
        raise SilBuildError(f"the ATmega2560 firmware ELF {AVR_ELF_PATH} is missing: an installed agnav_host cannot "
                            "build it (it takes PlatformIO and the source checkout: pio run -e megaatmega2560); set "
                            "AGNAV_AVR_ELF to a built firmware.elf")
    if not force and not _newer(AVR_ELF_PATH, _firmware_inputs()):
        return AVR_ELF_PATH
    pio = REPO_ROOT / ".venv" / "bin" / "pio"
    cmd = [str(pio) if pio.exists() else "pio", "run", "-e", "megaatmega2560"]
    env = dict(os.environ)
    env.setdefault("PLATFORMIO_CORE_DIR", str(REPO_ROOT / ".pio-core"))
    r = subprocess.run(cmd, cwd=REPO_ROOT, capture_output=True, text=True, env=env)
    elf = pio_elf_path()
    if r.returncode != 0 or not elf.exists():
        raise SilBuildError(f"AVR firmware build failed ({shlex.join(cmd)}):\n{r.stdout[-4000:]}\n{r.stderr[-4000:]}")
    AVR_ELF_PATH.parent.mkdir(parents=True, exist_ok=True)
    tmp = AVR_ELF_PATH.with_name(AVR_ELF_PATH.name + f".tmp{os.getpid()}")
    shutil.copyfile(elf, tmp)
    os.replace(tmp, AVR_ELF_PATH)  # a fresh mtime: newer than the sources it was built from
    return AVR_ELF_PATH


if __name__ == "__main__":  # python -m agnav_host.sil.avr_build [--force] [--print]
    import sys

    if "--print" in sys.argv:
        print(shlex.join(avr_compile_command()))
    else:
        force = "--force" in sys.argv
        print(build_avr_elf(force=force))
        print(build_avr_library(force=force))
