"""Obstacles for timed planning: the ref-003 deviation point, moving obstacles predicted with their
tracked velocity and its uncertainty, and space-time clearance checks of a plan.

Deviation point (003 eqs. 4.29-4.32): an obstacle seen at range Ddect and bearing theta_dect from the
sensor at (x_sen, y_sen), of radius Robs, is passed through the point

    D_dev     = sqrt((Rsm + w)^2 + (Ddect + Robs)^2)
    theta_dev = theta_dect +- atan((Rsm + w) / (Ddect + Robs))
    (x_dev, y_dev) = (x_sen, y_sen) + D_dev (cos theta_dev, sin theta_dev)

i.e. abreast of the obstacle's centre and Rsm + w to its side (Rsm safety margin, w robot width);
+ turns left, - right.

Moving obstacles: 003 registers two detections, estimates the obstacle's step and checks whether the
position two steps ahead falls in the robot's collision radius. AgNav uses the tracker's velocity
instead and predicts over the whole horizon, growing the obstacle's radius with the velocity
uncertainty: r(t) = r0 + k sigma_p + min(k sigma_v (t - t_stamp), max_growth) (k = 2: about 95 % per
axis; the growth is capped because tracks are refreshed every step and walkers turn). From a tracker's
covariance, sigma_v is the largest 1-sigma of the velocity in any direction (the speed's and the
heading's uncertainty), sigma_p the larger position sigma. The plan is
checked against that disc at every sample time (space-time), not against a two-step snapshot.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Protocol, Sequence

import numpy as np

from ...types import FloatArray
from ._plan import TimedPlan

__all__ = [
    "deviation_point",
    "MovingObstacle",
    "PlanObstacle",
    "SpaceTimeObstacle",
    "Conflict",
    "first_conflict",
    "first_blocked_s",
    "cluster_ordered",
    "moving_obstacles_from",
]


def deviation_point(x_sen_m: float, y_sen_m: float, d_dect_m: float, theta_dect_rad: float, r_obs_m: float,
                    r_sm_m: float, width_m: float, side: int) -> tuple[float, float, float, float]:
    """(D_dev m, theta_dev rad, x_dev m, y_dev m) of ref 003 eqs. 4.29-4.32; side +1 = left, -1 = right."""
    lat = r_sm_m + width_m
    depth = d_dect_m + r_obs_m
    d_dev = math.sqrt(lat * lat + depth * depth)
    th = theta_dect_rad + (1.0 if side >= 0 else -1.0) * math.atan2(lat, depth)
    return d_dev, th, x_sen_m + d_dev * math.cos(th), y_sen_m + d_dev * math.sin(th)


class SpaceTimeObstacle(Protocol):
    def predict(self, t_s: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Centres (n, 2) m and radii (n,) m at absolute times ``t_s`` (n,)."""
        ...


@dataclass(frozen=True)
class MovingObstacle:
    """A tracked obstacle: centre (m), velocity (m/s), radius (m), 1-sigma speed and position
    uncertainty, time of the estimate (s). :meth:`from_any` adapts tuples ``(x, y, vx, vy, radius,
    speed_sigma)`` and objects with those fields, e.g. ``agnav_host.perception``'s ``Track`` (its position
    covariance gives the position sigma)."""

    x_m: float
    y_m: float
    vx_m_s: float
    vy_m_s: float
    radius_m: float
    speed_sigma_m_s: float = 0.1
    pos_sigma_m: float = 0.05
    stamp_s: float = 0.0
    k_sigma: float = 2.0
    max_growth_m: float = 0.75  # the uncertainty disc stops growing here (walkers turn, tracks update)

    @property
    def speed_m_s(self) -> float:
        return math.hypot(self.vx_m_s, self.vy_m_s)

    def predict(self, t_s: FloatArray) -> tuple[FloatArray, FloatArray]:
        dt = np.maximum(np.asarray(t_s, dtype=float) - self.stamp_s, 0.0)
        xy = np.column_stack((self.x_m + self.vx_m_s * dt, self.y_m + self.vy_m_s * dt))
        r = self.radius_m + self.k_sigma * self.pos_sigma_m + np.minimum(self.k_sigma * self.speed_sigma_m_s * dt, self.max_growth_m)
        return xy, r

    @staticmethod
    def from_any(o: Any, stamp_s: float = 0.0) -> "MovingObstacle":
        if isinstance(o, MovingObstacle):
            return o
        if isinstance(o, (tuple, list, np.ndarray)):
            v = [float(a) for a in o]
            if len(v) not in (5, 6):
                raise ValueError(f"a moving obstacle tuple is (x, y, vx, vy, radius[, speed_sigma]), got {len(v)} values")
            return MovingObstacle(v[0], v[1], v[2], v[3], v[4], v[5] if len(v) == 6 else 0.1, stamp_s=stamp_s)

        def get(*names: str, default: float | None = None) -> float:
            for n in names:
                if hasattr(o, n):
                    return float(getattr(o, n))
            if default is None:
                raise ValueError(f"moving obstacle {o!r} lacks {names[0]}")
            return default

        pos_sigma = get("pos_sigma_m", default=0.05)
        speed_sigma = get("speed_sigma_m_s", "speed_sigma", default=0.1)
        cov = getattr(o, "covariance", None)  # perception's Track: covariance of (x, y, vx, vy)
        if cov is not None:
            try:
                c = np.asarray(cov, dtype=float)
                pos_sigma = math.sqrt(max(float(c[0, 0]), float(c[1, 1]), 0.0))
                if c.shape == (4, 4):  # the velocity's largest 1-sigma in any direction: heading uncertainty too
                    speed_sigma = max(speed_sigma, math.sqrt(max(float(np.linalg.eigvalsh(c[2:, 2:])[-1]), 0.0)))
            except (TypeError, IndexError, ValueError):
                pass
        return MovingObstacle(get("x_m", "x"), get("y_m", "y"), get("vx_m_s", "vx"), get("vy_m_s", "vy"),
                              get("radius_m", "radius", default=0.25), speed_sigma, pos_sigma,
                              get("stamp_s", "t_s", default=stamp_s))


