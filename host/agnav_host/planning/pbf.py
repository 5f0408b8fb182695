"""PBF: a potential-field planner on the laser scan (our own implementation).

The goal attracts with a force of constant magnitude ``k_att`` (a unit vector towards it, so the
pull does not fade near obstacles far from the goal); each return closer than ``d0_m`` (clearance,
i.e. range minus robot radius) repels with ``k_rep (1/c - 1/d0) / c^2`` along the line from it to
the robot (Khatib's field). The sum gives the direction to drive; the robot turns towards it with
``yaw_gain`` and drives at a speed falling with the turn and the clearance ahead.

Potential fields stall where the forces cancel (in front of a wall facing the goal) and weave in
corridors; as an escape, when the robot has made less than ``stall_progress_m`` progress towards the
goal for ``stall_s``, a tangential force along the obstacles is added for ``escape_s``: towards the
side their repulsion already pushes the robot to (the nearer end of a wall faced off-centre), or,
facing them square, towards the goal's side. In ref 000 "PBF" names a preference-based fuzzy method; the issue asks for a
potential-field planner under this name, and it plays the same role in the comparison.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..types import DriveCommand, Observation
from .base import RobotSpec, drive_command, free_distances_m, goal_in_robot_frame, local_view

__all__ = ["PbfParams", "PbfPlanner", "field_force"]


@dataclass(frozen=True)
class PbfParams:
    k_att: float = 1.0
    k_rep: float = 0.002  # per return at 1 deg resolution
    d0_m: float = 0.8
    min_clearance_m: float = 0.03
    yaw_gain: float = 2.0
    turn_in_place_rad: float = math.radians(70.0)
    slow_radius_m: float = 0.6
    stall_s: float = 4.0
    stall_progress_m: float = 0.3
    escape_s: float = 5.0
    k_tan: float = 1.5

    def __post_init__(self) -> None:
        if not (self.k_att > 0 and self.k_rep >= 0 and self.d0_m > 0 and self.min_clearance_m > 0):
            raise ValueError("PbfParams: k_att > 0, k_rep >= 0, d0 > 0, min_clearance > 0")
        if not self.slow_radius_m > 0:
            raise ValueError(f"PbfParams.slow_radius_m must be > 0, got {self.slow_radius_m}")


def field_force(xy: np.ndarray, radius_m: float, goal_rad: float, p: PbfParams) -> tuple[float, float, float, float]:
    """(fx, fy) total force and (rx, ry) repulsive part, robot frame, for points ``xy`` (k, 2)."""
    fx, fy = p.k_att * math.cos(goal_rad), p.k_att * math.sin(goal_rad)
    rx = ry = 0.0
    if len(xy):
        d = np.hypot(xy[:, 0], xy[:, 1])
        c = np.maximum(d - radius_m, p.min_clearance_m)
        m = c < p.d0_m
        if m.any():
            c, d, pts = c[m], d[m], xy[m]
            mag = p.k_rep * (1.0 / c - 1.0 / p.d0_m) / (c * c)
            rx = float(-(mag * pts[:, 0] / d).sum())
            ry = float(-(mag * pts[:, 1] / d).sum())
    return fx + rx, fy + ry, rx, ry


class PbfPlanner:
    name = "pbf"
    uses_sonar = False
    params_cls = PbfParams

    def __init__(self, spec: RobotSpec, params: PbfParams | None = None) -> None:
        self.spec = spec
        self.params = params or PbfParams()
        self.reset()

    def reset(self) -> None:
        self._best_d = math.inf
        self._since_progress = 0.0
        self._escape_left = 0.0
        self._escape_sign = 1.0

    def step(self, obs: Observation) -> DriveCommand:
        p, spec = self.params, self.spec
        dt = spec.control_dt_s
        view = local_view(obs, spec)
        d_goal, g_rel = goal_in_robot_frame(obs)
        # points are taken at 1 deg resolution; scale so the field does not depend on beam density
        fx, fy, rx, ry = field_force(view.xy, spec.radius_m, g_rel, p)
        if d_goal < self._best_d - p.stall_progress_m:
            self._best_d = d_goal
            self._since_progress = 0.0
        else:
            self._since_progress += dt
        if self._escape_left <= 0.0 and self._since_progress >= p.stall_s:
            self._escape_left = p.escape_s
            # round the obstacle on the side its field already pushes the robot to (the nearer end of a
            # wall faced off-centre); facing it square, on the goal's side
            n0 = math.hypot(rx, ry)
            if n0 > 1e-9 and abs(ry) > 0.1 * n0:
                self._escape_sign = math.copysign(1.0, ry)
            else:
                self._escape_sign = 1.0 if g_rel >= 0 else -1.0
            self._since_progress = 0.0
            self._best_d = d_goal
        if self._escape_left > 0.0:
            self._escape_left -= dt
            n = math.hypot(rx, ry)
            if n > 1e-9:  # tangent to the repulsion, on the chosen side: the repulsion turned clockwise is
                # its left-hand tangent (an obstacle ahead pushes back, -x; turned clockwise: +y, left)
                fx += p.k_tan * self._escape_sign * (ry / n)
                fy += p.k_tan * self._escape_sign * (-rx / n)
        heading = math.atan2(fy, fx)
        w = p.yaw_gain * heading
        if abs(heading) > p.turn_in_place_rad:
            return drive_command(spec, 0.0, w, view, obs)
        ahead = float(free_distances_m(view.xy, np.array([heading]), spec.radius_m + 0.02, 1.0)[0])
        v = spec.max_speed_m_s * math.cos(heading) ** 2 * min(1.0, d_goal / p.slow_radius_m + 0.2, ahead / 0.6)
        return drive_command(spec, v, w, view, obs)
