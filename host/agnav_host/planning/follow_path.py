"""Path following controller of ref 000 (secs. 4.4 / 5.4.2), and the ``follow-path`` planner.

Ref 000 lists the gains (k1 = 0.85, k2 = 0.02 m, k3 = 0.3, eps = 0.003 m, kv = kw = 3, reference
speed up to 4 m/s, acceleration 1 m/s^2, linear speed ramps) but its equations (14)-(21) were lost in
the text; only fragments remain ("k3 tanh(...)", the desired heading rate, and the dynamic extension
``v_r' = kv (v - v_a)``). Reconstructed here, with e the distance to the reference point P_d (a
look-ahead point on the path), beta its bearing from the robot, phi_d and kappa_d the path heading
and curvature at the closest point:

    ke    = e / (e + k2)                     saturating position gain (0 at P_d, -> 1 far away)
    kr    = e / (e + eps)                    blends aiming at P_d with aligning to the path as e -> 0
                                             (eps avoids the discontinuity of beta at e = 0)
    theta = kr beta + (1 - kr) (phi_d - phi) heading error
    v     = k1 v_ref ke max(cos theta, 0)
    w     = kappa_d v + w_max tanh(theta / k3)   feed-forward of the path's turn rate plus a bounded
                                                 correction; k3 (rad) sets how soon it saturates
    v_r  += kv dt (v - v_a),  w_r += kw dt (w - w_a)   dynamic extension (discrete, ref 000 eq. 20-21)

``v_ref`` follows a trapezoid: it ramps up at ``a_max`` from the start, is capped by the robot's
and the path's maximum speed, and ramps down as ``sqrt(2 a_max s_left)`` to stop at the path's end.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..perception._tracking import Track
from ..types import DriveCommand, FloatArray, Observation, Pose2D, norm_angle_rad
from ._grid import OccupancyGrid
from .base import DeadlineMissed, ForwardTurn, LocalView, MoverGuard, NoPathFound, RobotSpec, drive_command, local_view, way_blocked

__all__ = ["PathFollowerParams", "PathFollower", "FollowPathParams", "FollowPathPlanner"]


@dataclass(frozen=True)
class PathFollowerParams:
    k1: float = 0.85
    k2_m: float = 0.02
    k3_rad: float = 0.3
    eps_m: float = 0.003
    kv: float = 3.0
    kw: float = 3.0
    v_max_m_s: float = 4.0
    a_max_m_s2: float = 1.0
    lookahead_m: float = 0.6
    ds_m: float = 0.05
    end_tolerance_m: float = 0.05

    def __post_init__(self) -> None:
        if not all(v > 0 for v in (self.k1, self.k2_m, self.k3_rad, self.eps_m, self.kv, self.kw, self.v_max_m_s,
                                   self.a_max_m_s2, self.lookahead_m, self.ds_m)):
            raise ValueError("PathFollowerParams: every gain and limit must be > 0")


class PathFollower:
    """The controller alone: ``set_path`` then ``update`` once per control period."""

    def __init__(self, params: PathFollowerParams | None = None, max_speed_m_s: float = 4.0, max_yaw_rate_rad_s: float = 1.2) -> None:
        self.params = params or PathFollowerParams()
        self.v_limit = min(max_speed_m_s, self.params.v_max_m_s)
        self.w_max = max_yaw_rate_rad_s
        self.path: FloatArray = np.zeros((0, 2))
        self.reset()

    def reset(self) -> None:
        self.v_r = 0.0
        self.w_r = 0.0
        self.s = 0.0
        self.t_run = 0.0
        self.done = False

    def set_path(self, xy: FloatArray, keep_speed: bool = False) -> None:
        """Resample a polyline (n, 2), world frame, m, and precompute heading and curvature."""
        p = self.params
        xy = np.asarray(xy, dtype=float)
        d = np.hypot(*np.diff(xy, axis=0).T) if len(xy) > 1 else np.zeros(0)
        xy = xy[np.concatenate(([True], d > 1e-9))] if len(xy) else xy
        if len(xy) < 2:
            raise NoPathFound("a path needs two distinct points")
        cum = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))))
        s = np.arange(0.0, cum[-1], p.ds_m)
        s = np.append(s[s < cum[-1] - 1e-6], cum[-1])  # no zero-length last step (it would spoil the end heading)
        self.path = np.column_stack((np.interp(s, cum, xy[:, 0]), np.interp(s, cum, xy[:, 1])))
        self.s_arr = s
        g = np.gradient(self.path, axis=0)
        self.heading = np.unwrap(np.arctan2(g[:, 1], g[:, 0]))
        w = max(1, int(round(0.25 / p.ds_m)))  # curvature over +-0.25 m: corners become short arcs
        hp = np.concatenate((np.full(w, self.heading[0]), self.heading, np.full(w, self.heading[-1])))
        self.kappa = (hp[2 * w:] - hp[:-2 * w]) / (2 * w * p.ds_m)
        self.s = 0.0
        self.done = False
        if not keep_speed:
            self.v_r = self.w_r = 0.0
            self.t_run = 0.0

    @property
    def length_m(self) -> float:
        return float(self.s_arr[-1]) if len(self.path) else 0.0

    def closest_s(self, x: float, y: float) -> int:
        """Index of the closest path sample in a window around the last one (keeps progress monotone)."""
        i0 = int(np.searchsorted(self.s_arr, self.s - 0.5))
        i1 = int(np.searchsorted(self.s_arr, self.s + 2.0)) + 1
        seg = self.path[i0:i1]
        i = i0 + int(np.argmin((seg[:, 0] - x) ** 2 + (seg[:, 1] - y) ** 2))
        self.s = float(self.s_arr[i])
        return i

    def update(self, pose: Pose2D, v_a: float, w_a: float, dt: float) -> tuple[float, float]:
        """(v_r, w_r): the command for this period, m/s and rad/s."""
        p = self.params
        if len(self.path) < 2:
            return 0.0, 0.0
        self.t_run += dt
        i = self.closest_s(pose.x_m, pose.y_m)
        s_left = self.length_m - self.s
        j = min(int(np.searchsorted(self.s_arr, self.s + p.lookahead_m)), len(self.path) - 1)
        px, py = self.path[j]
        dx, dy = px - pose.x_m, py - pose.y_m
        e = math.hypot(dx, dy)
        if j == len(self.path) - 1 and e < p.end_tolerance_m:
            self.done = True
        beta = norm_angle_rad(math.atan2(dy, dx) - pose.yaw_rad) if e > 1e-9 else 0.0
        phi_err = norm_angle_rad(float(self.heading[i]) - pose.yaw_rad)
        kr = e / (e + p.eps_m)
        ke = e / (e + p.k2_m)
        theta = kr * beta + (1.0 - kr) * phi_err
        v_ref = min(self.v_limit, p.a_max_m_s2 * self.t_run, math.sqrt(2.0 * p.a_max_m_s2 * max(s_left + e if j == len(self.path) - 1 else s_left, 0.0)))
        v = 0.0 if self.done else p.k1 * v_ref * ke * max(math.cos(theta), 0.0)
        w = float(self.kappa[i]) * v + self.w_max * math.tanh(theta / p.k3_rad)
        if self.done:
            w = 0.0
        self.v_r = max(0.0, min(self.v_limit, self.v_r + p.kv * dt * (v - v_a)))
        self.w_r = max(-self.w_max, min(self.w_max, self.w_r + p.kw * dt * (w - w_a)))
        if self.done:
            self.v_r = 0.0
        return self.v_r, self.w_r


#: the largest map window follow-path makes for a far goal, m (4000 x 4000 cells of 0.1 m: 16 MB)
MAX_GRID_M = 400.0


@dataclass(frozen=True)
class FollowPathParams:
    follower: PathFollowerParams = PathFollowerParams()
    inflate_margin_m: float = 0.25
    grid_size_m: float = 60.0
    grid_res_m: float = 0.1
    replan_s: float = 1.0
    plan_deadline_s: float = 0.05
    stop_reach_m: float = 0.05  # the last line of defence looks this far along the arc, plus stop_lag_s of travel
    stop_lag_s: float = 0.4
    # moving obstacles (people walking) from the laser tracker: the robot stops when driving on along its
    # arc would meet one within mover_horizon_s (mover_margin_m of clearance), unless standing would not
    # escape it either. 0 horizon: off (the default: the tracker costs 0.30-0.80 ms per step on the planner
    # benchmark's scenes, more than the rest of the step; 2.0 s for yards with people)
    mover_horizon_s: float = 0.0
    mover_margin_m: float = 0.1

    def __post_init__(self) -> None:
        if not (self.inflate_margin_m >= 0 and self.grid_size_m > 0 and self.grid_res_m > 0 and self.replan_s > 0):
            raise ValueError("FollowPathParams: margin >= 0, grid size/resolution > 0, replan_s > 0")


class FollowPathPlanner:
    """Follows ``obs.extras["path"]`` when the scenario gives one; otherwise plans with A* on an
    occupancy grid built from the laser (unknown = free), replanning every ``replan_s`` and on a
    new goal, and follows that path with :class:`PathFollower`.

    People walking (``mover_horizon_s`` > 0, off by default for its cost): perception's obstacle tracker
    runs on the scans; returns of a moving track are kept out of the map (a walker's trail would wall off its whole beat), and the robot stands while driving
    on along its arc would meet a moving track within ``mover_horizon_s`` (constant-velocity prediction),
    unless standing would be met as soon (:class:`~agnav_host.planning.base.MoverGuard`)."""

    name = "follow-path"
    uses_sonar = False
    params_cls = FollowPathParams

    def __init__(self, spec: RobotSpec, params: FollowPathParams | None = None) -> None:
        self.spec = spec
        self.params = params or FollowPathParams()
        self.follower = PathFollower(self.params.follower, spec.max_speed_m_s, spec.max_yaw_rate_rad_s)
        self.reset()

    def reset(self) -> None:
        self.follower.reset()
        self.follower.path = np.zeros((0, 2))
        self.grid: OccupancyGrid | None = None
        self._given: FloatArray | None = None
        self._goal_key: tuple[float, float] | None = None
        self._since_plan = math.inf
        self.plan_failures = 0
        self.safety_stops = 0  # steps the last line of defence stopped the robot
        self._n_scans = 0
        self.movers = MoverGuard(self.spec, self.params.mover_horizon_s, self.params.mover_margin_m)

    @property
    def tracked_moving(self) -> list[Track]:
        return self.movers.moving

    @property
    def mover_stops(self) -> int:
        return self.movers.stops

    def _new_grid(self, obs: Observation) -> OccupancyGrid:
        """The map's window: ``grid_size_m`` centred on the robot when the goal lies inside it (a metre from
        its edge); otherwise large enough for both with 10 m to spare around them (at most
        ``MAX_GRID_M``), centred between them. A goal outside the map would leave A* without a path, and the
        robot on the straight line to the goal through whatever is in the way. A new goal outside the
        window starts a new map."""
        p = self.params
        sx, sy, gx, gy = obs.pose.x_m, obs.pose.y_m, obs.goal.x_m, obs.goal.y_m
        half = 0.5 * p.grid_size_m - 1.0
        if abs(gx - sx) <= half and abs(gy - sy) <= half:
            return OccupancyGrid((sx, sy), p.grid_size_m, p.grid_res_m)
        size = min(max(p.grid_size_m, max(abs(gx - sx), abs(gy - sy)) + 20.0), MAX_GRID_M)
        return OccupancyGrid((0.5 * (sx + gx), 0.5 * (sy + gy)), size, p.grid_res_m)

    def _replan(self, obs: Observation) -> None:
        assert self.grid is not None
        start = (obs.pose.x_m, obs.pose.y_m)
        goal = (obs.goal.x_m, obs.goal.y_m)
        try:
            path = self.grid.plan(start, goal, self.spec.radius_m + self.params.inflate_margin_m,
                                  deadline_s=self.params.plan_deadline_s)
        except (NoPathFound, DeadlineMissed):
            self.plan_failures += 1
            if len(self.follower.path) >= 2 and float(np.hypot(*(self.follower.path[-1] - goal))) < 1e-6:
                return  # keep following the old path to this goal
            path = np.array([start, goal])
        try:
            self.follower.set_path(path, keep_speed=True)
        except NoPathFound:  # start and goal on the same spot (at the goal): keep what is being followed
            self.plan_failures += 1

    def step(self, obs: Observation) -> DriveCommand:
        spec, p = self.spec, self.params
        given = obs.extras.get("path")
        v: LocalView | None = None
        self.movers.update(obs)
        if given is not None:
            if self._given is None:
                self._given = np.asarray(given, dtype=float)
                self.follower.set_path(self._given)
        else:
            if self.grid is None or not self.grid.covers(obs.goal.x_m, obs.goal.y_m, margin_m=1.0):
                self.grid = self._new_grid(obs)
            if obs.scan is not None:
                v = local_view(obs, spec)
                c, s = math.cos(obs.pose.yaw_rad), math.sin(obs.pose.yaw_rad)
                x = v.xy[:, 0] + spec.footprint_offset_m
                self._n_scans += 1
                origin = None
                if self._n_scans % 3 == 0 and obs.scan.pose is not None:
                    origin = (obs.scan.pose.x_m, obs.scan.pose.y_m)
                world = np.column_stack((obs.pose.x_m + c * x - s * v.xy[:, 1], obs.pose.y_m + s * x + c * v.xy[:, 1]))
                for tr in self.tracked_moving:  # a walker is not mapped: its trail would wall off its beat
                    world = world[np.hypot(world[:, 0] - tr.x_m, world[:, 1] - tr.y_m) > tr.radius_m + 0.15]
                self.grid.add_points(world, origin)
            key = (obs.goal.x_m, obs.goal.y_m)
            self._since_plan += spec.control_dt_s
            if key != self._goal_key or self._since_plan >= p.replan_s:
                self._goal_key = key
                self._since_plan = 0.0
                self._replan(obs)
        v_r, w_r = self.follower.update(obs.pose, obs.speed_m_s, obs.yaw_rate_rad_s, spec.control_dt_s)
        # last line of defence: a return inside the footprint along the arc being driven, within the
        # braking distance: stop and keep turning (a path kept after a failed replan, or cut at a corner by
        # the follower, once brushed a box the map had only just shown). The view's origin is the
        # footprint centre: the arc starts there, with no further offset.
        if given is None and v is not None and v_r > 0.0:
            kappa = w_r / v_r if v_r > 1e-6 else 0.0
            reach = p.stop_reach_m + max(v_r, abs(obs.speed_m_s)) * p.stop_lag_s
            # the arc asked for, and the one the robot is on (a car's steering lags the command)
            if way_blocked(v.xy, kappa, reach, spec.radius_m, 0.0, obs):
                v_r = 0.0
                self.safety_stops += 1
        if self.movers.stand(obs, v_r, w_r):
            v_r = 0.0
        # the view goes to drive_command only for a stop (the car's roll-out steering): driving, the check
        # above reaches further than drive_command's braking guard, which would only repeat it
        cmd = drive_command(spec, v_r, w_r, v if v_r == 0.0 else None, obs)
        if isinstance(cmd, ForwardTurn) and self.movers.stand_for(obs, cmd):  # drive_command made it: check it too
            return DriveCommand(0.0, 0.0, cmd.steer_rad)
        return cmd
