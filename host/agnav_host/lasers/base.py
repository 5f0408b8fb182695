"""One interface for every laser scanner the host reads: real devices, the SIL's emulators and replayed logs.

A :class:`LaserSource` delivers :class:`~agnav_host.types.LaserScan` records in the *sensor frame* (beam 0 at
``angle_min_rad``, 0 = the scanner's forward axis, counter-clockwise positive; no return = NaN) whose
``stamp_s`` is on the host's monotonic clock (``time.monotonic()``), the time the scan's middle beam was
measured as well as the source can tell:

- a device that sends its own time stamps (SICK telegrams, SCIP ``MD``/``GD`` time stamps) is mapped to the
  host clock with :class:`DeviceClock` (the smallest arrival-minus-device offset seen, which follows the
  path's least latency);
- a device without them is stamped at arrival minus the stated ``latency_s`` of :class:`LaserInfo`.

Beams with no echo and beams below the device's minimum range are NaN (the device codes differ: 0 for SICK
and RPLIDAR, error codes below 20 for SCIP); ``range_max_m`` is the device's.

Drivers run a reader thread (:class:`ThreadedLaser`): the control loop takes the newest scan with
:meth:`LaserSource.latest` and never blocks on the device. A dropped cable or a closed socket after a good
start is reconnected in the background (``LaserStats.reconnects``) without ending the run; what fails at
:meth:`LaserSource.start` (a wrong address, a device of another kind) raises a :class:`LaserError` whose text
says what to fix.
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

from ..types import LaserScan, Pose2D

__all__ = ["LaserMount", "LaserInfo", "LaserStats", "LaserSource", "LaserError", "LaserAddressError",
           "WrongDeviceError", "TelegramError", "DeviceClock", "ThreadedLaser"]


class LaserError(Exception):
    """A laser scanner could not be used; the message names the device and what to do."""


class LaserAddressError(LaserError):
    """Nothing answers at the address (no route, refused, no such serial port, timed out)."""


class WrongDeviceError(LaserError):
    """Something answered, but it is not the kind of scanner the URL names (the message says what it looks like)."""


class TelegramError(LaserError):
    """A telegram broke the device's protocol (bad framing, checksum, field count or value)."""


@dataclass(frozen=True)
class LaserMount:
    """Where a scanner sits on the robot: position and yaw in the robot frame (m, rad; x forward, y left), and
    for a tilted scanner its pitch down from horizontal (rad, > 0 looks at the ground ahead) and its height
    above the ground (m)."""

    x_m: float = 0.0
    y_m: float = 0.0
    yaw_rad: float = 0.0
    pitch_rad: float = 0.0
    height_m: float = 0.0

    def __post_init__(self) -> None:
        for k in ("x_m", "y_m", "yaw_rad", "pitch_rad", "height_m"):
            if not math.isfinite(getattr(self, k)):
                raise ValueError(f"laser mount: {k} must be a finite number, got {getattr(self, k)!r}")
        if not -math.pi / 2 < self.pitch_rad < math.pi / 2:
            raise ValueError(f"laser mount: pitch must be within +-90 deg, got {math.degrees(self.pitch_rad):g} deg")
        if self.height_m < 0:
            raise ValueError(f"laser mount: height_m must be >= 0, got {self.height_m:g}")
        if self.pitch_rad > 0 and self.height_m <= 0:
            raise ValueError("laser mount: a tilted scanner (pitch > 0) needs its height_m above the ground")

    @property
    def pose(self) -> Pose2D:
        """The planar mounting pose in the robot frame."""
        return Pose2D(self.x_m, self.y_m, self.yaw_rad)

    @property
    def tilted(self) -> bool:
        """True for a scanner pitched down at the ground (ruts, holes, steps)."""
        return self.pitch_rad > 0.0


@dataclass(frozen=True)
class LaserInfo:
    """What a source knows of its device once started."""

    kind: str  # "tim5xx", "lms1xx", "lms5xx", "ust", "urg", "rplidar", "replay"
    address: str  # as given in the URL (host:port, device path, file)
    model: str = ""  # what the device says it is (SICK device ident, SCIP VV PROD, RPLIDAR model byte)
    serial: str = ""
    stamps: str = "arrival"  # "device": mapped from the device's clock; "arrival": arrival time - latency_s
    latency_s: float = 0.0  # stated transfer latency subtracted from arrival stamps (or the offset floor)
    scan_hz: float = 0.0  # the device's scan frequency when it reports one, else 0


@dataclass
class LaserStats:
    """Counters of a running source (read from the control thread; written by the reader thread)."""

    scans: int = 0  # scans delivered to the ring
    malformed: int = 0  # telegrams dropped as malformed (TelegramError inside a running stream)
    reconnects: int = 0  # connections re-made after a loss
    dropped: int = 0  # scans overwritten before the control loop took them
    last_error: str = ""  # the most recent problem, for status lines and logs