def moving_obstacles_from(items: Sequence[Any] | None, stamp_s: float) -> list[MovingObstacle]:
    """Adapt a list of tracks (see :meth:`MovingObstacle.from_any`); None gives []."""
    return [MovingObstacle.from_any(o, stamp_s) for o in (items or [])]


@dataclass(frozen=True)
class PlanObstacle:
    """Another robot following its own timed plan (its footprint disc, plus a margin)."""

    plan: TimedPlan
    radius_m: float
    margin_m: float = 0.0

    def predict(self, t_s: FloatArray) -> tuple[FloatArray, FloatArray]:
        t = np.asarray(t_s, dtype=float)
        return self.plan.footprint_at(t), np.full(len(t), self.radius_m + self.margin_m)


@dataclass(frozen=True)
class Conflict:
    """First space-time conflict: time (s), index of the obstacle, robot footprint and obstacle
    centres (m), obstacle velocity over the sample (m/s) and the gap there (m, < 0)."""

    t_s: float
    index: int
    robot_xy: tuple[float, float]
    obstacle_xy: tuple[float, float]
    obstacle_v: tuple[float, float]
    gap_m: float


def first_conflict(plan: TimedPlan, obstacles: Sequence[SpaceTimeObstacle], t_from_s: float, t_to_s: float,
                   margin_m: float, dt_s: float = 0.1) -> Conflict | None:
    """Earliest time in [t_from, t_to] where the plan's footprint comes within ``margin_m`` of an
    obstacle's predicted disc; None if clear."""
    if not obstacles or t_to_s <= t_from_s:
        return None
    ts = np.arange(t_from_s, t_to_s + 1e-9, dt_s)
    P = plan.footprint_at(ts)
    r_rob = plan.limits.radius_m
    best: Conflict | None = None
    for i, ob in enumerate(obstacles):
        centre, R = ob.predict(ts)
        gap = np.hypot(P[:, 0] - centre[:, 0], P[:, 1] - centre[:, 1]) - R - r_rob - margin_m
        bad = np.flatnonzero(gap < 0.0)
        if len(bad) and (best is None or ts[bad[0]] < best.t_s):
            k = int(bad[0])
            k2 = min(k + 1, len(ts) - 1)
            k1 = k2 - 1 if k2 > 0 else 0
            vel = (centre[k2] - centre[k1]) / max(ts[k2] - ts[k1], 1e-9) if k2 != k1 else np.zeros(2)
            best = Conflict(float(ts[k]), i, (float(P[k, 0]), float(P[k, 1])), (float(centre[k, 0]), float(centre[k, 1])),
                            (float(vel[0]), float(vel[1])), float(gap[k]))
    return best


def first_blocked_s(plan: TimedPlan, points_xy: FloatArray, s_from_m: float, s_to_m: float, clearance_m: float,
                    ds_m: float = 0.05) -> tuple[float, FloatArray] | None:
    """First arc length in [s_from, s_to] where the footprint disc comes within ``clearance_m`` of a
    point (static obstacle returns, world frame (k, 2) m), and the mask of points that block there
    and further on; None if clear."""
    if len(points_xy) == 0 or s_to_m <= s_from_m:
        return None
    s_end = min(s_to_m, plan.path.length_m)
    if s_end < s_from_m:
        return None
    s = np.append(np.arange(s_from_m, s_end, ds_m), s_end)  # the end itself too (up to ds_m was left out)
    x, y, yaw, _ = plan.path.sample(s)
    off = plan.limits.footprint_offset_m
    cx, cy = x + off * np.cos(yaw), y + off * np.sin(yaw)
    lim = plan.limits.radius_m + clearance_m
    # cheap prefilter: points near the sampled stretch only
    lo = np.array([cx.min() - lim, cy.min() - lim])
    hi = np.array([cx.max() + lim, cy.max() + lim])
    near = np.all((points_xy >= lo) & (points_xy <= hi), axis=1)
    if not near.any():
        return None
    pts = points_xy[near]
    hit = (cx[:, None] - pts[None, :, 0]) ** 2 + (cy[:, None] - pts[None, :, 1]) ** 2 < lim * lim
    rows = np.flatnonzero(hit.any(axis=1))
    if len(rows) == 0:
        return None
    mask = np.zeros(len(points_xy), dtype=bool)
    mask[np.flatnonzero(near)[hit.any(axis=0)]] = True
    return float(s[rows[0]]), mask


def cluster_ordered(points_xy: FloatArray, gap_m: float = 0.3) -> list[FloatArray]:
    """Split points ordered by beam angle into clusters wherever consecutive points are further than
    ``gap_m`` apart; returns index arrays."""
    n = len(points_xy)
    if n == 0:
        return []
    d = np.hypot(*np.diff(points_xy, axis=0).T) if n > 1 else np.zeros(0)
    cuts = np.flatnonzero(d > gap_m) + 1
    return [np.asarray(c) for c in np.split(np.arange(n), cuts)]
