"""Idealised firmware stand-ins: simple controllers that let a scenario run end to end.

They take an :class:`~agnav_host.types.Observation` and return a :class:`~agnav_host.types.DriveCommand`,
the same shape the host planners use; the controller registry (``agnav_host.planning.registry``) builds the
stand-in ``goal_seek`` by name beside the planners and field controllers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from ..types import DriveCommand, Observation, norm_angle_rad
from ..planning.base import free_distances_m  # one implementation for stand-ins and planners

__all__ = ["Controller", "GoalSeekParams", "GoalSeek", "free_distances_m", "turn_circle_speed_m_s"]


class Controller(Protocol):
    def reset(self) -> None: ...

    def step(self, obs: Observation) -> DriveCommand: ...


@dataclass(frozen=True)
class GoalSeekParams:
    """Gains and limits of the goal-seeking stand-in (SI units)."""

    kinematics: str = "diff_drive"  # or "ackermann"
    radius_m: float = 0.225
    margin_m: float = 0.08
    max_speed_m_s: float = 0.5
    min_speed_m_s: float = 0.0  # Ackermann: the slowest speed the drive can hold
    max_yaw_rate_rad_s: float = 1.2
    wheelbase_m: float = 0.174
    max_steer_rad: float = math.radians(24.6)
    lookahead_m: float = 2.0
    yaw_gain: float = 2.0
    n_directions: int = 73
    hysteresis: float = 0.3  # penalty, m per rad of change from the previous choice
    slow_radius_m: float = 0.6  # slow down when the goal is nearer than this
    footprint_offset_m: float = 0.0  # footprint centre ahead of the reference point (Ackermann: L/2)


class GoalSeek:
    """Reactive goal seeking over the laser scan (a gap-following rule with hysteresis).

    Each step, for directions across +-135 deg (+-90 deg for Ackermann) it computes how far the robot's
    disc could drive straight (:func:`free_distances_m`), and picks the direction with the largest
    progress towards the goal, ``min(free, goal distance, lookahead) * cos(direction - goal bearing)``,
    less a hysteresis penalty for changing its mind; when no direction makes progress it heads for
    the most open one. Within ``slow_radius_m`` of the goal, with the straight way to it clear, it heads
    straight for the goal (the hysteresis would otherwise outweigh the little progress left and let the
    robot drive past a goal with a tight tolerance).
    A differential drive turns on the spot when the chosen direction is more than 60 deg off, and drives
    no faster than lets its turning circle at ``max_yaw_rate_rad_s`` reach the goal
    (:func:`turn_circle_speed_m_s`); an Ackermann robot steers by pure pursuit towards a point on that
    direction.
    """

    def __init__(self, params: GoalSeekParams | None = None) -> None:
        self.params = params or GoalSeekParams()
        self._prev: float = 0.0

    def reset(self) -> None:
        self._prev = 0.0

    def step(self, obs: Observation) -> DriveCommand:
        p = self.params
        pose = obs.pose
        gx, gy = obs.goal.x_m - pose.x_m, obs.goal.y_m - pose.y_m
        d_goal = math.hypot(gx, gy)
        g_rel = norm_angle_rad(math.atan2(gy, gx) - pose.yaw_rad)
        pts = np.zeros((0, 2))
        if obs.scan is not None and obs.scan.pose is not None:
            local = obs.scan.xy()
            sp = obs.scan.pose
            c, s = math.cos(sp.yaw_rad), math.sin(sp.yaw_rad)
            wx = sp.x_m + c * local[:, 0] - s * local[:, 1]
            wy = sp.y_m + s * local[:, 0] + c * local[:, 1]
            c0, s0 = math.cos(pose.yaw_rad), math.sin(pose.yaw_rad)
            dx, dy = wx - pose.x_m, wy - pose.y_m
            pts = np.column_stack((c0 * dx + s0 * dy - p.footprint_offset_m, -s0 * dx + c0 * dy))
        span = math.radians(135.0) if p.kinematics == "diff_drive" else math.radians(90.0)
        dirs = np.linspace(-span, span, p.n_directions)
        dirs = np.unique(np.append(dirs, np.clip(g_rel, -span, span)))
        w = p.radius_m + p.margin_m
        free = free_distances_m(pts, dirs, w, p.lookahead_m)
        need = min(d_goal, p.lookahead_m)
        # progress towards the goal a straight move along each direction would make, m
        progress = np.minimum(free, need) * np.cos(dirs - g_rel) - p.hysteresis * np.abs(dirs - self._prev)
        i_goal = int(np.argmin(np.abs(dirs - g_rel)))
        if d_goal <= p.slow_radius_m and abs(float(dirs[i_goal]) - g_rel) < 1e-9 and free[i_goal] >= d_goal:
            # the goal is near and the way to it is clear: head straight for it. Near the goal the progress
            # any direction can make is smaller than the hysteresis penalty, which would freeze the heading
            # and let the robot drive past (and circle) a goal with a tight tolerance.
            i = i_goal
        elif progress.max() > 0.05:
            i = int(np.argmax(progress))
        else:  # boxed in: head for the most open direction
            i = int(np.argmax(free - p.hysteresis * np.abs(dirs - self._prev)))
        theta = float(dirs[i])
        self._prev = theta
        ahead = float(free_distances_m(pts, np.array([0.0]), w, p.lookahead_m)[0])
        speed_cap = p.max_speed_m_s * min(1.0, free[i] / p.lookahead_m + 0.25, max(d_goal, 0.05) / p.slow_radius_m + 0.2)
        if p.kinematics == "diff_drive":
            yaw_rate = max(-p.max_yaw_rate_rad_s, min(p.max_yaw_rate_rad_s, p.yaw_gain * theta))
            if abs(theta) > math.radians(60.0) or ahead < 0.05:
                return DriveCommand(0.0, yaw_rate)
            # no faster than the turning circle at the yaw-rate limit that still reaches the goal
            v = min(speed_cap * math.cos(theta) ** 2, turn_circle_speed_m_s(p.max_yaw_rate_rad_s, d_goal, g_rel))
            return DriveCommand(v, yaw_rate)
        # Ackermann: pure pursuit to a point at distance ld along theta; no reverse
        ld = max(0.5, min(need, 1.5))
        steer = math.atan2(2.0 * p.wheelbase_m * math.sin(theta), ld)
        steer = max(-p.max_steer_rad, min(p.max_steer_rad, steer))
        if ahead < 0.05 and free[i] < 0.05:
            return DriveCommand(0.0, 0.0, steer)
        v = max(p.min_speed_m_s, speed_cap * (0.5 + 0.5 * math.cos(theta)))
        return DriveCommand(v, 0.0, steer)


def turn_circle_speed_m_s(max_yaw_rate_rad_s: float, d_goal_m: float, bearing_rad: float) -> float:
    """Fastest speed, m/s, whose turning circle at ``max_yaw_rate_rad_s`` still passes through a goal
    ``d_goal_m`` away at ``bearing_rad`` off the heading. The circle tangent to the heading through the
    goal has radius ``d / (2 |sin(bearing)|)``, so ``v <= max_yaw_rate * d / (2 |sin(bearing)|)``; faster,
    the robot circles the goal. Infinite (no cap) when the goal is dead ahead or behind."""
    s = abs(math.sin(bearing_rad))
    if s < 1e-9:
        return math.inf
    return max_yaw_rate_rad_s * d_goal_m / (2.0 * s)

