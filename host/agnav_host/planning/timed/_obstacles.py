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
from typing import TYPE_CHECKING, Any, Protocol, Sequence

import numpy as np
import numpy.typing as npt

from ...types import FloatArray
from ._plan import TimedLimits, TimedPlan

if TYPE_CHECKING:
    from ._path import GeoPath

__all__ = [
    "deviation_point",
    "MovingObstacle",
    "PlanObstacle",
    "SpaceTimeObstacle",
    "Conflict",
    "first_conflict",
    "first_blocked_s",
    "cluster_ordered",
    "cluster_labels",
    "path_prefix_blocked",
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
    px, py = plan.footprint_xy(ts)
    r_rob = plan.limits.radius_m
    best: Conflict | None = None
    for i, ob in enumerate(obstacles):
        if isinstance(ob, MovingObstacle):  # MovingObstacle.predict written out, without stacking the centres
            dt = np.maximum(ts - ob.stamp_s, 0.0)
            ox, oy = ob.x_m + ob.vx_m_s * dt, ob.y_m + ob.vy_m_s * dt
            R = ob.radius_m + ob.k_sigma * ob.pos_sigma_m + np.minimum(ob.k_sigma * ob.speed_sigma_m_s * dt, ob.max_growth_m)
        else:
            centre, R = ob.predict(ts)
            ox, oy = centre[:, 0], centre[:, 1]
        gap = np.hypot(px - ox, py - oy) - R - r_rob - margin_m
        neg = gap < 0.0
        if not neg.any():
            continue
        k = int(neg.argmax())
        if best is None or ts[k] < best.t_s:
            k2 = min(k + 1, len(ts) - 1)
            k1 = k2 - 1 if k2 > 0 else 0
            if k2 != k1:
                w = max(ts[k2] - ts[k1], 1e-9)
                vel = ((ox[k2] - ox[k1]) / w, (oy[k2] - oy[k1]) / w)
            else:
                vel = (0.0, 0.0)
            best = Conflict(float(ts[k]), i, (float(px[k]), float(py[k])), (float(ox[k]), float(oy[k])),
                            (float(vel[0]), float(vel[1])), float(gap[k]))
    return best


#: a point set up to this size is checked against every footprint sample directly (no bounding-box prefilter)
_DIRECT_POINTS = 48


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
    s = np.concatenate((np.arange(s_from_m, s_end, ds_m), (s_end,)))  # the end itself too (up to ds_m was left out)
    x, y, yaw = plan.path.sample_xy_yaw(s)
    off = plan.limits.footprint_offset_m
    cx, cy = x + off * np.cos(yaw), y + off * np.sin(yaw)
    lim = plan.limits.radius_m + clearance_m
    if len(points_xy) <= _DIRECT_POINTS:  # a point outside the samples' box grown by lim cannot be within lim
        near = None
        pts = points_xy
    else:  # cheap prefilter: points near the sampled stretch only
        px, py = points_xy[:, 0], points_xy[:, 1]
        near = (px >= cx.min() - lim) & (px <= cx.max() + lim) & (py >= cy.min() - lim) & (py <= cy.max() + lim)
        if not near.any():
            return None
        pts = points_xy[near]
    hit = (cx[:, None] - pts[None, :, 0]) ** 2 + (cy[:, None] - pts[None, :, 1]) ** 2 < lim * lim
    rows = hit.any(axis=1)
    if not rows.any():
        return None
    mask = np.zeros(len(points_xy), dtype=bool)
    if near is None:
        mask |= hit.any(axis=0)
    else:
        mask[np.flatnonzero(near)[hit.any(axis=0)]] = True
    return float(s[int(rows.argmax())]), mask


def path_prefix_blocked(path: "GeoPath", limits: "TimedLimits", points_xy: FloatArray, s_to_m: float, clearance_m: float,
                        ds_m: float = 0.05) -> bool:
    """True when the footprint disc along ``path`` comes within ``clearance_m`` of a point at one of
    s = 0, ds, 2 ds, ... below min(``s_to_m``, its length): samples that :func:`first_blocked_s` from 0 also
    takes, at the same places, along any longer path that begins with this one (a deviation's first leg), so
    such a path is blocked too."""
    if len(points_xy) == 0:
        return False
    s = np.arange(0.0, min(s_to_m, path.length_m), ds_m)
    if len(s) == 0:
        return False
    x, y, yaw = path.sample_xy_yaw(s)
    off = limits.footprint_offset_m
    cx, cy = x + off * np.cos(yaw), y + off * np.sin(yaw)
    lim = limits.radius_m + clearance_m
    pts = points_xy
    if len(pts) > _DIRECT_POINTS:
        px, py = pts[:, 0], pts[:, 1]
        pts = pts[(px >= cx.min() - lim) & (px <= cx.max() + lim) & (py >= cy.min() - lim) & (py <= cy.max() + lim)]
    return bool(((cx[:, None] - pts[None, :, 0]) ** 2 + (cy[:, None] - pts[None, :, 1]) ** 2 < lim * lim).any())


def cluster_ordered(points_xy: FloatArray, gap_m: float = 0.3) -> list[FloatArray]:
    """Split points ordered by beam angle into clusters wherever consecutive points are further than
    ``gap_m`` apart; returns index arrays."""
    n = len(points_xy)
    if n == 0:
        return []
    d = np.hypot(*np.diff(points_xy, axis=0).T) if n > 1 else np.zeros(0)
    cuts = np.flatnonzero(d > gap_m) + 1
    return [np.asarray(c) for c in np.split(np.arange(n), cuts)]


def cluster_labels(points_xy: FloatArray, gap_m: float = 0.3) -> npt.NDArray[np.intp]:
    """(n,) cluster number of each point, points ordered by beam angle: the clusters of
    :func:`cluster_ordered` numbered 0, 1, ... in order, without building one array per cluster."""
    if len(points_xy) < 2:
        return np.zeros(len(points_xy), dtype=np.intp)
    d = points_xy[1:] - points_xy[:-1]
    labels = np.zeros(len(points_xy), dtype=np.intp)
    np.cumsum(np.hypot(d[:, 0], d[:, 1]) > gap_m, out=labels[1:])
    return labels
