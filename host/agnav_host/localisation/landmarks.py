"""Surveyed marker posts and how a laser scan sees them.

A post is a vertical pole of known radius at a surveyed position. In a scan it shows up as a short
run of returns on the side facing the sensor. :func:`sight_posts` looks for each post near where the
current pose estimate predicts it, takes the returns within ``gate_m`` of the predicted centre, and
places the centre one radius behind the mean return, along the ray (a good estimate for a pole that
spans only a few beams). The result is the range and bearing of the centre from the sensor: what the
filter corrects with. Posts need not be distinguishable from each other: association is by the
predicted position, so the gate must be smaller than half the spacing of the posts and larger than
the pose error the filter can have (a few decimetres).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from ..types import FloatArray, Pose2D, norm_angle_rad

__all__ = ["LandmarkMap", "PostSighting", "landmarks_from_meta", "sight_posts"]


@dataclass(frozen=True)
class LandmarkMap:
    """Posts: ``xy`` (n, 2) world positions, m; ``radius_m`` (n,) pole radii, m."""

    xy: FloatArray
    radius_m: FloatArray

    def __post_init__(self) -> None:
        if self.xy.ndim != 2 or self.xy.shape[1] != 2 or self.radius_m.shape != (len(self.xy),):
            raise ValueError("LandmarkMap: xy must be (n, 2) and radius_m (n,)")
        if np.any(self.radius_m <= 0):
            raise ValueError("LandmarkMap: post radii must be > 0")

    def __len__(self) -> int:
        return len(self.xy)

    @staticmethod
    def from_rows(rows: Any) -> "LandmarkMap":
        """From rows ``[x_m, y_m, radius_m]``."""
        a = np.asarray(rows, dtype=float).reshape(-1, 3)
        return LandmarkMap(a[:, :2].copy(), a[:, 2].copy())


def landmarks_from_meta(meta: Mapping[str, Any]) -> LandmarkMap | None:
    """The scenario's surveyed posts (``[meta] landmarks = [[x_m, y_m, radius_m], ...]``), or None."""
    rows = meta.get("landmarks")
    if not rows:
        return None
    try:
        return LandmarkMap.from_rows(rows)
    except ValueError as e:
        raise ValueError(f"meta.landmarks must be rows of [x_m, y_m, radius_m]: {e}") from None


@dataclass(frozen=True)
class PostSighting:
    """Post ``index`` seen at ``range_m`` (to its centre) and ``bearing_rad`` (sensor frame, CCW) from
    ``returns`` laser returns."""

    index: int
    range_m: float
    bearing_rad: float
    returns: int


def sight_posts(ranges_m: FloatArray, angles_rad: FloatArray, sensor_pose: Pose2D, posts: LandmarkMap, *,
                range_max_m: float = math.inf, gate_m: float = 0.3, min_returns: int = 2) -> list[PostSighting]:
    """Posts found in a scan taken from (the estimate) ``sensor_pose``; see the module docstring.

    ``ranges_m``/``angles_rad`` (n,): the scan in the sensor frame (NaN/inf/0 = no return). A post is
    skipped when fewer than ``min_returns`` returns fall in its gate, or when a return in the gate is
    clearly nearer the sensor than the post's face (something stands in front of it)."""
    r = np.asarray(ranges_m, dtype=float)
    a = np.asarray(angles_rad, dtype=float)
    ok = np.isfinite(r) & (r > 0.0) & (r < range_max_m)
    if not ok.any() or len(posts) == 0:
        return []
    r, a = r[ok], a[ok]
    wa = a + sensor_pose.yaw_rad
    px = sensor_pose.x_m + r * np.cos(wa)
    py = sensor_pose.y_m + r * np.sin(wa)
    out: list[PostSighting] = []
    for i in range(len(posts)):
        lx, ly = float(posts.xy[i, 0]), float(posts.xy[i, 1])
        rad = float(posts.radius_m[i])
        dx, dy = lx - sensor_pose.x_m, ly - sensor_pose.y_m
        d = math.hypot(dx, dy)
        if d - rad >= range_max_m or d <= rad:
            continue
        near = np.hypot(px - lx, py - ly) < gate_m + rad
        if int(near.sum()) < min_returns:
            continue
        rr, aa = r[near], a[near]
        if float(rr.min()) < d - rad - gate_m:  # occluded by something nearer
            continue
        cx, cy = fit_post_centre(rr * np.cos(aa), rr * np.sin(aa), rad)
        out.append(PostSighting(i, math.hypot(cx, cy), norm_angle_rad(math.atan2(cy, cx)), int(near.sum())))
    return out


def fit_post_centre(x_m: FloatArray, y_m: FloatArray, radius_m: float, iterations: int = 4) -> tuple[float, float]:
    """Centre (sensor frame, m) of a circle of known radius through returns (x, y) seen from the
    origin: start from the mean return pushed one radius further along its ray, then a few
    Gauss-Newton steps on sum (|p - c| - r)^2. A step that moves the centre more than one radius
    from the start is not taken (too few or too noisy returns to trust it)."""
    mx, my = float(np.mean(x_m)), float(np.mean(y_m))
    m = math.hypot(mx, my)
    if m <= 0:
        return mx, my
    c0 = np.array([mx + radius_m * mx / m, my + radius_m * my / m])
    c = c0.copy()
    p = np.column_stack((x_m, y_m))
    if len(p) < 3:
        return float(c[0]), float(c[1])
    for _ in range(iterations):
        d = p - c
        n = np.maximum(np.hypot(d[:, 0], d[:, 1]), 1e-9)
        res = n - radius_m
        J = -d / n[:, None]
        step, *_ = np.linalg.lstsq(J, -res, rcond=None)
        c = c + step
        if float(np.hypot(*(c - c0))) > radius_m:
            return float(c0[0]), float(c0[1])
    return float(c[0]), float(c[1])
