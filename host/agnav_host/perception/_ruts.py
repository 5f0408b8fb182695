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

import math
from dataclasses import dataclass, field

import numpy as np

from ..types import DriveCommand, LaserScan, Observation
from ._follow import DriveLimits, _steer
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
    """Rut following (SI units). The midline points seen over the last ``history_m`` of travel are kept in
    the world frame (through the robot's pose: odometry on a robot); once they span ``min_span_m`` along the
    robot, a quadratic through them gives the lateral error, heading error and curvature at the robot, and the
    row followers' steering law (``omega_n``, ``zeta``, curvature feed-forward) drives the error to zero.
    Before that: pure pursuit to the latest midline point, low-passed with ``smoothing``."""

    tilted: TiltedMount = field(default_factory=TiltedMount)
    ruts: RutParams = field(default_factory=RutParams)
    limits: DriveLimits = field(default_factory=DriveLimits)
    speed_m_s: float = 0.4
    smoothing: float = 0.5  # low-pass weight of the previous midline (pure pursuit only)
    history_m: float = 3.0
    min_span_m: float = 1.2
    omega_n_rad_s: float = 1.2
    zeta: float = 0.9

    def __post_init__(self) -> None:
        if not (self.speed_m_s > 0 and self.history_m > 0 and self.min_span_m > 0 and self.omega_n_rad_s > 0
                and self.zeta > 0 and 0 <= self.smoothing < 1):
            raise ValueError("RutFollowerParams: speed, history, span, omega_n and zeta must be > 0, 0 <= smoothing < 1")


class RutFollower:
    """Follow the rut midline seen on the tilted scan line (``obs.extras['tilted_scan']``); see
    :class:`RutFollowerParams`. Straight on while no rut has been seen."""

    uses_tilted_laser = True  # the simulator's runner then puts the tilted scan in obs.extras

    def __init__(self, params: RutFollowerParams | None = None) -> None:
        self.params = params or RutFollowerParams()
        self.reset()

    def reset(self) -> None:
        self._y: float | None = None
        self._x = 1.0
        self._pts: list[tuple[float, float, float]] = []  # (travel, world x, world y) of midline points
        self._s = 0.0
        self._last: tuple[float, float] | None = None
        self.state: tuple[float, float, float] | None = None  # last (lateral error, heading error, curvature)

    def step(self, obs: Observation) -> DriveCommand:
        p = self.params
        pose = obs.pose
        if self._last is not None:
            self._s += math.hypot(pose.x_m - self._last[0], pose.y_m - self._last[1])
        self._last = (pose.x_m, pose.y_m)
        c, s = math.cos(pose.yaw_rad), math.sin(pose.yaw_rad)
        ts = obs.extras.get("tilted_scan")
        if isinstance(ts, LaserScan):
            est = detect_ruts(ts, p.tilted, p.ruts)
            if est.midline_xy is not None:
                xm, ym = est.midline_xy
                self._y = ym if self._y is None else p.smoothing * self._y + (1 - p.smoothing) * ym
                self._x = xm
                self._pts.append((self._s, pose.x_m + c * xm - s * ym, pose.y_m + s * xm + c * ym))
        while self._pts and self._pts[0][0] < self._s - p.history_m:
            self._pts.pop(0)
        if len(self._pts) >= 6:
            w = np.asarray(self._pts)
            dx, dy = w[:, 1] - pose.x_m, w[:, 2] - pose.y_m
            x, y = c * dx + s * dy, -s * dx + c * dy  # robot frame
            if float(np.ptp(x)) >= p.min_span_m:
                a0, b1, c2 = (float(v) for v in np.polynomial.polynomial.polyfit(x, y, 2))
                e = -a0 * math.cos(math.atan(b1))  # robot left of the midline: positive
                psi = -math.atan(b1)
                kappa = 2.0 * c2 / (1.0 + b1 * b1) ** 1.5
                self.state = (e, psi, kappa)
                return _steer(p.limits, p.speed_m_s, e, psi, kappa, p.omega_n_rad_s, p.zeta)
        if self._y is None:
            return p.limits.command(p.speed_m_s, 0.0)
        x0 = self._x
        k = 2.0 * self._y / max(x0 * x0 + self._y * self._y, 1e-6)
        return p.limits.command(p.speed_m_s, p.speed_m_s * k)
