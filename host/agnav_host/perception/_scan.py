"""Scan handling: clean a :class:`~agnav_host.types.LaserScan` and turn it into points.

A beam is dropped when its range is NaN, inf or 0 (no return), outside ``[min_range_m, max_range_m]``,
or a mixed pixel. A mixed pixel is a beam that straddled an edge and reports a blend of the
foreground and background ranges: its range lies strictly between its two neighbours' ranges, its
point is more than ``mixed_jump_m`` from both neighbouring points, and on at least one side the range
then levels off (the next step out is less than half the step into the beam: the foreground or the
background surface). The last test keeps a smooth surface seen at a grazing angle (a wall, a hedge
face far ahead), whose ranges climb steadily from beam to beam with points as far apart as an edge's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from ..types import FloatArray, LaserScan, Pose2D, ScanXY

__all__ = ["ScanParams", "ScanPoints", "check_scan", "points_from_scan", "mixed_pixel_mask", "xy_robot_from_sensor"]


@dataclass(frozen=True)
class ScanParams:
    """Which returns to keep. Ranges in m."""

    min_range_m: float = 0.05
    max_range_m: float = math.inf  # also capped by the scan's own range_max_m
    mixed_jump_m: float = 0.15
    drop_mixed: bool = True

    def __post_init__(self) -> None:
        if not (0.0 <= self.min_range_m < self.max_range_m):
            raise ValueError(f"ScanParams: need 0 <= min_range_m < max_range_m, got {self.min_range_m}, {self.max_range_m}")
        if not self.mixed_jump_m > 0:
            raise ValueError(f"ScanParams.mixed_jump_m must be > 0, got {self.mixed_jump_m}")


@dataclass(frozen=True)
class ScanPoints:
    """The kept returns of one scan, in beam order.

    ``index`` (k,) beam indices into the original scan; ``angles_rad`` (k,) and ``ranges_m`` (k,) in
    the sensor frame; ``xy`` (k, 2) points in the robot frame (through ``mount``), m; ``stamp_s`` s.
    """

    index: npt.NDArray[np.intp]
    angles_rad: FloatArray
    ranges_m: FloatArray
    xy: ScanXY
    stamp_s: float
    mount: Pose2D
    angle_increment_rad: float = math.radians(1.0)

    def __len__(self) -> int:
        return len(self.index)


def mixed_pixel_mask(angles_rad: FloatArray, ranges_m: FloatArray, jump_m: float) -> npt.NDArray[np.bool_]:
    """True for beams that look like mixed pixels (see the module docstring). Inputs (n,); NaN ok."""
    n = len(ranges_m)
    out = np.zeros(n, dtype=bool)
    if n < 3:
        return out
    r = np.where(np.isfinite(ranges_m) & (ranges_m > 0), ranges_m, np.nan)
    x, y = r * np.cos(angles_rad), r * np.sin(angles_rad)
    with np.errstate(invalid="ignore"):
        d_prev = np.hypot(x[1:-1] - x[:-2], y[1:-1] - y[:-2])
        d_next = np.hypot(x[1:-1] - x[2:], y[1:-1] - y[2:])
        between = (r[1:-1] - r[:-2]) * (r[2:] - r[1:-1]) > 0
        # steps into the beam from each side, and the next step out on that side (unknown at the scan's
        # ends and next to a beam without a return: then that side does not count as level)
        d_in_prev, d_in_next = np.abs(r[1:-1] - r[:-2]), np.abs(r[2:] - r[1:-1])
        d_out_prev = np.abs(np.concatenate(([np.nan], r[1:-2] - r[:-3])))
        d_out_next = np.abs(np.concatenate((r[3:] - r[2:-1], [np.nan])))
        level = (d_out_prev < 0.5 * d_in_prev) | (d_out_next < 0.5 * d_in_next)
        out[1:-1] = between & (d_prev > jump_m) & (d_next > jump_m) & level
    return out


def xy_robot_from_sensor(xy_sensor: ScanXY, mount: Pose2D) -> ScanXY:
    """Points (k, 2) from the sensor frame to the robot frame; ``mount`` is the sensor pose on the robot. m."""
    c, s = math.cos(mount.yaw_rad), math.sin(mount.yaw_rad)
    x, y = xy_sensor[:, 0], xy_sensor[:, 1]
    return np.column_stack((mount.x_m + c * x - s * y, mount.y_m + s * x + c * y))


def check_scan(scan: LaserScan, params: ScanParams | None = None) -> npt.NDArray[np.bool_]:
    """Mask (n,) of the beams worth using (see the module docstring)."""
    p = params or ScanParams()
    r = np.asarray(scan.ranges_m, dtype=float)
    if r.ndim != 1:
        raise ValueError(f"scan ranges must be one-dimensional, got shape {r.shape}")
    hi = min(p.max_range_m, scan.range_max_m)
    with np.errstate(invalid="ignore"):
        keep: npt.NDArray[np.bool_] = np.isfinite(r) & (r > 0.0) & (r >= p.min_range_m) & (r <= hi)
    if p.drop_mixed:
        keep &= ~mixed_pixel_mask(scan.angles_rad, np.where(keep, r, np.nan), p.mixed_jump_m)
    return keep


def points_from_scan(scan: LaserScan, mount: Pose2D | None = None, params: ScanParams | None = None) -> ScanPoints:
    """Clean ``scan`` and convert the kept returns to robot-frame points (``mount``: sensor pose on the robot)."""
    m = mount or Pose2D()
    keep = check_scan(scan, params)
    idx = np.nonzero(keep)[0]
    a = scan.angles_rad[idx]
    r = np.asarray(scan.ranges_m, dtype=float)[idx]
    xy_s = np.column_stack((r * np.cos(a), r * np.sin(a)))
    xy = xy_robot_from_sensor(xy_s, m) if (m.x_m or m.y_m or m.yaw_rad) else xy_s
    return ScanPoints(idx, a, r, xy, float(scan.stamp_s), m, float(scan.angle_increment_rad))
