"""The progress line of the long commands (sim, bench, faults, replay, rows): one line on stderr, drawn again
in place (``\\r``) as the work goes on, and ended with a newline, or wiped, when the work is done."""

from __future__ import annotations

import sys
import time
from typing import Callable

__all__ = ["ProgressLine", "bar", "bar_line"]


def bar(done: int, total: int, width: int = 30) -> str:
    """``[#########.....................] 3/10``: ``done`` of ``total`` as a bar of ``width`` cells."""
    filled = int(width * done / total) if total else width
    return f"[{'#' * filled}{'.' * (width - filled)}] {done}/{total}"


class ProgressLine:
    """A line on stderr that :meth:`show` draws again in place.

    ``every_s``: draw at most this often (0: at every call that changes the text); ``wipe``: :meth:`end` clears
    the line instead of ending it with a newline (for a line shown only while the output goes elsewhere)."""

    def __init__(self, every_s: float = 0.0, wipe: bool = False) -> None:
        self.every_s = every_s
        self.wipe = wipe
        self.shown = False
        self._text: str | None = None
        self._at = -float("inf")

    def show(self, text: str) -> None:
        """Draw ``text`` (unless it is what the line shows, or the last drawing is more recent than ``every_s``)."""
        now = time.monotonic()
        if text == self._text or now - self._at < self.every_s:
            return
        self._text, self._at, self.shown = text, now, True
        print(f"\r{text}", end="", file=sys.stderr, flush=True)

    def end(self, text: str | None = None) -> None:
        """Draw ``text`` last (when given), then end the line: a newline, or with ``wipe`` the line cleared.
        Nothing when nothing was drawn."""
        if text is not None and text != self._text:
            self._text, self.shown = text, True
            print(f"\r{text}", end="", file=sys.stderr, flush=True)
        if self.shown:
            print("\r\033[K" if self.wipe else "", end="" if self.wipe else "\n", file=sys.stderr, flush=True)
        self.shown = False
        self._text = None


def bar_line(label_width: int) -> Callable[[int, int, str], None]:
    """A progress callback ``(done, total, label)``: the :func:`bar` and the label (cut or padded to
    ``label_width``) on a :class:`ProgressLine`, ended when ``done`` reaches ``total``."""
    line = ProgressLine()

    def show(done: int, total: int, label: str) -> None:
        text = f"{bar(done, total)} {label:<{label_width}.{label_width}}"
        if done >= total:
            line.end(text)
        else:
            line.show(text)

    return show
