"""VFH: a vector field histogram planner (Borenstein and Koren's method, our own implementation).

1. Polar histogram: ``n_sectors`` sectors round the robot. Every return within ``window_m`` has a
   magnitude ``a - b d`` (1 at the robot, 0 at the window edge) and, enlarged by the robot radius
   plus ``margin_m`` (VFH+ style), covers every sector within ``asin((r + margin) / d)`` of its
   bearing; a sector holds the largest magnitude that covers it (so the value does not depend on the
   beam density), then the histogram is smoothed over ``smooth`` neighbours each side.
2. Binary histogram with hysteresis: blocked above ``tau_high``, free below ``tau_low``, else as
   in the previous step.
3. Valleys are runs of free sectors. The candidate directions are: the goal direction if it lies
   in a valley; the middle of a narrow valley (fewer than ``s_max`` sectors); and, in a wide one,
   the direction ``s_max / 2`` sectors inside each border. The cost of a candidate is
   ``mu1 |c - goal| + mu2 |c - heading| + mu3 |c - previous|`` (VFH+); the cheapest wins.
   When the straight way to the goal is free within the window, the goal direction is taken as is.
4. Speed falls with the smoothed density ahead and with the turn; more than ``turn_in_place_rad``
   off the nose, a differential drive turns on the spot.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..types import DriveCommand, FloatArray, Observation, norm_angle_rad
from .base import RobotSpec, drive_command, free_distances_m, goal_in_robot_frame, local_view

__all__ = ["VfhParams", "VfhPlanner", "polar_histogram", "find_valleys", "choose_direction"]


@dataclass(frozen=True)
class VfhParams:
    n_sectors: int = 72
    window_m: float = 2.5
    margin_m: float = 0.1
    smooth: int = 2
    tau_low: float = 0.25
    tau_high: float = 0.45
    s_max: int = 12
    mu1: float = 5.0
    mu2: float = 2.0
    mu3: float = 2.0
    yaw_gain: float = 2.0
    turn_in_place_rad: float = math.radians(60.0)
    slow_radius_m: float = 0.6
    resolution_rad: float = math.radians(2.0)  # laser returns thinned to the nearest per 2 deg

    def __post_init__(self) -> None:
        if not (8 <= self.n_sectors <= 720 and self.window_m > 0 and 0 <= self.tau_low <= self.tau_high and self.s_max >= 1):
            raise ValueError("VfhParams: need 8 <= n_sectors <= 720, window > 0, 0 <= tau_low <= tau_high, s_max >= 1")
        if not 0 <= self.smooth < self.n_sectors // 2:
            raise ValueError(f"VfhParams.smooth must be in [0, n_sectors / 2), got {self.smooth} for {self.n_sectors} sectors")
        if not self.slow_radius_m > 0:
            raise ValueError(f"VfhParams.slow_radius_m must be > 0, got {self.slow_radius_m}")


def polar_histogram(xy: FloatArray, n: int, window_m: float, enlarge_m: float, smooth: int) -> FloatArray:
    """Smoothed polar obstacle density (n,), sector k centred at ``-pi + (k + 0.5) 2 pi / n``."""
    d = np.hypot(xy[:, 0], xy[:, 1])
    m = d < window_m
    h = np.zeros(n)
    if m.any():
        d, b = d[m], np.arctan2(xy[m, 1], xy[m, 0])
        mag = 1.0 - d / window_m
        gamma = np.arcsin(np.minimum(1.0, enlarge_m / np.maximum(d, 1e-6)))
        width = 2.0 * math.pi / n
        centres = -math.pi + width * (np.arange(n) + 0.5)
        diff = np.abs(norm_angle_rad(centres[None, :] - b[:, None]))
        cover = diff <= (gamma[:, None] + 0.5 * width)
        h = np.max(np.where(cover, mag[:, None], 0.0), axis=0)
    if smooth > 0:
        k = np.concatenate((np.arange(1, smooth + 2), np.arange(smooth, 0, -1))).astype(float)
        ext = np.concatenate((h[-smooth:], h, h[:smooth]))
        h = np.convolve(ext, k / k.sum(), mode="valid")
    return h


def find_valleys(free: np.ndarray) -> list[tuple[int, int]]:
    """Runs of free sectors as (start, length), circular; [(0, n)] when all are free."""
    n = len(free)
    if free.all():
        return [(0, n)]
    if not free.any():
        return []
    start = int(np.argmin(free))  # a blocked sector: walk from there so no run wraps unseen
    out: list[tuple[int, int]] = []
    k, run_start, run = 0, -1, 0
    while k < n:
        i = (start + k) % n
        if free[i]:
            if run == 0:
                run_start = i
            run += 1
        elif run:
            out.append((run_start, run))
            run = 0
        k += 1
    if run:
        out.append((run_start, run))
    return out


def _ang_dist(a: float, b: float) -> float:
    return abs(norm_angle_rad(a - b))


def choose_direction(valleys: list[tuple[int, int]], n: int, goal_rad: float, prev_rad: float, p: VfhParams) -> float | None:
    """The VFH+ steering direction (rad, robot frame) among the valleys; None when there is none."""
    width = 2.0 * math.pi / n

    def centre(k: float) -> float:
        return -math.pi + width * (k % n + 0.5)

    cands: list[float] = []
    for s, L in valleys:
        if L == n:
            return goal_rad
        # goal inside this valley?
        kg = int((goal_rad + math.pi) // width) % n
        if (kg - s) % n < L and (kg - s) % n >= min(p.s_max // 2, L // 2) and (s + L - 1 - kg) % n >= min(p.s_max // 2, L // 2):
            cands.append(goal_rad)
        if L < p.s_max:
            cands.append(centre(s + (L - 1) / 2.0))
        else:
            cands.append(centre(s + p.s_max / 2.0))
            cands.append(centre(s + L - 1 - p.s_max / 2.0))
    if not cands:
        return None
    costs = [p.mu1 * _ang_dist(c, goal_rad) + p.mu2 * abs(c) + p.mu3 * _ang_dist(c, prev_rad) for c in cands]
    return cands[int(np.argmin(costs))]


class VfhPlanner:
    """Vector field histogram planner; ``histogram`` keeps the latest smoothed density."""

    name = "vfh"
    uses_sonar = False
    params_cls = VfhParams

    def __init__(self, spec: RobotSpec, params: VfhParams | None = None) -> None:
        self.spec = spec
        self.params = params or VfhParams()
        self.histogram: FloatArray = np.zeros(self.params.n_sectors)
        self._blocked = np.zeros(self.params.n_sectors, dtype=bool)
        self._prev = 0.0

    def reset(self) -> None:
        self.histogram = np.zeros(self.params.n_sectors)
        self._blocked[:] = False
        self._prev = 0.0

    def step(self, obs: Observation) -> DriveCommand:
        p, spec = self.params, self.spec
        view = local_view(obs, spec, resolution_rad=p.resolution_rad)
        d_goal, g_rel = goal_in_robot_frame(obs)
        h = polar_histogram(view.xy, p.n_sectors, p.window_m, spec.radius_m + p.margin_m, p.smooth)
        self.histogram = h
        self._blocked = np.where(h > p.tau_high, True, np.where(h < p.tau_low, False, self._blocked))
        direct = float(free_distances_m(view.xy, np.array([g_rel]), spec.radius_m + p.margin_m, min(d_goal, p.window_m))[0])
        if direct >= min(d_goal, p.window_m) - 1e-6:
            steer: float | None = g_rel  # the straight way to the goal is free within the window
        else:
            steer = choose_direction(find_valleys(~self._blocked), p.n_sectors, g_rel, self._prev, p)
        if steer is None:  # boxed in: turn towards the least dense sector
            width = 2.0 * math.pi / p.n_sectors
            steer = -math.pi + width * (int(np.argmin(h)) + 0.5)
            self._prev = steer
            return drive_command(spec, 0.0, math.copysign(0.6 * spec.max_yaw_rate_rad_s, steer), view, obs)
        self._prev = steer
        w = p.yaw_gain * steer
        if abs(steer) > p.turn_in_place_rad:
            return drive_command(spec, 0.0, w, view, obs)
        k0 = int((0.0 + math.pi) // (2.0 * math.pi / p.n_sectors)) % p.n_sectors
        h_ahead = min(1.0, float(h[k0]) / max(p.tau_high, 1e-6))
        ahead = float(free_distances_m(view.xy, np.array([steer]), spec.radius_m + 0.02, 1.0)[0])
        v = spec.max_speed_m_s * (1.0 - 0.7 * h_ahead) * max(0.0, math.cos(steer)) ** 2
        v *= min(1.0, d_goal / p.slow_radius_m + 0.2, ahead / 0.6)
        return drive_command(spec, v, w, view, obs)
