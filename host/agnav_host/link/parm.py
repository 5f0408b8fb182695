"""Parameter files in the .parm form MAVProxy and Mission Planner read and write.

One parameter a line: ``NAME VALUE`` (MAVProxy's ``param save``) or ``NAME,VALUE`` (Mission Planner's .param);
``#`` starts a comment, blank lines are skipped. :func:`write_parm` writes MAVProxy's form, names sorted, with a
comment header; :func:`read_parm` reads both and raises :class:`ParmError` naming the line for anything else."""

from __future__ import annotations

import math
import re
from pathlib import Path

from ..atomic import write_atomic

__all__ = ["ParmError", "read_parm", "write_parm", "format_parm"]

_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]{0,15}$")  # a MAVLink param_id: up to 16 characters
MAX_LINES = 10_000


class ParmError(ValueError):
    def __init__(self, path: str | Path, line: int | None, what: str) -> None:
        super().__init__(f"{path}:{line}: {what}" if line is not None else f"{path}: {what}")
        self.line = line


def format_parm(params: dict[str, float], header: str = "") -> str:
    """The text of a .parm file: integers written without a fraction (the firmware's are all integers)."""
    out = [f"# {h}" for h in header.splitlines()] if header else []
    for name in sorted(params):
        v = float(params[name])
        out.append(f"{name} {int(v)}" if v.is_integer() else f"{name} {v:.9g}")
    return "\n".join(out) + "\n"


def write_parm(params: dict[str, float], path: str | Path, header: str = "") -> Path:
    """Write ``params`` to ``path`` atomically (a temporary file beside it, then renamed): a full disk leaves the
    old file, or none, never half of one. OSError as the file system raises it."""
    return write_atomic(path, format_parm(params, header))


def read_parm(path: str | Path) -> dict[str, float]:
    """Name -> value from a .parm / .param file. ParmError for an unreadable file, a line that is not
    ``NAME VALUE`` or ``NAME,VALUE``, a name a MAVLink parameter cannot have, a value that is not a finite
    number, a name given twice, or more than 10,000 lines."""
    p = Path(path)
    try:
        raw = p.read_bytes()
    except OSError as e:
        raise ParmError(p, None, f"cannot read: {e.strerror or e}") from None
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as e:
        raise ParmError(p, raw[:e.start].count(b"\n") + 1, "not a text file (bytes that are not UTF-8)") from None
    out: dict[str, float] = {}
    for i, line in enumerate(text.splitlines(), 1):
        if i > MAX_LINES:
            raise ParmError(p, i, f"more than {MAX_LINES} lines: not a parameter file")
        body = line.split("#", 1)[0].strip()
        if not body:
            continue
        parts = [x for x in re.split(r"[,\s]+", body) if x]
        if len(parts) != 2:
            raise ParmError(p, i, f"expected NAME VALUE (or NAME,VALUE), got {line.strip()[:60]!r}")
        name, text_v = parts
        if not _NAME.match(name):
            raise ParmError(p, i, f"{name[:40]!r} is not a parameter name (letters, digits, '_', at most 16)")
        try:
            v = float(text_v)
        except ValueError:
            raise ParmError(p, i, f"{name}: value {text_v[:40]!r} is not a number") from None
        if not math.isfinite(v):
            raise ParmError(p, i, f"{name}: value must be a finite number, got {text_v!r}")
        if name in out:
            raise ParmError(p, i, f"{name} is given twice")
        out[name] = v
    return out
