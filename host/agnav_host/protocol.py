"""The AgNav MAVLink dialect for Python, generated from protocol/agnav.xml on first use.

The bindings are never committed: `dialect()` runs pymavlink's mavgen (through protocol/generate.py)
and imports the result. In a source checkout they go to build/mavlink (regenerated when the XML is
newer than the generated module); an installed package generates them once per version of its
sources and of pymavlink into the user cache (`<cache>/mavlink-<hash>`, see agnav_host._paths).
AGNAV_MAVLINK_BUILD_DIR overrides the folder in both cases.
"""
from __future__ import annotations

import importlib.util
import os
import sys
from functools import lru_cache
from pathlib import Path
from types import ModuleType
from typing import Any

from ._paths import CHECKOUT_ROOT, SOURCE_ROOT, keyed_dir, publish_dir

PROTOCOL_DIR = SOURCE_ROOT / "protocol"
# what the generated bindings depend on besides pymavlink (common.xml and mavgen come from it)
BINDING_INPUTS = (PROTOCOL_DIR / "agnav.xml", PROTOCOL_DIR / "generate.py",
                  SOURCE_ROOT / "firmware" / "lib" / "signing" / "agnav_sha256.h")


def _generator() -> ModuleType:
    path = PROTOCOL_DIR / "generate.py"
    if not path.is_file():
        raise RuntimeError(f"protocol/generate.py not found at {path}: the agnav_host installation is incomplete "
                           "(reinstall it, or run from a source checkout)")
    spec = importlib.util.spec_from_file_location("agnav_protocol_generate", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _pymavlink_version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("pymavlink")
    except PackageNotFoundError:
        return "unknown"


def bindings_dir() -> Path:
    """The folder of the generated bindings (c/, python/, xml/)."""
    env = os.environ.get("AGNAV_MAVLINK_BUILD_DIR")
    if env:
        return Path(env)
    if CHECKOUT_ROOT is not None:
        return CHECKOUT_ROOT / "build" / "mavlink"
    return keyed_dir("mavlink", BINDING_INPUTS, [f"pymavlink {_pymavlink_version()}"])


def generate_bindings(lang: str) -> dict[str, Path]:
    """Generate the ``lang`` bindings ("c", "python" or "all") where missing or stale; return their paths."""
    out = bindings_dir()
    if CHECKOUT_ROOT is not None or os.environ.get("AGNAV_MAVLINK_BUILD_DIR"):
        generated: dict[str, Path] = _generator().generate(lang, out)
        return generated
    # an installed package: both languages at once into a keyed folder that is complete or absent
    publish_dir(out, lambda tmp: _generator().generate("all", tmp))
    paths = {"c": out / "c" / "agnav" / "mavlink.h", "c_wrapper": out / "c" / "agnav_mavlink.h",
             "python": out / "python" / "agnav.py"}
    return paths if lang == "all" else {k: v for k, v in paths.items() if k.startswith(lang)}


@lru_cache(maxsize=1)
def dialect() -> ModuleType:
    """Return the generated pymavlink module of the AgNav dialect (common.xml included)."""
    module_path = generate_bindings("python")["python"]
    spec = importlib.util.spec_from_file_location("agnav_mavlink_dialect", module_path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules["agnav_mavlink_dialect"] = module
    spec.loader.exec_module(module)
    return module


def new_codec(sysid: int = 255, compid: int = 190) -> Any:
    """A fresh encoder/decoder (MAVLink 2) with the given source ids (255/190 = ground station)."""
    mav = dialect().MAVLink(None, srcSystem=sysid, srcComponent=compid)
    mav.robust_parsing = True
    return mav
