"""Synthetic observations for the planning tests (no simulator involved)."""

from __future__ import annotations

import math

import numpy as np

from agnav_host.types import Goal, LaserScan, Observation, Pose2D, SonarFrame

N_BEAMS = 541  # 270 deg at 0.5 deg
A0 = math.radians(-135.0)
INC = math.radians(0.5)


def scan_from_segments(segments: list[tuple[float, float, float, float]], max_range: float = 10.0) -> LaserScan:
    """A scan (sensor at the robot origin, facing +x) of line segments given in the robot frame, m."""
    a = A0 + INC * np.arange(N_BEAMS)
    r = np.full(N_BEAMS, np.nan)
    dx, dy = np.cos(a), np.sin(a)
    for x0, y0, x1, y1 in segments:
        ex, ey = x1 - x0, y1 - y0
        den = dx * ey - dy * ex
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (x0 * ey - y0 * ex) / den
            u = (x0 * dy - y0 * dx) / den
        hit = (np.abs(den) > 1e-12) & (t > 0) & (u >= 0) & (u <= 1) & (t <= max_range)
        r = np.where(hit & ~(r <= t), t, r)
    return LaserScan(A0, INC, r, max_range, 0.0, Pose2D())


def obs_with(scan: LaserScan | None, goal: tuple[float, float], sonar: SonarFrame | None = None, t: float = 0.0,
             speed: float = 0.0) -> Observation:
    return Observation(t, Pose2D(), speed, 0.0, Goal(goal[0], goal[1]), scan, sonar, {})


def empty_scan() -> LaserScan:
    return LaserScan(A0, INC, np.full(N_BEAMS, np.nan), 10.0, 0.0, Pose2D())


def wall_ahead(x: float = 0.7, half: float = 2.0) -> LaserScan:
    return scan_from_segments([(x, -half, x, half)])


def sonar_frame(ranges: list[float] | np.ndarray, t: float = 0.0) -> SonarFrame:
    r = np.asarray(ranges, dtype=float)
    return SonarFrame(t, np.ones(len(r), dtype=bool), 2.0 * r / 343.0 * 1e6, r)
