"""HIM: the human-inspired method of ref 000 (sec. 3.3.1).

1. Check direct path: if a disc of the robot's radius plus ``margin_m`` can drive straight to the
   goal (or ``horizon_m`` towards it), go to the goal.
2. Otherwise build a polar grid from the scan (``bin_rad`` bins holding their nearest return: the
   cell at that range is occupied, nearer cells are free, farther ones unknown; bins without a
   return are open to ``horizon_m``). Between neighbouring bins whose points are farther apart than
   the robot's width plus twice the margin there is a passable gap; the nearer end point, moved
   sideways into the gap by radius + margin, is an escape point S_i.
3. Keep the escape points reachable in a straight line and with clearance, and choose the one with
   the least D_i = L_i + P_i (robot -> S_i plus S_i -> goal, ref 000). Drive to it; on arrival, or as
   soon as the direct path opens, repeat. The chosen point is held in the world frame and only
   replaced when it becomes unreachable or another is shorter by ``switch_gain_m``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..types import DriveCommand, FloatArray, Observation, norm_angle_rad
from .base import LocalView, RobotSpec, drive_command, free_distances_m, goal_in_robot_frame, local_view

__all__ = ["HimParams", "HimPlanner", "escape_points"]


@dataclass(frozen=True)
class HimParams:
    margin_m: float = 0.15  # safety margin added to the robot radius on each side of a gap
    horizon_m: float = 6.0
    bin_rad: float = math.radians(2.0)
    reach_m: float = 0.3  # an escape point counts as reached this close
    switch_gain_m: float = 0.4
    yaw_gain: float = 2.0
    turn_in_place_rad: float = math.radians(60.0)
    slow_radius_m: float = 0.6

    def __post_init__(self) -> None:
        if not (self.margin_m >= 0 and self.horizon_m > 0 and 0 < self.bin_rad < 0.5 and self.reach_m > 0):
            raise ValueError("HimParams: margin >= 0, horizon > 0, 0 < bin_rad < 0.5, reach > 0")


def polar_grid(view: LocalView, bin_rad: float, horizon_m: float) -> tuple[FloatArray, FloatArray]:
    """(bin centre bearings (b,), nearest range per bin (b,)) over [-pi, pi); empty bins read ``horizon_m``."""
    nb = int(round(2.0 * math.pi / bin_rad))
    edges = -math.pi + (2.0 * math.pi / nb) * np.arange(nb + 1)
    centres = 0.5 * (edges[:-1] + edges[1:])
    rng = np.full(nb, horizon_m)
    if len(view.range_m):  # bearings are sorted: reduce runs of equal bin index
        idx = np.clip(((view.bearing_rad + math.pi) * (nb / (2.0 * math.pi))).astype(int), 0, nb - 1)
        starts = np.flatnonzero(np.concatenate(([True], idx[1:] != idx[:-1])))
        rng[idx[starts]] = np.minimum(np.minimum.reduceat(view.range_m, starts), horizon_m)
    return centres, rng


def escape_points(ang: FloatArray, rng: FloatArray, radius_m: float, margin_m: float, horizon_m: float) -> FloatArray:
    """Escape points (k, 2), robot frame, m, from a polar grid (:func:`polar_grid`): nearer gap ends
    shifted into gaps at least ``2 (radius + margin)`` wide (see the module docstring)."""
    px, py = rng * np.cos(ang), rng * np.sin(ang)
    nx_, ny_ = np.concatenate((px[1:], px[:1])), np.concatenate((py[1:], py[:1]))
    rn = np.concatenate((rng[1:], rng[:1]))
    w = radius_m + margin_m
    gap = np.hypot(nx_ - px, ny_ - py) >= 2.0 * w
    near_is_first = rng <= rn
    r_near = np.where(near_is_first, rng, rn)
    ok = gap & (r_near < horizon_m - 1e-9)
    if not ok.any():
        return np.zeros((0, 2))
    # the near end point N moved perpendicular to its ray, towards the farther bin, by 1.05 w and 1.6 w
    a_near = np.where(near_is_first, ang, np.concatenate((ang[1:], ang[:1])))[ok]
    side = np.where(near_is_first, 1.0, -1.0)[ok]  # the farther bin is CCW of N when it comes next
    rn_ok = r_near[ok]
    nxx, nyy = rn_ok * np.cos(a_near), rn_ok * np.sin(a_near)
    ux, uy = -np.sin(a_near) * side, np.cos(a_near) * side
    out = [np.column_stack((nxx + f * w * ux, nyy + f * w * uy)) for f in (1.05, 1.6)]
    return np.concatenate(out)


class HimPlanner:
    """Human-inspired method (ref 000). ``subgoal_world`` is the current escape point or None."""

    name = "him"
    uses_sonar = False
    params_cls = HimParams

    def __init__(self, spec: RobotSpec, params: HimParams | None = None) -> None:
        self.spec = spec
        self.params = params or HimParams()
        self.subgoal_world: tuple[float, float] | None = None

    def reset(self) -> None:
        self.subgoal_world = None

    def _to_robot(self, obs: Observation, x: float, y: float) -> tuple[float, float]:
        c, s = math.cos(obs.pose.yaw_rad), math.sin(obs.pose.yaw_rad)
        dx, dy = x - obs.pose.x_m, y - obs.pose.y_m
        return c * dx + s * dy - self.spec.footprint_offset_m, -s * dx + c * dy

    def _to_world(self, obs: Observation, x: float, y: float) -> tuple[float, float]:
        c, s = math.cos(obs.pose.yaw_rad), math.sin(obs.pose.yaw_rad)
        x += self.spec.footprint_offset_m
        return obs.pose.x_m + c * x - s * y, obs.pose.y_m + s * x + c * y

    def _reachable(self, pts: FloatArray, targets: FloatArray, w_free: float, w_clear: float) -> FloatArray:
        """True where the straight way to each target (t, 2) is free and the target has clearance."""
        d = np.hypot(targets[:, 0], targets[:, 1])
        free = free_distances_m(pts, np.arctan2(targets[:, 1], targets[:, 0]), w_free, float(d.max()) + 1.0 if len(d) else 1.0)
        if len(pts) == 0:
            return free >= d - 0.05
        clear = np.min(np.hypot(targets[:, None, 0] - pts[None, :, 0], targets[:, None, 1] - pts[None, :, 1]), axis=1)
        return (free >= d - 0.05) & (clear >= w_clear)

    def step(self, obs: Observation) -> DriveCommand:
        p, spec = self.params, self.spec
        view = local_view(obs, spec)
        pts = view.xy  # replaced by the polar-grid cells once escape points are needed
        r = spec.radius_m
        d_goal, g_rel = goal_in_robot_frame(obs)
        gx, gy = self._to_robot(obs, obs.goal.x_m, obs.goal.y_m)
        need = min(d_goal, p.horizon_m)
        w_free = r + 0.5 * p.margin_m
        direct = float(free_distances_m(pts, np.array([math.atan2(gy, gx)]), w_free, need)[0]) >= need - 1e-6
        target: tuple[float, float]
        if direct:
            self.subgoal_world = None
            target = (gx, gy)
        else:
            cur = None
            if self.subgoal_world is not None:
                sx, sy = self._to_robot(obs, *self.subgoal_world)
                if math.hypot(sx, sy) < p.reach_m or not self._reachable(pts, np.array([[sx, sy]]), r + 0.03, r)[0]:
                    self.subgoal_world = None
                else:
                    cur = (sx, sy, math.hypot(sx, sy) + math.hypot(gx - sx, gy - sy))
            ang, rng = polar_grid(view, p.bin_rad, p.horizon_m)
            cand = escape_points(ang, rng, r, p.margin_m, p.horizon_m)
            near = rng < p.horizon_m
            pts = np.column_stack((rng[near] * np.cos(ang[near]), rng[near] * np.sin(ang[near])))
            best = None
            if len(cand):
                dist = np.hypot(cand[:, 0], cand[:, 1])
                cand, dist = cand[dist > p.reach_m], dist[dist > p.reach_m]
                dtot = dist + np.hypot(gx - cand[:, 0], gy - cand[:, 1])
                order = np.argsort(dtot)[:12]
                ok = self._reachable(pts, cand[order], r + 0.03, r) if len(order) else np.zeros(0, dtype=bool)
                if ok.any():
                    j = int(order[int(np.argmax(ok))])
                    best = (float(cand[j, 0]), float(cand[j, 1]), float(dtot[j]))
            if best is not None and (cur is None or best[2] < cur[2] - p.switch_gain_m):
                cur = best
                self.subgoal_world = self._to_world(obs, best[0], best[1])
            if cur is None:  # nothing passable in view: turn towards the most open direction
                ang, rng = polar_grid(view, p.bin_rad, p.horizon_m)
                k = int(np.argmax(rng - 0.3 * np.abs(norm_angle_arr(ang - g_rel))))
                return drive_command(spec, 0.0, math.copysign(spec.max_yaw_rate_rad_s * 0.6, float(ang[k])))
            target = (cur[0], cur[1])
        bearing = math.atan2(target[1], target[0])
        dist = math.hypot(*target)
        w = p.yaw_gain * bearing
        if abs(bearing) > p.turn_in_place_rad:
            return drive_command(spec, 0.0, w)
        ahead, nose = (float(x) for x in free_distances_m(view.xy, np.array([bearing, 0.0]), r + 0.02, 1.5))
        v = spec.max_speed_m_s * math.cos(bearing) ** 2 * min(1.0, ahead / 1.0 + 0.2, d_goal / p.slow_radius_m + 0.2, nose / 0.3 + 0.1)
        if self.subgoal_world is not None:
            v = min(v, spec.max_speed_m_s * max(0.4, min(1.0, dist / 0.8)))
        return drive_command(spec, v, w)


def norm_angle_arr(a: FloatArray) -> FloatArray:
    return (a + math.pi) % (2.0 * math.pi) - math.pi
