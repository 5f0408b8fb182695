"""FLB: the fuzzy-logic planner of ref 000 (chapters 2-3) on a laser scan.

Inputs are the smallest laser ranges in three 60 deg sectors (right -90..-30, front -30..30, left
30..90 deg, ref 000 eq. 1), turned into clearances normalised by the robot radius and mapped to
Close / Medium / Far. The 27 rules of table 3-I give a heading change and a speed class
(Stop / 0.2 Vmax / Vmax); product inference, centre-of-largest-area defuzzification with the
threshold ``trsh`` (0.3 for cluttered scenes, 0.6 for simple ones, ref 000 sec. 3.4).

How the output is executed (ref 000 gives the heading change and the speed, not how a drive
follows them; these are ours, on engineering grounds):

* The heading change is a change of direction of travel, so while the robot moves it is spread
  over a stretch of path ``L`` (curvature ``dphi / L``, yaw rate ``v dphi / L``), as a steered
  vehicle executes it. ``L`` is ``steer_distance_m`` (0.4 m, about the robot's size), shortened to
  the front clearance (the turn has to be done before the obstacle ahead), never below
  ``min_steer_distance_m``. At a stop (the STOP rules) the change is turned on the spot in
  ``turn_time_s``; between a stop and the SLOW speed the two blend linearly. A fixed time constant
  (``dphi / 0.7 s``, the first implementation) makes the curvature ``dphi / (0.7 v)``: at the SLOW
  speed of 0.2 Vmax every 30 deg set became a turn of 0.27 m radius, which is where FLB's bending
  energy came from.
* CLA with hysteresis: the area holding the previous output counts ``1 + keep_bonus`` times, so two
  nearly equal areas do not take turns from one control step to the next.
* GOAL with the front not Far turns at least one set to the goal's side; while the goal is within
  ``ahead_rad`` of the nose that side is held from the previous step (first time: the more open
  side), otherwise the side flips with each wobble of the heading and the robot drives straight
  into the obstacle.
* Blind-spot guard: a laser mounted ahead of the centre does not see beside the body. Near returns
  are remembered for ``memory_s`` / ``memory_distance_m`` of travel; when one of them, now behind
  the laser's mounting line, is within ``side_margin_m`` of the body on the side of the turn, the
  turn is not made while driving (straight on, or on the spot when the front is near). The rules
  themselves see only the current scan, as in ref 000.
* Rules 4 and 7 (Close on both sides) stop without turning, which never ends in a passage narrower
  than the Close band; after ``stall_s`` in that state the robot creeps ahead when the straight
  path is free.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..types import DriveCommand, Observation
from .base import RobotSpec, drive_command, free_distances_m, goal_in_robot_frame, local_view
from .fuzzy import SPEED_FRACTION, DistanceSets, Inference, Speed, TurnSets, infer

__all__ = ["FlbParams", "FlbPlanner"]


@dataclass(frozen=True)
class FlbParams:
    trsh: float = 0.6
    sector_rad: float = math.radians(30.0)  # front sector half width; sides run from here to 90 deg
    horizon_m: float = 10.0  # a sector with no return reads this far
    distance_sets: DistanceSets = field(default_factory=DistanceSets)
    turn_sets: TurnSets = field(default_factory=TurnSets)
    turn_time_s: float = 0.7  # standing still: yaw rate = heading change / this
    steer_distance_m: float = 0.4  # moving: the heading change is spread over this much travel
    min_steer_distance_m: float = 0.15
    memory_s: float = 30.0  # near returns kept this long (and this far of travel) to cover the blind
    memory_distance_m: float = 1.0  # spot beside the robot
    memory_range_m: float = 1.2
    side_margin_m: float = 0.08  # a remembered return this near the body blocks turning towards it
    ahead_rad: float = math.radians(15.0)  # goal bearing inside +-this: keep the side of the last GOAL turn
    keep_bonus: float = 0.25  # CLA hysteresis: the area holding the previous output counts this much more
    slow_radius_m: float = 0.8  # speed scaled down inside this goal distance
    stall_s: float = 2.0
    creep_fraction: float = 0.15

    def __post_init__(self) -> None:
        if not 0.0 <= self.trsh <= 1.0:
            raise ValueError(f"FlbParams.trsh must be in [0, 1], got {self.trsh}")
        if not self.slow_radius_m > 0:
            raise ValueError(f"FlbParams.slow_radius_m must be > 0, got {self.slow_radius_m}")
        if not (self.turn_time_s > 0 and self.horizon_m > 0 and 0 < self.sector_rad < math.pi / 2):
            raise ValueError("FlbParams: turn_time_s, horizon_m must be > 0 and sector_rad in (0, 90 deg)")
        if not (self.steer_distance_m > 0 and self.keep_bonus >= 0):
            raise ValueError("FlbParams: steer_distance_m must be > 0 and keep_bonus >= 0")


class FlbPlanner:
    """Fuzzy-logic based planner (ref 000). ``last`` keeps the latest :class:`Inference`."""

    name = "flb"
    uses_sonar = False
    params_cls = FlbParams

    def __init__(self, spec: RobotSpec, params: FlbParams | None = None) -> None:
        self.spec = spec
        self.params = params or FlbParams()
        self.last: Inference | None = None
        self._stall_t = 0.0
        self._side = 0.0  # side of a GOAL turn past an obstacle ahead, held while the goal is dead ahead
        self.reset()

    def reset(self) -> None:
        self.last = None
        self._stall_t = 0.0
        self._side = 0.0
        self._mem_xy = np.zeros((0, 2))  # near returns in the odometry frame, m
        self._mem_stamp = np.zeros((0, 2))  # (time s, odometer m) when each was seen
        self._odometer = 0.0
        self._last_xy: tuple[float, float] | None = None
        self._scans = 0

    def step(self, obs: Observation) -> DriveCommand:
        p, spec = self.params, self.spec
        view = local_view(obs, spec)
        h, r = p.horizon_m, spec.radius_m
        d_r = view.sector_min(-math.pi / 2, -p.sector_rad, h)
        d_f = view.sector_min(-p.sector_rad, p.sector_rad, h)
        d_l = view.sector_min(p.sector_rad, math.pi / 2, h)
        d_goal, g_rel = goal_in_robot_frame(obs)
        keep = self.last.turn_rad if self.last is not None else None
        if abs(g_rel) > p.ahead_rad or self._side == 0.0:
            # goal clearly to one side, or no side held yet: its side (dead ahead: the more open side)
            self._side = math.copysign(1.0, g_rel) if abs(g_rel) > p.ahead_rad else (1.0 if d_l >= d_r else -1.0)
        inf = infer((d_l - r) / r, (d_f - r) / r, (d_r - r) / r, g_rel, p.trsh, p.distance_sets, p.turn_sets,
                    keep, p.keep_bonus, self._side)
        self.last = inf
        turn = inf.turn_rad
        v = inf.speed_fraction * spec.max_speed_m_s * min(1.0, d_goal / p.slow_radius_m + 0.15)
        ahead = float(free_distances_m(view.xy, np.array([0.0]), r + 0.02, 1.0)[0])
        if v <= 1e-6 and abs(turn) < math.radians(5.0):
            self._stall_t += spec.control_dt_s
            if self._stall_t >= p.stall_s and ahead > 0.3:
                v = p.creep_fraction * spec.max_speed_m_s
        else:
            self._stall_t = 0.0
        if ahead < 0.05:
            v = 0.0
        w = self.yaw_rate(turn, v, d_f - r)
        if v > 0.0 and w != 0.0:
            # never swing the body into a return that has slipped into the laser's blind spot beside
            # it: drive straight on, or, with an obstacle ahead nearer than the steering distance,
            # make the turn on the spot (a round body turning in place sweeps nothing)
            blind = self._blind_spot_points(obs)
            side = blind[:, 1] * w > 0.0
            if side.any() and float(np.hypot(blind[side, 0], blind[side, 1]).min()) < r + p.side_margin_m:
                if d_f - r < p.steer_distance_m:
                    v = 0.0
                    w = self.yaw_rate(turn, 0.0, d_f - r)
                else:
                    w = 0.0
        self._remember(obs, view.xy)
        return drive_command(spec, v, w, view, obs)

    def _remember(self, obs: Observation, xy: np.ndarray) -> None:
        """Keep the near returns of every third scan in the odometry frame (see :meth:`_blind_spot_points`)."""
        p = self.params
        if p.memory_s <= 0.0:
            return
        if self._last_xy is not None:
            self._odometer += math.hypot(obs.pose.x_m - self._last_xy[0], obs.pose.y_m - self._last_xy[1])
        self._last_xy = (obs.pose.x_m, obs.pose.y_m)
        self._scans += 1
        if self._scans % 3 != 1:  # every third scan is plenty at these speeds
            return
        c, s = math.cos(obs.pose.yaw_rad), math.sin(obs.pose.yaw_rad)
        near = xy[np.hypot(xy[:, 0], xy[:, 1]) < p.memory_range_m]
        fresh = (obs.t_s - self._mem_stamp[:, 0] <= p.memory_s) & (self._odometer - self._mem_stamp[:, 1] <= p.memory_distance_m)
        nx = near[:, 0] + self.spec.footprint_offset_m  # the view is about the footprint's centre, the pose the reference point
        world = np.column_stack((obs.pose.x_m + c * nx - s * near[:, 1],
                                 obs.pose.y_m + s * nx + c * near[:, 1]))
        stamp = np.tile([obs.t_s, self._odometer], (len(near), 1))
        self._mem_xy = np.concatenate((self._mem_xy[fresh], world))
        self._mem_stamp = np.concatenate((self._mem_stamp[fresh], stamp))

    def _blind_spot_points(self, obs: Observation) -> np.ndarray:
        """Recent near returns that the laser can no longer see, robot frame (k, 2), m.

        A laser mounted ahead of the robot's centre sees nothing beside the robot; an obstacle it
        has just passed is invisible while the body is still alongside. The returns within
        ``memory_range_m`` are kept in the odometry frame for ``memory_s`` or ``memory_distance_m``
        of travel; those now behind the laser's mounting line (and not behind the robot) are
        returned. They only guard the turn (see :meth:`step`); the rules see what the laser sees,
        as in ref 000."""
        if not len(self._mem_xy):
            return self._mem_xy
        c, s = math.cos(obs.pose.yaw_rad), math.sin(obs.pose.yaw_rad)
        dx, dy = self._mem_xy[:, 0] - obs.pose.x_m, self._mem_xy[:, 1] - obs.pose.y_m
        off = self.spec.footprint_offset_m
        lx, ly = c * dx + s * dy - off, -s * dx + c * dy  # about the footprint's centre, like the view
        mount_x = 0.0
        if obs.scan is not None and obs.scan.pose is not None:
            mx, my = obs.scan.pose.x_m - obs.pose.x_m, obs.scan.pose.y_m - obs.pose.y_m
            mount_x = c * mx + s * my
        keep = (lx < mount_x - off) & (lx > -self.spec.radius_m)
        return np.column_stack((lx[keep], ly[keep]))

    def yaw_rate(self, turn_rad: float, speed_m_s: float, front_clearance_m: float) -> float:
        """The heading change as a yaw rate, rad/s.

        Moving at the SLOW speed or faster, the change is spread over a stretch of travel ``L``
        (curvature ``dphi / L``, yaw rate ``v dphi / L``), as a steered vehicle executes it: ``L`` is
        ``steer_distance_m``, shortened to the front clearance (the turn must be done before the
        obstacle ahead) but not below ``min_steer_distance_m``. At a stop the change is turned on the
        spot in ``turn_time_s``; in between the two blend linearly."""
        p = self.params
        v = max(speed_m_s, 0.0)
        v_slow = SPEED_FRACTION[Speed.SLOW] * self.spec.max_speed_m_s
        standing = max(0.0, 1.0 - v / v_slow)
        length = max(p.min_steer_distance_m, min(p.steer_distance_m, front_clearance_m))
        return turn_rad * (v / length + standing / p.turn_time_s)