@runtime_checkable
class LaserSource(Protocol):
    """A scanner the host loop reads (see the module docstring for frames, stamps and invalid beams)."""

    url: str
    mount: LaserMount
    stats: LaserStats

    def start(self, timeout_s: float = 5.0) -> LaserInfo:
        """Connect, check the device is of the URL's kind, start scans; LaserError says why not."""
        ...

    def latest(self) -> LaserScan | None:
        """The newest scan not yet taken (None when none arrived since the last call). Never blocks."""
        ...

    def wait(self, timeout_s: float) -> LaserScan | None:
        """The next scan, waiting up to ``timeout_s`` (None on time-out)."""
        ...

    def close(self) -> None:
        """Stop scans and release the device; idempotent."""
        ...


class DeviceClock:
    """Maps a device's time stamps (s, any origin, may wrap) to the host's monotonic clock.

    ``offset = min(arrival - device)`` over the scans seen: the scan that came through fastest bounds the
    path latency from below, so ``device + offset`` is never later than arrival and follows the device's clock
    exactly. ``wrap_s`` (e.g. 2**32 us for a 32-bit microsecond counter, 2**24 ms for SCIP) unwraps the
    counter. ``latency_s`` is the known least transfer time added back (the telegram's own duration).
    """

    def __init__(self, wrap_s: float | None = None, latency_s: float = 0.0) -> None:
        self.wrap_s = wrap_s
        self.latency_s = latency_s
        self._offset: float | None = None
        self._last_raw: float | None = None
        self._turns = 0

    def reset(self) -> None:
        """Forget the offset (a reconnect may have restarted the device's clock)."""
        self._offset = None
        self._last_raw = None
        self._turns = 0

    def to_host(self, device_s: float, arrival_s: float) -> float:
        if self.wrap_s is not None and self._last_raw is not None and device_s < self._last_raw - 0.5 * self.wrap_s:
            self._turns += 1
        self._last_raw = device_s
        d = device_s + self._turns * (self.wrap_s or 0.0)
        off = arrival_s - d - self.latency_s
        if self._offset is None or off < self._offset:
            self._offset = off
        return d + self._offset


class ThreadedLaser:
    """Base of the device drivers: a reader thread with reconnect, and the newest-scan slot.

    A driver implements :meth:`_connect` (open the transport, identify the device, start scans; raise
    LaserAddressError / WrongDeviceError / TelegramError), :meth:`_read_scan` (block until one scan, return it
    stamped on the host clock, or None on a read time-out) and :meth:`_disconnect` (close quietly).
    """

    kind = "laser"
    reconnect_delay_s = 0.5  # first wait before a reconnect; doubles up to reconnect_max_s
    reconnect_max_s = 4.0

    def __init__(self, url: str, mount: LaserMount | None = None) -> None:
        self.url = url
        self.mount = mount or LaserMount()
        self.stats = LaserStats()
        self.info: LaserInfo | None = None
        self._cond = threading.Condition()
        self._newest: LaserScan | None = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    # ---- what a driver implements ---------------------------------------------------------------------
    def _connect(self, timeout_s: float) -> LaserInfo:
        raise NotImplementedError

    def _read_scan(self) -> LaserScan | None:
        raise NotImplementedError

    def _disconnect(self) -> None:
        raise NotImplementedError

    # ---- LaserSource -----------------------------------------------------------------------------------
    def start(self, timeout_s: float = 5.0) -> LaserInfo:
        if self._thread is not None:
            assert self.info is not None
            return self.info
        self.info = self._connect(timeout_s)
        self._stop.clear()
        self._thread = threading.Thread(target=self._run, name=f"laser {self.url}", daemon=True)
        self._thread.start()
        return self.info

    def latest(self) -> LaserScan | None:
        with self._cond:
            s, self._newest = self._newest, None
        return s

    def wait(self, timeout_s: float) -> LaserScan | None:
        end = time.monotonic() + timeout_s
        with self._cond:
            while self._newest is None:
                left = end - time.monotonic()
                if left <= 0 or self._stop.is_set():
                    return None
                self._cond.wait(left)
            s, self._newest = self._newest, None
        return s

    def close(self) -> None:
        self._stop.set()
        t, self._thread = self._thread, None
        if t is not None:
            t.join(timeout=3.0)
        try:
            self._disconnect()
        except Exception:  # closing a half-open device must not raise
            pass

    # ---- the reader thread ------------------------------------------------------------------------------
    def _deliver(self, scan: LaserScan) -> None:
        with self._cond:
            if self._newest is not None:
                self.stats.dropped += 1
            self._newest = scan
            self.stats.scans += 1
            self._cond.notify_all()

    def _run(self) -> None:
        delay = self.reconnect_delay_s
        while not self._stop.is_set():
            try:
                scan = self._read_scan()
            except TelegramError as e:  # one bad telegram: count it, keep the stream
                self.stats.malformed += 1
                self.stats.last_error = str(e)
                continue
            except (OSError, LaserError) as e:  # the connection is gone: reconnect until closed
                self.stats.last_error = f"{self.url}: {e}"
                try:
                    self._disconnect()
                except Exception:
                    pass
                while not self._stop.is_set():
                    if self._stop.wait(delay):
                        return
                    try:
                        self.info = self._connect(timeout_s=2.0)
                    except (OSError, LaserError) as e2:
                        self.stats.last_error = f"{self.url}: {e2}"
                        delay = min(2 * delay, self.reconnect_max_s)
                        continue
                    self.stats.reconnects += 1
                    delay = self.reconnect_delay_s
                    break
                continue
            if scan is not None:
                self._deliver(scan)
