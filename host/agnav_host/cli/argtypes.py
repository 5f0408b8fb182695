"""Argument types of the ``agnav`` options: checked numbers, whole numbers, text that is not empty, goals.

Number options use these checked types so that ``nan``, ``inf`` or a negative count is refused by argparse
with the option's name, not deep in a run. Every option or positional that takes text (a path, a name, a
device) and declares no type of its own gets :func:`nonempty_text` (added by :func:`text_refusing_empty`):
an empty value (``--out ""``, ``--device "$PORT"`` with ``PORT`` unset) would otherwise mean ``.`` or the
option's default.
"""

from __future__ import annotations

import argparse
import math
from typing import Any, Callable

__all__ = ["finite_float", "positive_float", "positive_float_at_most", "DAY_S", "up_to_a_day", "nonneg_float",
           "int_in", "positive_int", "nonneg_int", "nonempty_text", "text_refusing_empty", "parse_goal"]


def _number(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None


def finite_float(text: str) -> float:
    """argparse type: a finite number (``nan`` and ``inf`` refused)."""
    v = _number(text)
    if not math.isfinite(v):
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text!r}")
    return v


def positive_float(text: str) -> float:
    """argparse type: a finite number > 0."""
    v = finite_float(text)
    if v <= 0:
        raise argparse.ArgumentTypeError(f"must be > 0, got {text!r}")
    return v


def positive_float_at_most(hi: float, what: str = "") -> Callable[[str], float]:
    """argparse type: a finite number > 0 and <= ``hi`` (``what`` says what ``hi`` is: "a day")."""

    def parse(text: str) -> float:
        v = positive_float(text)
        if v > hi:
            raise argparse.ArgumentTypeError(f"must be <= {hi:g}{f' ({what})' if what else ''}, got {text!r}")
        return v

    parse.__name__ = "float"
    return parse


#: The longest time an option takes, s (a wait, a timeout, an arrival time): longer waits overflow the
#: threading timeouts they end in, and no field robot's task is timed further out
DAY_S = 86400.0
up_to_a_day = positive_float_at_most(DAY_S, "a day")


def nonneg_float(text: str) -> float:
    """argparse type: a finite number >= 0."""
    v = finite_float(text)
    if v < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {text!r}")
    return v


def int_in(lo: int | None = None, hi: int | None = None) -> Callable[[str], int]:
    """argparse type: a whole number in [lo, hi] (either end open when None)."""

    def parse(text: str) -> int:
        try:  # decimal first, leading zeros and all ("010" is ten), then 0x10, 0o17, 0b101
            v = int(text, 10)
        except ValueError:
            try:
                v = int(text, 0)
            except ValueError:
                raise argparse.ArgumentTypeError(f"expected a whole number, got {text!r}{_digits_hint(text)}") from None
        if (lo is not None and v < lo) or (hi is not None and v > hi):
            span = f"{lo}..{hi}" if lo is not None and hi is not None else (f">= {lo}" if lo is not None else f"<= {hi}")
            raise argparse.ArgumentTypeError(f"must be {span}, got {text!r}")
        return v

    parse.__name__ = "int"
    return parse


positive_int = int_in(1)
nonneg_int = int_in(0)


def _digits_hint(text: str) -> str:
    """For a whole number written as a float (``1e3``, ``10.0``): the digits to write instead."""
    try:
        f = float(text)
    except ValueError:
        return ""
    return f" (write it in digits: {int(f)})" if f.is_integer() and abs(f) < 2**53 else ""


def nonempty_text(text: str) -> str:
    """argparse type of the text options and positionals (paths, names, devices): anything but the empty string.
    An empty value (``--out ""``, or ``--device "$PORT"`` with PORT not set) would otherwise be taken for the
    current folder or silently for the option's default."""
    if text == "":
        raise argparse.ArgumentTypeError("empty value (a shell variable that is not set?)")
    return text


def text_refusing_empty(kw: dict[str, Any]) -> dict[str, Any]:
    """``kw`` of an argument with :func:`nonempty_text` as its type when it takes text: it stores a value and has
    neither a type nor a list of choices of its own."""
    if "type" in kw or "choices" in kw or kw.get("action", "store") not in ("store", "append", "extend"):
        return kw
    return {**kw, "type": nonempty_text}


def parse_goal(text: str) -> tuple[float, float, float | None]:
    """``X,Y`` or ``X,Y,HEADING_DEG`` -> (x_m, y_m, heading_deg or None). Negative numbers are fine."""
    parts = [p.strip() for p in text.split(",")]
    if len(parts) not in (2, 3):
        raise argparse.ArgumentTypeError(f"goal must be X,Y or X,Y,HEADING_DEG, got {text!r}")
    try:
        vals = [float(p) for p in parts]
    except ValueError:
        raise argparse.ArgumentTypeError(f"goal must contain numbers, got {text!r}") from None
    if not all(math.isfinite(v) for v in vals):
        raise argparse.ArgumentTypeError(f"goal values must be finite, got {text!r}")
    return vals[0], vals[1], vals[2] if len(vals) == 3 else None
