"""Ruts from a tilted laser: the edges of each groove on the scan line and the midline to follow.

On flat ground a tilted laser's scan line is a straight line across the robot's path at
``x = H / tan(theta)`` ahead. A rut shows as a dip in the height profile z(y) along that line. Each
run of returns deeper than ``edge_depth_m`` below the ground level (the median height) and between
``min_width_m`` and ``max_width_m`` wide is a rut; its edges are the lateral positions where the
profile crosses that level (linear interpolation). The path to follow is the middle between the
outer edges of the two ruts nearest the robot (ref 000, Fig. 5-24: "the middle of the left and right
ends of the ruts"), or the centre of a single rut.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..types import DriveCommand, LaserScan, Observation
from ._follow import DriveLimits
from ._ground import TiltedMount, ground_points

__all__ = ["Rut", "RutEstimate", "RutParams", "detect_ruts", "RutFollower", "RutFollowerParams"]


@dataclass(frozen=True)
class Rut:
    """One groove on the scan line, robot frame: lateral edges (m, left > right), depth (m), and x_m, the
    distance ahead of its edges (the beams that fall into the groove land further on)."""

    left_y_m: float
    right_y_m: float
    depth_m: float
    x_m: float

    @property
    def centre_y_m(self) -> float:
        return 0.5 * (self.left_y_m + self.right_y_m)

    @property
    def width_m(self) -> float:
        return self.left_y_m - self.right_y_m


@dataclass(frozen=True)
class RutEstimate:
    """All ruts found (right to left) and the midline point to follow (robot frame, m), or None."""

    ruts: tuple[Rut, ...]
    midline_xy: tuple[float, float] | None


@dataclass(frozen=True)
class RutParams:
    edge_depth_m: float = 0.02
    min_width_m: float = 0.08
    max_width_m: float = 0.8
    max_pair_spacing_m: float = 2.5  # two ruts further apart than this are not one vehicle's track

    def __post_init__(self) -> None:
        if not (self.edge_depth_m > 0 and 0 < self.min_width_m < self.max_width_m):
            raise ValueError("RutParams: need edge_depth_m > 0 and 0 < min_width_m < max_width_m")


def detect_ruts(scan: LaserScan, tm: TiltedMount, params: RutParams | None = None) -> RutEstimate:
    """Ruts on one tilted scan line (see the module docstring)."""
    p = params or RutParams()
    pts = ground_points(scan, tm)
    ok = np.isfinite(pts[:, 2])
    pts = pts[ok]
    if len(pts) < 5:
        return RutEstimate((), None)
    order = np.argsort(pts[:, 1])
    y, z, x = pts[order, 1], pts[order, 2], pts[order, 0]
    level = float(np.median(z))
    low = z < level - p.edge_depth_m
    d = np.diff(np.concatenate(([0], low.astype(np.int8), [0])))
    starts, ends = np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1
    thr = level - p.edge_depth_m
    ruts = []
    for s0, e0 in zip(starts, ends):
        if s0 == 0 or e0 == len(y) - 1:
            continue  # runs off the end of the scan: no edge on that side
        # interpolate the level crossings between the last high and the first low point
        yr = y[s0 - 1] + (thr - z[s0 - 1]) * (y[s0] - y[s0 - 1]) / (z[s0] - z[s0 - 1])
        yl = y[e0] + (thr - z[e0]) * (y[e0 + 1] - y[e0]) / (z[e0 + 1] - z[e0])
        w = yl - yr
        if p.min_width_m <= w <= p.max_width_m:
            ruts.append(Rut(float(yl), float(yr), float(level - z[s0:e0 + 1].min()), float(0.5 * (x[s0 - 1] + x[e0 + 1]))))
    if not ruts:
        return RutEstimate((), None)
    # the rut nearest the robot's path, and a partner on its other side within a vehicle's track
    by = sorted(ruts, key=lambda r: abs(r.centre_y_m))
    first = by[0]
    partner = None
    for r in by[1:]:
        if abs(r.centre_y_m - first.centre_y_m) <= p.max_pair_spacing_m:
            partner = r
            break
    if partner is None:
        mid = (first.x_m, first.centre_y_m)
    else:
        lft, rgt = (first, partner) if first.centre_y_m > partner.centre_y_m else (partner, first)
        mid = (0.5 * (lft.x_m + rgt.x_m), 0.5 * (lft.left_y_m + rgt.right_y_m))
    return RutEstimate(tuple(ruts), mid)


@dataclass(frozen=True)
class RutFollowerParams:
    tilted: TiltedMount = field(default_factory=TiltedMount)
    ruts: RutParams = field(default_factory=RutParams)
    limits: DriveLimits = field(default_factory=DriveLimits)
    speed_m_s: float = 0.4
    smoothing: float = 0.5  # low-pass weight of the previous midline


class RutFollower:
    """Pure pursuit to the rut midline point on the tilted scan line (``obs.extras['tilted_scan']``):
    curvature ``2 y / (x^2 + y^2)`` to the point (x, y) ahead; straight on while no rut is seen."""

    uses_tilted_laser = True  # the simulator's runner then puts the tilted scan in obs.extras

    def __init__(self, params: RutFollowerParams | None = None) -> None:
        self.params = params or RutFollowerParams()
        self._y: float | None = None
        self._x = 1.0

    def reset(self) -> None:
        self._y = None
        self._x = 1.0

    def step(self, obs: Observation) -> DriveCommand:
        p = self.params
        ts = obs.extras.get("tilted_scan")
        if isinstance(ts, LaserScan):
            est = detect_ruts(ts, p.tilted, p.ruts)
            if est.midline_xy is not None:
                xm, ym = est.midline_xy
                self._y = ym if self._y is None else p.smoothing * self._y + (1 - p.smoothing) * ym
                self._x = xm
        if self._y is None:
            return p.limits.command(p.speed_m_s, 0.0)
        x = self._x
        k = 2.0 * self._y / max(x * x + self._y * self._y, 1e-6)
        return p.limits.command(p.speed_m_s, p.speed_m_s * k)
