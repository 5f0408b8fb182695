"""Radio link model between the host and the firmware, and the telemetry log (.tlog).

Each direction is a :class:`LinkChannel`: the byte stream is cut into MAVLink frames (a radio
packet each), frames are lost with probability ``loss`` (seeded), serialised at ``baud / 10`` bytes
per second (57600 baud = 5760 B/s, one frame after the other), held in a transmit buffer of
``buffer_bytes`` (frames that do not fit are dropped, as an XBee does), and delivered
``latency_s`` after their last byte left. Bytes that are not part of a MAVLink frame pass as
their own packet. Everything is in integer microseconds of simulated time, so a run is exactly
reproducible.

Faults (:class:`LinkFaults`, set per direction): outage windows in which everything that goes on
air is lost (a dead radio, or one burst of interference), latency spikes (frames sent inside a
window arrive ``extra_s`` late; the radio stays first-in first-out, so frames behind a late one
wait for it), and random loss bursts (:func:`random_bursts`: Poisson arrivals, exponential
lengths, drawn once from a seed). ``LinkChannel.down`` cuts the channel from now on.

:class:`Tlog` writes what the radio carried, both ways, in the MAVProxy ``.tlog`` layout: for every
frame an 8-byte big-endian timestamp in microseconds (simulated time since boot here, not Unix
time) followed by the raw frame. ``pymavlink.mavutil.mavlink_connection(path)`` reads it.
"""

from __future__ import annotations

import heapq
import struct
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO, Callable

import numpy as np

__all__ = ["LinkParams", "LinkFaults", "random_bursts", "MavFramer", "LinkChannel", "Tlog", "split_frames"]

_U64 = struct.Struct(">Q")  # .tlog record time stamp


@dataclass(frozen=True)
class LinkParams:
    """One direction of the radio. ``baud`` 0 = unlimited bandwidth."""

    baud: int = 57600
    latency_s: float = 0.010
    loss: float = 0.0  # probability a frame is lost
    buffer_bytes: int = 2048  # radio transmit buffer; frames beyond it are dropped

    def __post_init__(self) -> None:
        if self.baud < 0 or self.latency_s < 0 or not 0.0 <= self.loss <= 1.0 or self.buffer_bytes < 1:
            raise ValueError(f"bad link parameters: {self}")

    @property
    def bytes_per_s(self) -> float:
        return self.baud / 10.0  # 8N1: 10 bits per byte


Window = tuple[float, float]  # [start_s, end_s) in simulated seconds


@dataclass(frozen=True)
class LinkFaults:
    """Scheduled faults of one direction, times in seconds of the session clock (``SilSession.t_s``)."""

    outages: tuple[Window, ...] = ()  # everything sent inside a window is lost
    latency_spikes: tuple[tuple[float, float, float], ...] = ()  # (start_s, end_s, extra_latency_s)

    def __post_init__(self) -> None:
        for w in self.outages:
            if len(w) != 2 or not w[0] < w[1]:
                raise ValueError(f"outage window must be (start_s, end_s) with start < end, got {w!r}")
        for spike in self.latency_spikes:
            if len(spike) != 3 or not spike[0] < spike[1] or spike[2] < 0:
                raise ValueError(f"latency spike must be (start_s, end_s, extra_s >= 0), got {spike!r}")

    def lost_at(self, t_us: int) -> bool:
        t = t_us * 1e-6
        return any(a <= t < b for a, b in self.outages)

    def extra_latency_us(self, t_us: int) -> int:
        t = t_us * 1e-6
        return max((int(round(x * 1e6)) for a, b, x in self.latency_spikes if a <= t < b), default=0)


def random_bursts(seed: int, duration_s: float, rate_hz: float, mean_length_s: float,
                  start_s: float = 0.0) -> tuple[Window, ...]:
    """Loss bursts as a Poisson process of ``rate_hz`` with exponential lengths of mean
    ``mean_length_s`` between ``start_s`` and ``start_s + duration_s`` (deterministic in ``seed``)."""
    if rate_hz <= 0 or mean_length_s <= 0 or duration_s <= 0:
        return ()
    rng = np.random.default_rng(seed)
    out: list[Window] = []
    t = start_s
    end = start_s + duration_s
    while True:
        t += float(rng.exponential(1.0 / rate_hz))
        if t >= end:
            break
        length = float(rng.exponential(mean_length_s))
        out.append((t, min(end, t + length)))
        t += length
    return tuple(out)


class MavFramer:
    """Cuts a byte stream into MAVLink 1/2 frames (partial frames are kept for the next call)."""

    def __init__(self) -> None:
        self._buf = bytearray()

    def feed(self, data: bytes) -> list[bytes]:
        self._buf += data
        out: list[bytes] = []
        b = self._buf
        i = 0
        while i < len(b):
            m = b[i]
            if m not in (0xFD, 0xFE):
                j = i
                while j < len(b) and b[j] not in (0xFD, 0xFE):
                    j += 1
                out.append(bytes(b[i:j]))  # stray bytes pass as they are
                i = j
                continue
            if len(b) - i < 3:
                break
            if m == 0xFD:
                n = 12 + b[i + 1] + (13 if b[i + 2] & 0x01 else 0)
            else:
                n = 8 + b[i + 1]
            if len(b) - i < n:
                break
            out.append(bytes(b[i:i + n]))
            i += n
        del b[:i]
        return out


def split_frames(data: bytes) -> list[bytes]:
    return MavFramer().feed(data)


