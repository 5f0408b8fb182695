"""Telemetry logs in mavutil's ``.tlog`` format (what MAVProxy, mavlogdump.py and
``pymavlink.mavutil.mavlogfile`` read): each MAVLink frame is preceded by an 8-byte big-endian
timestamp in microseconds since the Unix epoch. Both directions go into the same file (the
host's own frames carry the host's system id, 255 by default), as MAVProxy does.
"""

from __future__ import annotations

import struct
import threading
import time
from pathlib import Path
from typing import Any, Callable, Iterator

__all__ = ["TlogWriter", "read_tlog"]


class TlogWriter:
    """Append-only, thread-safe tlog writer. ``write(frame)`` stamps with the wall clock."""

    def __init__(self, path: str | Path, flush_every_s: float = 1.0) -> None:
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._f = open(self.path, "ab")
        self._lock = threading.Lock()
        self._flush_every_s = flush_every_s
        self._last_flush = time.monotonic()
        self.frames = 0
        self.bytes = 0
        self.frames_dropped = 0  # not written because the file failed (disk full, I/O error)
        self.error: str | None = None  # the first write error; the log stops growing after it

    def _failed(self, e: OSError) -> None:
        if self.error is None:
            self.error = f"{self.path}: {e.strerror or e}"
            try:  # keep what made it to the disk; the buffered rest is gone
                self._f.close()
            except OSError:
                pass

    def write(self, frame: bytes | bytearray, t_s: float | None = None) -> None:
        usec = int((time.time() if t_s is None else t_s) * 1e6) & ~3  # mavutil masks the low bits too
        with self._lock:
            if self._f.closed:
                if self.error is not None:
                    self.frames_dropped += 1
                return
            try:
                self._f.write(struct.pack(">Q", usec) + bytes(frame))
                self.frames += 1
                self.bytes += len(frame) + 8
                now = time.monotonic()
                if now - self._last_flush >= self._flush_every_s:
                    self._f.flush()
                    self._last_flush = now
            except OSError as e:  # disk full: the link must go on, the log stops here
                self.frames_dropped += 1
                self._failed(e)

    def flush(self) -> None:
        with self._lock:
            if not self._f.closed:
                try:
                    self._f.flush()
                except OSError as e:
                    self._failed(e)

    def close(self) -> None:
        with self._lock:
            if not self._f.closed:
                try:
                    self._f.close()
                except OSError as e:
                    self._failed(e)

    def __enter__(self) -> "TlogWriter":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


#: read_tlog reports its progress every this many frames
PROGRESS_EVERY = 4096


def read_tlog(path: str | Path, progress: Callable[[int, int], None] | None = None) -> Iterator[tuple[float, Any]]:
    """Yield (unix time s, decoded message) from a tlog, with pymavlink's own reader
    (``mavutil.mavlogfile``) fitted with the AgNav dialect so AgNav messages decode.
    ``progress(bytes read, file bytes)`` is called every PROGRESS_EVERY frames and once at the end."""
    from pymavlink import mavutil

    from ..protocol import dialect

    log = mavutil.mavlogfile(str(path), robust_parsing=True, notimestamps=False)
    d = dialect()
    log.mav = d.MAVLink(log, srcSystem=0, srcComponent=0)
    log.mav.robust_parsing = True
    log.first_byte = False
    log.WIRE_PROTOCOL_VERSION = "2.0"
    total = Path(path).stat().st_size if progress is not None else 0
    n = 0
    try:
        while True:
            m = log.recv_msg()
            if m is None:
                break
            n += 1
            if progress is not None and n % PROGRESS_EVERY == 0:
                progress(log.f.tell(), total)
            if m.get_type() == "BAD_DATA":
                continue
            yield float(getattr(m, "_timestamp", 0.0)), m
        if progress is not None:
            progress(total, total)
    finally:
        log.close()


#: a gap between two frames longer than this (s) is a break in the log (runs appended to one file, a
#: clock set while logging), not time the link ran
TLOG_BREAK_S = 10.0

MAV_TYPE_GCS = 6  # a ground station's HEARTBEAT type (common.xml MAV_TYPE)


def host_systems(path: str | Path) -> set[int]:
    """MAVLink system ids of the ground stations (GCS heartbeats) in a tlog; {255} when none is found
    (the host's frames are what the log "sent", every other system's what it received)."""
    ids = {m.get_srcSystem() for _, m in read_tlog(path) if m.get_type() == "HEARTBEAT" and m.type == MAV_TYPE_GCS}
    return ids or {255}


class LogClock:
    """Time since the start of a tlog's run from its wall-clock stamps, in which a stamp going back (the
    clock was set) or jumping ahead by more than ``TLOG_BREAK_S`` (another run appended) adds nothing;
    ``breaks`` counts them."""

    def __init__(self) -> None:
        self.rel_s = 0.0
        self.breaks = 0
        self._last: float | None = None

    def tick(self, t: float) -> float:
        if self._last is not None:
            gap = t - self._last
            if 0.0 <= gap <= TLOG_BREAK_S:
                self.rel_s += gap
            else:
                self.breaks += 1
        self._last = t
        return self.rel_s

