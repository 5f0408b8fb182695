"""The laser watchdog: a broken laser is recognised from the scan stream alone, a bare field
with nothing in range is not a fault."""

from __future__ import annotations

import math

import numpy as np
import pytest

from agnav_host.perception._health import LaserHealthParams, LaserWatchdog, scan_anomaly
from agnav_host.types import LaserScan

N = 181


def scan(t: float, ranges=None, seed: int = 0, range_max: float = 4.0) -> LaserScan:
    if ranges is None:
        rng = np.random.default_rng(seed)
        ranges = 2.0 + 0.01 * rng.standard_normal(N)  # a wall 2 m away, with noise
    return LaserScan(-math.pi / 2, math.pi / (N - 1), np.asarray(ranges, dtype=float), range_max, t)


def feed(w: LaserWatchdog, scans) -> list[bool]:
    return [w.update(s, s.stamp_s if s is not None else t).ok for t, s in scans]


def stream(n: int, t0: float = 0.0, **kw):
    return [(t0 + i / 15, scan(t0 + i / 15, seed=i, **kw)) for i in range(n)]


def test_healthy_stream_and_an_empty_field_are_fine():
    w = LaserWatchdog()
    assert all(feed(w, stream(30)))
    empty = [(2 + i / 15, scan(2 + i / 15, np.full(N, np.nan))) for i in range(30)]
    w2 = LaserWatchdog()
    assert all(feed(w2, empty)), "nothing in range is not a fault"
    assert w.faults == 0 and w2.faults == 0


@pytest.mark.parametrize("bad, reason", [
    (lambda t: scan(t, np.full(N, -1.0)), "negative"),
    (lambda t: scan(t, np.full(N, 60.0)), "beyond"),
    (lambda t: LaserScan(-1.0, 0.01, np.full(90, 2.0), 4.0, t), "beam count"),
])
def test_garbage_is_a_fault_after_two_scans_and_clears_after_five_good(bad, reason):
    w = LaserWatchdog()
    feed(w, stream(10))
    t = 10 / 15
    assert w.update(bad(t), t).ok, "one glitch is tolerated"
    h = w.update(bad(t + 1 / 15), t + 1 / 15)
    assert not h.ok and reason in h.reason
    oks = feed(w, stream(6, t0=t + 2 / 15))
    assert oks == [False] * 4 + [True] * 2


def test_vanishing_returns_latch_until_they_come_back():
    w = LaserWatchdog()
    feed(w, stream(10))
    dead = [(1 + i / 15, scan(1 + i / 15, np.full(N, np.nan))) for i in range(20)]
    oks = feed(w, dead)
    assert oks[0] is False and not any(oks), "a laser whose returns all vanish at once has failed"
    assert "vanished" in w.health.reason
    assert feed(w, stream(5, t0=3.0)) == [False] * 4 + [True]


def test_frozen_driver_and_silence():
    w = LaserWatchdog()
    feed(w, stream(5))
    s = scan(0.0, seed=99)
    frozen = [(1 + i / 15, LaserScan(s.angle_min_rad, s.angle_increment_rad, s.ranges_m.copy(), 4.0, 1 + i / 15))
              for i in range(8)]
    oks = feed(w, frozen)
    assert oks[:3] == [True] * 3 and not oks[-1] and "frozen" in w.health.reason
    w2 = LaserWatchdog(LaserHealthParams(max_gap_s=0.5))
    feed(w2, stream(5))
    assert w2.update(None, 0.6).ok and not w2.update(None, 0.9).ok
    assert "no scan" in w2.health.reason


def test_beam_count_is_the_first_scans():
    w = LaserWatchdog()
    feed(w, stream(3))
    short = [(1 + i / 15, LaserScan(-1.0, 0.01, np.full(90, 2.0), 4.0, 1 + i / 15)) for i in range(4)]
    assert feed(w, short) == [True, False, False, False], "a new beam count stays a fault"


def test_stamp_going_backwards():
    prev = scan(1.0)
    assert "time stamp" in scan_anomaly(scan(0.9, seed=1), prev)
    assert scan_anomaly(scan(1.1, seed=1), prev) == ""


def test_bad_parameters_are_refused():
    with pytest.raises(ValueError):
        LaserHealthParams(max_gap_s=0)
    with pytest.raises(ValueError):
        LaserHealthParams(frozen_scans=1)