class LinkChannel:
    """One direction of the link: ``send(t_us, bytes)`` then ``receive(t_us)`` what has arrived."""

    def __init__(self, params: LinkParams, rng: np.random.Generator, name: str = "", tlog: "Tlog | None" = None) -> None:
        self.params = params
        self.name = name
        self._rng = rng
        self._framer = MavFramer()
        self._busy_until_us = 0
        self._queue: list[tuple[int, int, bytes]] = []  # (deliver_us, seq, frame)
        self._seq = 0
        self._tlog = tlog
        self.down = False  # True: everything sent is lost (link cut)
        self.faults: LinkFaults | None = None
        self._last_deliver_us = 0  # first in, first out even through a latency spike
        self.frames_sent = 0
        self.frames_lost = 0
        self.frames_dropped = 0  # transmit buffer overflow
        self.bytes_sent = 0
        self.last_delivery_us: int | None = None

    def reset_framer(self) -> None:
        """Forget a frame half received (its sender is gone), so the next sender's first frame is whole."""
        self._framer = MavFramer()

    def _backlog_bytes(self, t_us: int) -> float:
        if self.params.baud <= 0:
            return 0.0
        return max(0, self._busy_until_us - t_us) * self.params.bytes_per_s * 1e-6

    def send(self, t_us: int, data: bytes) -> None:
        if not data:
            return
        p = self.params
        bps = p.bytes_per_s
        latency_us = int(round(p.latency_s * 1e6))
        tlog = self._tlog
        for frame in self._framer.feed(data):
            self.frames_sent += 1
            n = len(frame)
            busy = self._busy_until_us
            backlog = 0.0 if p.baud <= 0 else max(0, busy - t_us) * bps * 1e-6  # as _backlog_bytes
            if backlog + n > p.buffer_bytes:
                self.frames_dropped += 1
                continue
            start = t_us if t_us > busy else busy
            busy = self._busy_until_us = start + (0 if p.baud <= 0 else int(round(n * 1e6 / bps)))
            lost = self.down or (p.loss > 0.0 and self._rng.random() < p.loss)
            faults = self.faults
            extra_us = 0
            if faults is not None:
                lost = lost or faults.lost_at(start)
                extra_us = faults.extra_latency_us(start)
            if tlog is not None:
                tlog.write(start, frame)  # it went on air (lost or not)
            if lost:
                self.frames_lost += 1
                continue
            self.bytes_sent += n
            deliver = busy + latency_us + extra_us
            if deliver < self._last_deliver_us:
                deliver = self._last_deliver_us
            self._last_deliver_us = deliver
            heapq.heappush(self._queue, (deliver, self._seq, frame))
            self._seq += 1

    def next_delivery_us(self) -> int | None:
        return self._queue[0][0] if self._queue else None

    def receive(self, t_us: int) -> bytes:
        out = []
        while self._queue and self._queue[0][0] <= t_us:
            d, _, frame = heapq.heappop(self._queue)
            self.last_delivery_us = d
            out.append(frame)
        return b"".join(out)


class Tlog:
    """Frames with their time, in the .tlog layout (see the module docstring)."""

    def __init__(self, path: str | Path | None = None, on_error: Callable[[str], None] | None = None) -> None:
        self.path = None if path is None else Path(path)
        self._f: BinaryIO | None = open(path, "wb") if path is not None else None
        self._mem = bytearray() if path is None else None
        self.frames = 0
        self._last_us = 0
        self.frames_dropped = 0  # after a write error (disk full): the log stops there, the run goes on
        self.bytes_written = 0
        self.error: str | None = None
        self._on_error = on_error

    def write(self, t_us: int, frame: bytes) -> None:
        # in file order the stamps never go back: a frame the radio model delivers late is logged when written
        t_us = self._last_us = max(t_us, self._last_us)
        self.frames += 1
        if self._mem is not None:
            self._mem += _U64.pack(t_us)
            self._mem += frame
            return
        if self._f is None:
            self.frames_dropped += 1
            return
        rec = _U64.pack(t_us) + frame
        try:
            self._f.write(rec)
            self.bytes_written += len(rec)
        except OSError as e:
            self.frames_dropped += 1
            self._fail(e)

    def _fail(self, e: OSError) -> None:
        """The first write error: said once, the file closed with what reached the disk."""
        f, self._f = self._f, None
        try:
            if f is not None:
                f.close()
        except OSError:
            pass
        if self._on_disk() == 0 and self.path is not None and self.path.is_file():
            self.path.unlink(missing_ok=True)  # nothing reached the disk: no empty file left behind
        self._said(e)

    def _on_disk(self) -> int:
        try:
            return self.path.stat().st_size if self.path is not None and self.path.is_file() else 0
        except OSError:
            return 0

    def _said(self, e: OSError) -> None:
        if self.error is None:
            self.error = f"{self.path}: {e.strerror or e}"
            if self._on_error is not None:
                self._on_error(f"tlog {self.error}: the log stops here (partial, {self._on_disk()} B on the disk), "
                               "the run goes on")

    def getvalue(self) -> bytes:
        return bytes(self._mem) if self._mem is not None else b""

    def save(self, path: str | Path) -> None:
        Path(path).write_bytes(self.getvalue())

    def close(self) -> None:
        f, self._f = self._f, None
        if f is None:
            return
        try:
            f.close()
        except OSError as e:  # the buffered tail could not be written
            self._said(e)
