"""The AgNav MAVLink dialect for Python, generated from protocol/agnav.xml on first use.

The bindings are never committed: `dialect()` runs pymavlink's mavgen (through
protocol/generate.py) into build/mavlink/python when the XML is newer than the
generated module, then imports it.
"""
from __future__ import annotations

import importlib.util
import os
import sys
from functools import lru_cache
from pathlib import Path
from types import ModuleType

REPO_ROOT = Path(__file__).resolve().parents[2]
PROTOCOL_DIR = REPO_ROOT / "protocol"
DEFAULT_BUILD_DIR = REPO_ROOT / "build" / "mavlink"


def _generator() -> ModuleType:
    path = PROTOCOL_DIR / "generate.py"
    if not path.is_file():
        raise RuntimeError(
            f"protocol/generate.py not found at {path}: agnav_host must run from a source checkout"
        )
    spec = importlib.util.spec_from_file_location("agnav_protocol_generate", path)
    module = importlib.util.module_from_spec(spec)
    assert spec.loader is not None
    spec.loader.exec_module(module)
    return module


@lru_cache(maxsize=1)
def dialect() -> ModuleType:
    """Return the generated pymavlink module of the AgNav dialect (common.xml included)."""
    out = Path(os.environ.get("AGNAV_MAVLINK_BUILD_DIR", DEFAULT_BUILD_DIR))
    module_path = _generator().generate("python", out)["python"]
    spec = importlib.util.spec_from_file_location("agnav_mavlink_dialect", module_path)
    module = importlib.util.module_from_spec(spec)
    sys.modules["agnav_mavlink_dialect"] = module
    assert spec.loader is not None
    spec.loader.exec_module(module)
    return module


def new_codec(sysid: int = 255, compid: int = 190):
    """A fresh encoder/decoder (MAVLink 2) with the given source ids (255/190 = ground station)."""
    mav = dialect().MAVLink(None, srcSystem=sysid, srcComponent=compid)
    mav.robust_parsing = True
    return mav
