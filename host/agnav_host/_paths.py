"""Where agnav_host finds the sources it builds on first use, and where it puts what it builds.

Two layouts:

* a source checkout (``pip install -e .``, ``make setup``): the package sits in ``host/agnav_host`` of the
  repository; the sources are the repository's own (``protocol/``, ``firmware/``, ``hil/``) and the outputs go
  to ``build/`` (``build/mavlink``, ``build/sil``), rebuilt when a source is newer;
* an installed wheel: the same sources ship inside the package as ``agnav_host/_data`` (the repository's
  layout, copied there by setup.py's build step) and the outputs go to a user cache directory,
  ``$AGNAV_CACHE_DIR``, else ``$XDG_CACHE_HOME/agnav``, else ``~/.cache/agnav``, one folder per output
  named after a hash of its inputs (:func:`keyed_dir`): a changed source, compiler or flag builds a new one.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import tempfile
from collections.abc import Callable, Iterable
from pathlib import Path

__all__ = ["PACKAGE_DIR", "CHECKOUT_ROOT", "SOURCE_ROOT", "cache_dir", "inputs_digest", "keyed_dir", "publish_dir"]

PACKAGE_DIR = Path(__file__).resolve().parent


def _checkout_root() -> Path | None:
    root = PACKAGE_DIR.parents[1]
    if PACKAGE_DIR.parent.name == "host" and (root / "protocol" / "agnav.xml").is_file() \
            and (root / "firmware" / "src" / "main.c").is_file():
        return root
    return None


CHECKOUT_ROOT: Path | None = _checkout_root()
"""The repository root when running from a source checkout, else None."""
SOURCE_ROOT: Path = CHECKOUT_ROOT if CHECKOUT_ROOT is not None else PACKAGE_DIR / "_data"
"""The root of the repository layout the builds read: the checkout itself, or the package's copy."""


def cache_dir() -> Path:
    """The user cache directory of an installed package (not created here)."""
    env = os.environ.get("AGNAV_CACHE_DIR")
    if env:
        return Path(env).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = Path(xdg).expanduser() if xdg and Path(xdg).is_absolute() else Path.home() / ".cache"
    return base / "agnav"


def inputs_digest(files: Iterable[Path], extra: Iterable[str] = ()) -> str:
    """A short hash of the files' names (relative to the sources or the package) and contents, and of ``extra``."""
    h = hashlib.sha256()
    for p in sorted({Path(f) for f in files}):
        name = str(p)
        for root in (SOURCE_ROOT, PACKAGE_DIR):  # so the key does not depend on where the package is installed
            if p.is_relative_to(root):
                name = p.relative_to(root).as_posix()
                break
        h.update(name.encode() + b"\0")
        h.update(p.read_bytes() if p.is_file() else b"<missing>")
        h.update(b"\0")
    for s in extra:
        h.update(s.encode() + b"\0")
    return h.hexdigest()[:16]


def keyed_dir(kind: str, files: Iterable[Path], extra: Iterable[str] = ()) -> Path:
    """``<cache>/<kind>-<hash of the inputs>``: where an installed package keeps one built output."""
    return cache_dir() / f"{kind}-{inputs_digest(files, extra)}"


def publish_dir(final: Path, build: Callable[[Path], object]) -> Path:
    """``final`` complete or not at all: when missing, ``build(tmp)`` fills a fresh sibling folder that is then
    renamed to ``final`` (a concurrent process that finished first wins, and this one's copy is dropped)."""
    if final.is_dir():
        return final
    final.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{final.name}.", dir=final.parent))
    try:
        build(tmp)
        try:
            os.rename(tmp, final)
        except OSError:
            if not final.is_dir():
                raise
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
    return final
