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

Additions for dead ends (ref 000 tests none; D_i itself is unchanged):

* Visited cells: the time spent in each ``cell_m`` cell of the odometry frame is counted; an escape
  point in (or next to) a visited cell costs ``visit_gain_m_s`` metres per second spent there on
  top of D_i (at most ``visit_cap_m``), so a robot that has tried the bottom of a dead end, or
  dithers in front of a wall tip, picks an escape point it has not tried yet.
* A wider polar grid when trapped: the laser covers 180-270 deg, so returns within
  ``memory_radius_m`` are kept in the odometry frame for ``memory_s`` (one per ``memory_cell_m``
  cell); once the robot has spent ``trapped_s`` around its current cell, those now outside the
  laser's field of view fill the grid's blind sector. Without them an escape point behind the robot
  always looks free, and the robot turns to and fro between one ahead and one behind.
* The straight-line test uses every return, not only the grid's cells (a wall seen at a grazing
  angle leaves cells farther apart than the body is wide), and a return the body already grazes
  does not block moving off it (:func:`departing_free_m`).
* The escape point is held, without re-choosing, while the robot turns on the spot towards it.
* With nothing passable in view the robot turns to the direction it can move furthest and creeps
  along it, instead of turning on the spot for ever.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

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
    memory_s: float = 30.0  # returns kept to fill the laser's blind sector (see the module docstring)
    memory_cell_m: float = 0.1
    memory_radius_m: float = 3.0
    trapped_s: float = 4.0  # time spent around the robot's cell that counts as trapped
    cell_m: float = 0.4  # visited-cells memory (see the module docstring)
    visit_gain_m_s: float = 0.5
    visit_cap_m: float = 8.0

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

        self._visited: dict[tuple[int, int], float] = {}
        self._around: dict[tuple[int, int], float] = {}  # the same summed over each cell's 3 x 3 block
        self._mem_xy = np.zeros((0, 2))
        self._mem_t = np.zeros(0)
        self._steps = 0

    def reset(self) -> None:
        self.subgoal_world = None
        self._visited = {}
        self._around = {}
        self._mem_xy = np.zeros((0, 2))  # remembered returns, odometry frame, m
        self._mem_t = np.zeros(0)  # when each was last seen, s
        self._steps = 0

    def _wide_view(self, obs: Observation, view: LocalView, trapped: bool) -> LocalView:
        """``view``, and when ``trapped`` the remembered returns that lie outside the laser's field
        of view now; the memory is updated with ``view``'s returns (the latest sighting of a cell
        wins; cells beyond ``memory_radius_m`` are dropped)."""
        p = self.params
        c, s = math.cos(obs.pose.yaw_rad), math.sin(obs.pose.yaw_rad)
        off = self.spec.footprint_offset_m
        extra = np.zeros((0, 2))
        if trapped and p.memory_s > 0.0 and len(self._mem_xy):
            dx, dy = self._mem_xy[:, 0] - obs.pose.x_m, self._mem_xy[:, 1] - obs.pose.y_m
            lx, ly = c * dx + s * dy - off, -s * dx + c * dy
            blind = np.ones(len(lx), dtype=bool)
            scan = obs.scan
            if scan is not None and len(scan.ranges_m):
                sp = scan.pose if scan.pose is not None else obs.pose
                mx = c * (sp.x_m - obs.pose.x_m) + s * (sp.y_m - obs.pose.y_m) - off
                my = -s * (sp.x_m - obs.pose.x_m) + c * (sp.y_m - obs.pose.y_m)
                dyaw = norm_angle_rad(sp.yaw_rad - obs.pose.yaw_rad)
                a = norm_angle_rad(np.arctan2(ly - my, lx - mx) - dyaw)
                # outside the beams' span, measured from the first beam in the laser's own sense of turn
                # (any start angle: a full-circle laser's 0..2 pi too)
                span = abs(scan.angle_increment_rad) * (len(scan.ranges_m) - 1)
                blind = scan.from_first_beam_rad(a) > span + 1e-9
            extra = np.column_stack((lx[blind], ly[blind]))
        self._steps += 1
        if p.memory_s > 0.0 and self._steps % 3 == 1:  # every third scan is plenty
            wx = obs.pose.x_m + c * (view.xy[:, 0] + off) - s * view.xy[:, 1]
            wy = obs.pose.y_m + s * (view.xy[:, 0] + off) + c * view.xy[:, 1]
            near = np.hypot(view.xy[:, 0], view.xy[:, 1]) < p.memory_radius_m
            keep = (obs.t_s - self._mem_t <= p.memory_s) & (
                np.hypot(self._mem_xy[:, 0] - obs.pose.x_m, self._mem_xy[:, 1] - obs.pose.y_m) < p.memory_radius_m)
            xy = np.concatenate((np.column_stack((wx[near], wy[near])), self._mem_xy[keep]))
            t = np.concatenate((np.full(int(near.sum()), obs.t_s), self._mem_t[keep]))
            key = np.floor(xy / p.memory_cell_m).astype(np.int64)
            _, first = np.unique(key[:, 0] * 2_000_003 + key[:, 1], return_index=True)  # newest first
            self._mem_xy, self._mem_t = xy[first], t[first]
        if not len(extra):
            return view
        xy = np.concatenate((view.xy, extra))
        rng = np.hypot(xy[:, 0], xy[:, 1])
        bear = np.arctan2(xy[:, 1], xy[:, 0])
        order = np.argsort(bear, kind="stable")
        return LocalView(xy[order], rng[order], bear[order], view.no_return_rad)

    def _cell(self, x: float, y: float) -> tuple[int, int]:
        c = self.params.cell_m
        return (int(math.floor(x / c)), int(math.floor(y / c)))

    def _visit(self, cell: tuple[int, int], dt_s: float) -> None:
        """Count ``dt_s`` spent in ``cell``."""
        self._visited[cell] = self._visited.get(cell, 0.0) + dt_s
        for di in (-1, 0, 1):
            for dj in (-1, 0, 1):
                k = (cell[0] + di, cell[1] + dj)
                self._around[k] = self._around.get(k, 0.0) + dt_s

    def _time_here(self, cell: tuple[int, int]) -> float:
        """Time spent in ``cell`` and its 8 neighbours, s."""
        return self._around.get(cell, 0.0)

    def _visit_cost(self, obs: Observation, pts: FloatArray) -> FloatArray:
        """Visited-cells cost (k,) of robot-frame points (k, 2), m: the time spent in each point's
        cell and its 8 neighbours (neighbours count half), times ``visit_gain_m_s``, capped."""
        p = self.params
        out = np.zeros(len(pts))
        if not self._visited or not len(pts):
            return out
        c, s = math.cos(obs.pose.yaw_rad), math.sin(obs.pose.yaw_rad)
        x = pts[:, 0] + self.spec.footprint_offset_m
        ci = np.floor((obs.pose.x_m + c * x - s * pts[:, 1]) / p.cell_m).astype(int)
        cj = np.floor((obs.pose.y_m + s * x + c * pts[:, 1]) / p.cell_m).astype(int)
        get, around = self._visited.get, self._around.get
        for k in range(len(pts)):
            key = (int(ci[k]), int(cj[k]))
            out[k] = min(p.visit_gain_m_s * (0.5 * around(key, 0.0) + 0.5 * get(key, 0.0)), p.visit_cap_m)
        return out

    def _to_robot(self, obs: Observation, x: float, y: float) -> tuple[float, float]:
        c, s = math.cos(obs.pose.yaw_rad), math.sin(obs.pose.yaw_rad)
        dx, dy = x - obs.pose.x_m, y - obs.pose.y_m
        return c * dx + s * dy - self.spec.footprint_offset_m, -s * dx + c * dy

    def _to_world(self, obs: Observation, x: float, y: float) -> tuple[float, float]:
        c, s = math.cos(obs.pose.yaw_rad), math.sin(obs.pose.yaw_rad)
        x += self.spec.footprint_offset_m
        return obs.pose.x_m + c * x - s * y, obs.pose.y_m + s * x + c * y

    def _reachable(self, pts: FloatArray, targets: FloatArray, w_free: float, w_clear: float) -> npt.NDArray[np.bool_]:
        """True where the straight way to each target (t, 2) is free and the target has clearance."""
        d = np.hypot(targets[:, 0], targets[:, 1])
        # a return the body already grazes does not block moving off it (pressed against a wall tip,
        # the plain test would rule out every escape point)
        free = departing_free_m(pts, np.arctan2(targets[:, 1], targets[:, 0]), w_free, float(d.max()) + 1.0 if len(d) else 1.0)
        if len(pts) == 0:
            return free >= d - 0.05
        clear = np.min(np.hypot(targets[:, None, 0] - pts[None, :, 0], targets[:, None, 1] - pts[None, :, 1]), axis=1)
        reachable: npt.NDArray[np.bool_] = (free >= d - 0.05) & (clear >= w_clear)
        return reachable

    def step(self, obs: Observation) -> DriveCommand:
        p, spec = self.params, self.spec
        cell = self._cell(obs.pose.x_m, obs.pose.y_m)
        self._visit(cell, spec.control_dt_s)
        view = self._wide_view(obs, local_view(obs, spec), self._time_here(cell) >= p.trapped_s)
        pts = view.xy
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
            held: tuple[float, float] | None = None  # the current escape point, robot frame
            if self.subgoal_world is not None:
                sx, sy = self._to_robot(obs, *self.subgoal_world)
                if abs(math.atan2(sy, sx)) > p.turn_in_place_rad and math.hypot(sx, sy) >= p.reach_m:
                    # still turning towards the chosen escape point: hold it (the laser's view swings
                    # with the body, and a re-choice at every step makes the robot turn to and fro)
                    return drive_command(spec, 0.0, p.yaw_gain * math.atan2(sy, sx), view, obs)
                if math.hypot(sx, sy) < p.reach_m:
                    self.subgoal_world = None
                else:
                    held = (sx, sy)
            ang, rng = polar_grid(view, p.bin_rad, p.horizon_m)
            cand = escape_points(ang, rng, r, p.margin_m, p.horizon_m)
            order = np.zeros(0, dtype=int)
            dtot = np.zeros(0)
            if len(cand):
                dist = np.hypot(cand[:, 0], cand[:, 1])
                cand, dist = cand[dist > p.reach_m], dist[dist > p.reach_m]
                dtot = dist + np.hypot(gx - cand[:, 0], gy - cand[:, 1])
                first = np.argsort(dtot)[:24]
                dtot[first] += self._visit_cost(obs, cand[first])
                order = first[np.argsort(dtot[first])][:12]
            # one straight-line test for the held point and the candidates (on every return, not
            # only the grid's cells: a wall seen at a grazing angle leaves cells farther apart than
            # the body is wide)
            targets = cand[order] if held is None else np.vstack((np.array([held]), cand[order]))
            ok = self._reachable(pts, targets, r + 0.03, r) if len(targets) else np.zeros(0, dtype=bool)
            if held is not None:
                if ok[0]:
                    sx, sy = held
                    cur = (sx, sy, math.hypot(sx, sy) + math.hypot(gx - sx, gy - sy)
                           + float(self._visit_cost(obs, np.array([held]))[0]))
                else:
                    self.subgoal_world = None
                ok = ok[1:]
            best = None
            if ok.any():
                j = int(order[int(np.argmax(ok))])
                best = (float(cand[j, 0]), float(cand[j, 1]), float(dtot[j]))
            if best is not None and (cur is None or best[2] < cur[2] - p.switch_gain_m):
                cur = best
                self.subgoal_world = self._to_world(obs, best[0], best[1])
            if cur is None:  # nothing passable in view: head for the most open direction
                # (pressed against a wall tip, every escape point fails the margin test; the way
                # out is the direction the body can move furthest, returns behind it not blocking)
                dirs = np.linspace(-math.pi, math.pi, 72, endpoint=False)
                free = departing_free_m(view.xy, dirs, r + 0.03, 1.0)
                k = int(np.argmax(free - 0.3 * np.abs(norm_angle_rad(dirs - g_rel))))
                a = float(dirs[k])
                if abs(a) > math.radians(10.0):
                    return drive_command(spec, 0.0, math.copysign(spec.max_yaw_rate_rad_s * 0.6, a), view, obs)
                v = 0.3 * spec.max_speed_m_s * min(1.0, free[k] / 0.5) if free[k] > 0.2 else 0.0
                return drive_command(spec, v, p.yaw_gain * a, view, obs)
            target = (cur[0], cur[1])
        bearing = math.atan2(target[1], target[0])
        target_m = math.hypot(*target)
        w = p.yaw_gain * bearing
        if abs(bearing) > p.turn_in_place_rad:
            return drive_command(spec, 0.0, w, view, obs)
        ahead, nose = (float(x) for x in free_distances_m(view.xy, np.array([bearing, 0.0]), r + 0.02, 1.5))
        v = spec.max_speed_m_s * math.cos(bearing) ** 2 * min(1.0, ahead / 1.0 + 0.2, d_goal / p.slow_radius_m + 0.2, nose / 0.3 + 0.1)
        if self.subgoal_world is not None:
            v = min(v, spec.max_speed_m_s * max(0.4, min(1.0, target_m / 0.8)))
        return drive_command(spec, v, w, view, obs)




def departing_free_m(points_xy: FloatArray, directions_rad: FloatArray, half_width_m: float, horizon_m: float) -> FloatArray:
    """Like :func:`~agnav_host.planning.base.free_distances_m`, but a return the disc already
    overlaps only blocks the directions that close in on it (moving off a wall is free)."""
    d = np.asarray(directions_rad, dtype=float)
    out = np.full(len(d), horizon_m)
    near = points_xy[np.hypot(points_xy[:, 0], points_xy[:, 1]) < horizon_m + half_width_m] if len(points_xy) else points_xy
    if len(near) == 0:
        return out
    ux, uy = np.cos(d)[:, None], np.sin(d)[:, None]
    px, py = near[None, :, 0], near[None, :, 1]
    along = px * ux + py * uy
    lat = np.abs(px * uy - py * ux)
    dist = along - np.sqrt(np.maximum(half_width_m**2 - lat**2, 0.0))
    dist = np.where((lat < half_width_m) & (along > 0.0), np.maximum(dist, 0.0), np.inf)
    free: FloatArray = np.minimum(out, dist.min(axis=1))
    return free
