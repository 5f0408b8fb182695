"""Files written whole or not at all.

:func:`write_atomic` writes to a temporary file beside the target, flushes it to the disk and renames it over
the target, so a full disk or a crash leaves the old file (or none), never a cut or empty one; the temporary
file is removed on failure and the OSError goes to the caller, who reports it. :func:`savefig_atomic` does the
same for a matplotlib figure (rendered to memory first)."""

from __future__ import annotations

import io
import os
import tempfile
from pathlib import Path
from typing import Any

__all__ = ["write_atomic", "savefig_atomic"]


def write_atomic(path: str | Path, data: bytes | str) -> Path:
    """Write ``data`` (str: UTF-8) to ``path`` whole, or raise OSError and leave ``path`` as it was."""
    p = Path(path)
    raw = data.encode("utf-8") if isinstance(data, str) else bytes(data)
    fd, tmp = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".part", dir=p.parent)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(raw)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, p)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
    return p


def savefig_atomic(fig: Any, path: str | Path, **kw: Any) -> Path:
    """``fig.savefig(path, **kw)`` through :func:`write_atomic` (the format from the suffix)."""
    p = Path(path)
    buf = io.BytesIO()
    kw.setdefault("format", p.suffix.lstrip(".") or "png")
    fig.savefig(buf, **kw)
    return write_atomic(p, buf.getvalue())
