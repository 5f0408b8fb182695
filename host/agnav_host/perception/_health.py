"""Is the laser telling the truth? A watchdog over the stream of scans.

A planner fed by a broken laser drives blind, so the host checks every scan before planning on it
and holds the robot when the laser has failed. What counts as a failure (each is a property of the
stream a working laser cannot have; a bare field with nothing in range is *not* one: NaN, inf and 0
all mean "no return"):

- no scan for longer than ``max_gap_s`` (driver hung, cable pulled);
- the beam count changes, or the time stamp does not increase (a restarted or confused driver);
- ranges outside the sensor's physics: negative, or beyond ``range_max_m`` by more than
  ``over_range_factor`` (garbage bytes read as ranges);
- every return vanishing from one scan to the next while the previous scan had at least
  ``vanish_min_valid`` of its beams valid (the world does not disappear in 1/15 s; a laser whose
  receiver died does exactly that); the fault holds until returns come back;
- the same ranges, bit for bit, ``frozen_scans`` times in a row while they contain returns (a
  driver re-sending its last buffer: real ranges always carry noise).

A fault needs ``bad_scans_to_fault`` anomalous scans in a row (one glitch is tolerated) and clears
after ``good_scans_to_clear`` good ones.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..types import LaserScan

__all__ = ["LaserHealthParams", "LaserHealth", "scan_anomaly", "LaserWatchdog"]


@dataclass(frozen=True)
class LaserHealthParams:
    max_gap_s: float = 0.5
    over_range_factor: float = 1.5
    vanish_min_valid: float = 0.3  # fraction of beams
    frozen_scans: int = 5
    bad_scans_to_fault: int = 2
    good_scans_to_clear: int = 5

    def __post_init__(self) -> None:
        if self.max_gap_s <= 0 or self.over_range_factor < 1 or not 0 < self.vanish_min_valid <= 1:
            raise ValueError(f"bad laser health parameters: {self}")
        if self.frozen_scans < 2 or self.bad_scans_to_fault < 1 or self.good_scans_to_clear < 1:
            raise ValueError(f"bad laser health parameters: {self}")


@dataclass(frozen=True)
class LaserHealth:
    ok: bool
    reason: str = ""  # why not ok (the first anomaly of the fault), "" when ok
    since_s: float | None = None  # when the current fault was declared


def _valid_fraction(r: np.ndarray) -> float:
    return float(np.count_nonzero(np.isfinite(r) & (r > 0.0))) / max(1, len(r))


def scan_anomaly(scan: LaserScan, prev: LaserScan | None, params: LaserHealthParams = LaserHealthParams()) -> str:
    """Why this scan cannot come from a working laser ("" when it can). Pure."""
    r = np.asarray(scan.ranges_m, dtype=float)
    if len(r) == 0:
        return "empty scan"
    finite = r[np.isfinite(r)]
    if np.any(finite < 0.0):
        return f"{int(np.count_nonzero(finite < 0.0))} negative ranges"
    if math.isfinite(scan.range_max_m):
        over = int(np.count_nonzero(finite > scan.range_max_m * params.over_range_factor))
        if over:
            return f"{over} ranges beyond {scan.range_max_m * params.over_range_factor:.1f} m"
    if prev is not None:
        if scan.stamp_s <= prev.stamp_s:
            return f"time stamp not increasing ({prev.stamp_s:.3f} -> {scan.stamp_s:.3f} s)"
        if _valid_fraction(r) == 0.0 and _valid_fraction(np.asarray(prev.ranges_m, dtype=float)) >= params.vanish_min_valid:
            return "every return vanished at once"
    return ""


class LaserWatchdog:
    """Feed it every scan (or ``None`` when the driver delivered nothing this cycle) with the
    host's clock; it answers whether the laser can be trusted (see the module docstring)."""

    def __init__(self, params: LaserHealthParams | None = None) -> None:
        self.p = params or LaserHealthParams()
        self.reset()

    def reset(self) -> None:
        self._prev: LaserScan | None = None
        self._last_rx_s: float | None = None
        self._first_t_s: float | None = None  # the first update: a laser that never delivers is timed from here
        self._bad = 0
        self._good = 0
        self._same = 0
        self._vanished = False
        self._beams: int | None = None  # the beam count of the first scan: the sensor's
        self.health = LaserHealth(True)
        self.faults = 0  # faults declared so far

    def _fault(self, reason: str, t_s: float) -> None:
        if self.health.ok:
            self.faults += 1
            self.health = LaserHealth(False, reason, t_s)

    def update(self, scan: LaserScan | None, t_s: float) -> LaserHealth:
        p = self.p
        if self._first_t_s is None:
            self._first_t_s = t_s
        if scan is None:
            since = self._last_rx_s if self._last_rx_s is not None else self._first_t_s
            if t_s - since > p.max_gap_s:
                self._good = 0
                self._fault(f"no scan for {t_s - since:.1f} s" + ("" if self._last_rx_s is not None else " (none yet)"), t_s)
            return self.health
        self._last_rx_s = t_s
        why = scan_anomaly(scan, self._prev, p)
        r = np.asarray(scan.ranges_m, dtype=float)
        if self._beams is None:
            self._beams = len(r)
        elif not why and len(r) != self._beams:
            why = f"beam count changed {self._beams} -> {len(r)}"
        if why == "every return vanished at once":
            self._vanished = True
        if self._vanished and _valid_fraction(r) > 0.0:
            self._vanished = False
        if self._vanished and not why:
            why = "no returns since they all vanished"
        if not why and self._prev is not None and _valid_fraction(r) > 0.0 and \
                np.array_equal(r, np.asarray(self._prev.ranges_m, dtype=float), equal_nan=True):
            self._same += 1
            if self._same + 1 >= p.frozen_scans:
                why = f"identical ranges in {self._same + 1} scans in a row (frozen driver)"
        else:
            self._same = 0
        self._prev = scan
        if why:
            self._good = 0
            self._bad += 1
            if self._bad >= p.bad_scans_to_fault or self._vanished:
                self._fault(why, t_s)
        else:
            self._bad = 0
            self._good += 1
            if not self.health.ok and self._good >= p.good_scans_to_clear:
                self.health = LaserHealth(True)
        return self.health
