"""Sonar-ring subsumption on the host: a float mirror of firmware/lib/behaviour/behaviour.c (ref 002).

Same layers, same order and the same defaults (converted to SI) as the firmware, for comparison with
the laser planners; the host-only layers (failsafe, manual, host command) are left out because in
the simulator nothing feeds them:

    AVOID_OBSTACLE  >  FOLLOW_WALL  >  MOVE_TO_GOAL      (a higher layer's proposal wins)

* move to goal: steer at the goal bearing (clamped to ``max_steer``), ``goal_speed`` slowing inside
  ``goal_slow``, crawling at ``goal_min_speed`` while the goal is more than 60 deg off the nose.
* follow wall: obstacle extents ``l = sum cos(a_i) / (R_i + R0)`` over the left sensors
  (15 <= a < 90 deg), ``r`` likewise on the right and ``f`` dead ahead (|a| < 15 deg); a sensor
  without an echo counts with the ring's maximum range. Abstains when all are below ``Imin``, or
  (exit test, ref 002 eq. 8) when the goal is in the front half and the front-side sensors (15-45
  deg) see nothing within the engage horizon. Speed falls linearly from ``wall_speed`` at ``Imin``
  to 0 at ``Imax``. Front blocked: turn at ``wall_turn_steer`` away from the nearer side; canyon
  timers hold a chosen turn direction for ``wall_canyon_s`` after the last blocked tick. Front
  open: proportional steer away from the nearer side with a dead band.

  Host-only extension (``wall_goal_side_rad``, 0 gives exactly the firmware): with the front
  blocked and the goal more than ``wall_goal_side_rad`` (20 deg) off the nose, the turn goes to the
  goal's side unless that side is already inside the Imax horizon; and when that goal cue and the
  wall cue (away from the nearer side) agree, a canyon timer still held from an earlier obstacle is
  dropped instead of flipping the turn. Without it the firmware layer, in the 3 m corridor of ref
  002, keeps the left turn of plate 1 while the upper wall blocks the 1.5 m engage horizon and turns
  round until it follows the walls back to the start (the timer is restarted every blocked tick,
  which is what the dead-end canyon needs); ref 002 leaves the choice of turn direction to "the
  programming parameters" and names automatic selection as future work, so this is our addition.
  The canyon case is unchanged: there the goal is dead ahead (no goal cue) or the cues disagree
  while the robot turns round, and the timer holds as before.

  Second host-only extension (``wall_goal_exit``; False, or ``wall_goal_side_rad`` 0, gives the
  firmware's exit test alone): the layer also abstains when the front is not blocked, the goal
  lies within ``wall_goal_side_rad`` of the nose, no canyon timer is running and no front-side
  sensor sees anything within half the engage horizon. The firmware's exit test asks for nothing
  within the whole 1.5 m horizon; in the greenhouse a wall 1 m to the side is inside it (the
  sonar cone at -30 deg meets it at about 1.5 m), so the layer never let go, steered away from
  the wall towards the plant bench and stalled at its west end. The timer condition keeps the
  layer in charge for ``wall_canyon_s`` after a blocked front, as in the canyon and the corridor.
  ``Imax = 1 / (Nmax vmax dt + R0)`` and ``Imin = 1 / (Nmin vmax dt + R0)`` (reconstructed in the
  firmware; kept as is).
* avoid obstacle (passive motion safety): a valid echo closer than ``avoid_stop`` in the front cone
  while driving forward -> stop ``avoid_stop_s`` -> back off ``avoid_backoff`` (or until the rear
  cone is closer than ``avoid_rear_clear``) -> wait ``avoid_wait_s`` -> release.

The result is a (steer, speed) pair as the firmware's; a differential drive turns it into a yaw rate
as firmware/lib/drive does: ``w = v tan(steer) / track``, and below ``drive_spin_below`` a turn on
the spot with wheel speeds -/+ ``steer / 45 deg * drive_spin``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum

import numpy as np

from ..types import DriveCommand, Observation, norm_angle_rad
from .base import InvalidObservation, RobotSpec, goal_in_robot_frame

__all__ = ["SubsumptionParams", "SubsumptionPlanner", "Layer", "Reason"]


class Layer(IntEnum):  # values as bhv_layer_t
    IDLE = 0
    AVOID_OBSTACLE = 2
    FOLLOW_WALL = 4
    MOVE_TO_GOAL = 6


class Reason(IntEnum):  # values as bhv_reason_t
    OBSTACLE_STOP = 5
    OBSTACLE_BACKOFF = 6
    OBSTACLE_WAIT = 7
    WALL_LEFT = 9
    WALL_RIGHT = 10
    CANYON_TIMER = 11
    GOAL_SEEK = 13
    GOAL_REACHED = 14
    NO_COMMAND = 15


@dataclass(frozen=True)
class SubsumptionParams:
    """BEHAVIOUR_PARAMS_DEFAULT in SI units."""

    max_speed_m_s: float = 1.0
    max_steer_rad: float = math.radians(30.0)
    avoid_stop_m: float = 0.3
    avoid_cone_rad: float = math.radians(30.0)
    avoid_moving_m_s: float = 0.02
    avoid_stop_s: float = 0.2
    avoid_backoff_m: float = 0.05
    avoid_backoff_speed_m_s: float = 0.1
    avoid_rear_clear_m: float = 0.15
    avoid_wait_s: float = 1.0
    wall_r0_m: float = 0.1
    wall_speed_m_s: float = 0.3
    wall_dt_s: float = 0.1
    wall_imax_steps: int = 10
    wall_imin_steps: int = 50
    wall_deadband_per_m: float = 0.1  # 100 per km
    wall_gain_rad_m: float = math.radians(20.0)  # 2 cdeg per (1/km) = 20 deg per (1/m)
    wall_turn_steer_rad: float = math.radians(20.0)
    wall_tie_dir: int = -1
    wall_canyon_s: float = 1.5
    # host only (0 = exactly the firmware): with the front blocked, turn to the goal's side when the goal
    # is more than this off the nose, and let a turn on which the wall and the goal agree end a canyon
    # timer held from an earlier obstacle (see the module docstring)
    wall_goal_side_rad: float = math.radians(20.0)
    # host only (False = the firmware's exit test alone): leave the wall layer when the front is open,
    # the goal within wall_goal_side_rad of the nose, no canyon timer runs and the front-side sensors
    # see nothing within half the engage horizon (see the module docstring)
    wall_goal_exit: bool = True
    goal_speed_m_s: float = 0.4
    goal_min_speed_m_s: float = 0.08
    goal_slow_m: float = 1.0
    goal_tol_m: float = 0.1
    follow_wall: bool = True
    avoid: bool = True
    # firmware/lib/drive (differential): below drive_spin_below the wheels get -/+ steer / 45 deg *
    # drive_spin instead of the arc w = v tan(steer) / track, so the robot turns on the spot
    drive_spin_m_s: float = 0.3
    drive_spin_below_m_s: float = 0.1

    def __post_init__(self) -> None:
        if not (self.wall_imin_steps > self.wall_imax_steps > 0 and self.wall_speed_m_s > 0 and self.wall_dt_s > 0):
            raise ValueError("SubsumptionParams: need wall_imin_steps > wall_imax_steps > 0, wall_speed > 0, wall_dt > 0")


class _Av(IntEnum):
    CLEAR = 0
    STOP = 1
    BACKOFF = 2
    WAIT = 3


_AXIS, _LEFT, _RIGHT, _CONE, _REAR, _FRONT_SIDE = 1, 2, 4, 8, 16, 32


class SubsumptionPlanner:
    """Mirror of the firmware behaviour arbiter. ``layer`` and ``reason`` hold the last winner."""

    name = "subsumption"
    uses_sonar = True
    params_cls = SubsumptionParams

    def __init__(self, spec: RobotSpec, params: SubsumptionParams | None = None) -> None:
        self.spec = spec
        self.params = p = params or SubsumptionParams()
        b = norm_angle_rad(spec.sonar_spacing_rad * np.arange(spec.sonar_count, dtype=np.float64))
        self.bearing = b
        self.cos = np.where(np.cos(b) > 0, np.cos(b), 0.0)
        ab = np.abs(b)
        cls = np.zeros(len(b), dtype=int)
        eps = 1e-9
        cls |= np.where(ab < math.radians(15) - eps, _AXIS, 0)
        cls |= np.where((ab >= math.radians(15) - eps) & (ab < math.radians(90) - eps), np.where(b > 0, _LEFT, _RIGHT), 0)
        cls |= np.where((ab >= math.radians(15) - eps) & (ab <= math.radians(45) + eps), _FRONT_SIDE, 0)
        cls |= np.where(ab <= p.avoid_cone_rad + eps, _CONE, 0)
        cls |= np.where(ab >= math.pi - p.avoid_cone_rad - eps, _REAR, 0)
        self.cls = cls
        step = p.wall_speed_m_s * p.wall_dt_s
        self.imax = 1.0 / (p.wall_imax_steps * step + p.wall_r0_m)
        self.imin = 1.0 / (p.wall_imin_steps * step + p.wall_r0_m)
        self.engage_m = p.wall_imin_steps * step
        self.reset()

    def reset(self) -> None:
        self.layer = Layer.IDLE
        self.reason = Reason.NO_COMMAND
        self.wall_l = self.wall_r = 0.0
        self._av = _Av.CLEAR
        self._av_t = 0.0
        self._backed = 0.0
        self._timer_end = [-math.inf, -math.inf]  # [left, right]

    # ---- layers ------------------------------------------------------------------------------
    def _goal(self, dist: float, err: float, mission_tol_m: float | None = None) -> tuple[float, float, Reason]:
        p = self.params
        # the layer's own 0.1 m, or less for a mission goal that asks for less (stop inside it)
        tol = min(p.goal_tol_m, 0.8 * mission_tol_m) if mission_tol_m else p.goal_tol_m
        if dist <= tol:
            return 0.0, 0.0, Reason.GOAL_REACHED
        speed = p.goal_speed_m_s if dist >= p.goal_slow_m else p.goal_speed_m_s * dist / p.goal_slow_m
        if abs(err) > math.radians(60.0):
            speed = p.goal_min_speed_m_s
        speed = max(speed, p.goal_min_speed_m_s)
        return max(-p.max_steer_rad, min(p.max_steer_rad, err)), speed, Reason.GOAL_SEEK

    def _wall(self, t: float, rng: np.ndarray, valid: np.ndarray, err: float) -> tuple[float, float, Reason] | None:
        p = self.params
        side_clear = not bool(np.any(((self.cls & _FRONT_SIDE) != 0) & valid & (rng < self.engage_m)))
        term = self.cos / (rng + p.wall_r0_m)
        i_left = float(term[(self.cls & _LEFT) != 0].sum())
        i_right = float(term[(self.cls & _RIGHT) != 0].sum())
        i_front = float(term[((self.cls & _AXIS) != 0) & (self.cos > 0)].sum())
        self.wall_l, self.wall_r = i_left, i_right
        blocked = i_front >= self.imin
        if i_left < self.imin and i_right < self.imin and not blocked:
            return None
        # ... but not while a side sensor on the goal's side is closer than avoid_stop (as the firmware):
        # move-to-goal would turn into what stands there (a post 3 cm off the left at 60 deg was swept)
        near = valid & (rng < p.avoid_stop_m)
        side = _LEFT if err > 0 else _RIGHT if err < 0 else 0
        goal_side_near = bool(np.any(near & ((self.cls & side) != 0)))
        if side_clear and not blocked and -math.pi / 2 <= err <= math.pi / 2 and not goal_side_near:
            return None  # exit condition (ref 002 eq. 8)
        if (p.wall_goal_exit and p.wall_goal_side_rad > 0 and not blocked and not goal_side_near and abs(err) <= p.wall_goal_side_rad
                and max(self._timer_end) <= t
                and not np.any(((self.cls & _FRONT_SIDE) != 0) & valid & (rng < 0.5 * self.engage_m))):
            # host only: front open, goal near the nose, no canyon timer running and the front-side
            # sensors clear of half the engage horizon: a wall alongside does not hold the layer
            return None
        e = max(i_left, i_right, i_front)
        if e >= self.imax:
            speed = 0.0
        elif e <= self.imin:
            speed = p.wall_speed_m_s
        else:
            speed = p.wall_speed_m_s * (self.imax - e) / (self.imax - self.imin)
        diff = i_left - i_right
        reason = Reason.WALL_LEFT if i_left >= i_right else Reason.WALL_RIGHT
        timers = p.wall_canyon_s > 0
        if blocked:
            # firmware: away from the nearer side, ties to wall_tie_dir
            d_wall = -1 if diff > p.wall_deadband_per_m else 1 if diff < -p.wall_deadband_per_m else 0
            # host extension (wall_goal_side_rad > 0): towards the goal's side when the goal is off the
            # nose and that side is not already inside the Imax horizon
            d_goal = 0
            if p.wall_goal_side_rad > 0 and abs(err) > p.wall_goal_side_rad and (i_left if err > 0 else i_right) < self.imax:
                d_goal = 1 if err > 0 else -1
            d = d_goal or d_wall or (1 if p.wall_tie_dir >= 0 else -1)
            # both cues agree: a new situation, not the sway of a canyon; the held direction is dropped
            agree = d_wall != 0 and d_wall == d_goal
            if timers:
                want = 0 if d > 0 else 1
                other = 1 - want
                if agree:
                    self._timer_end[other] = -math.inf
                elif self._timer_end[other] > t:
                    d, want, reason = -d, other, Reason.CANYON_TIMER
                self._timer_end[want] = t + p.wall_canyon_s
            steer = d * p.wall_turn_steer_rad
        else:
            if abs(diff) <= p.wall_deadband_per_m:
                steer = 0.0
            else:
                steer = max(-p.wall_turn_steer_rad, min(p.wall_turn_steer_rad, -diff * p.wall_gain_rad_m))
            if timers and steer != 0.0:
                other = 1 if steer > 0 else 0
                if self._timer_end[other] > t:
                    steer, reason = 0.0, Reason.CANYON_TIMER
        return steer, speed, reason

    def _avoid(self, t: float, dt: float, rng: np.ndarray, valid: np.ndarray, lower_fwd: bool, speed_meas: float) -> tuple[float, float, Reason] | None:
        p = self.params
        front = bool(np.any(((self.cls & _CONE) != 0) & valid & (rng < p.avoid_stop_m)))
        rear = bool(np.any(((self.cls & _REAR) != 0) & valid & (rng < p.avoid_rear_clear_m)))
        forward = lower_fwd or speed_meas > p.avoid_moving_m_s
        v = abs(speed_meas)
        in_state = t - self._av_t
        if self._av == _Av.WAIT and in_state >= p.avoid_wait_s:
            self._av = _Av.CLEAR
        if self._av == _Av.CLEAR:
            if not (front and forward):
                return None
            self._av, self._av_t, in_state = _Av.STOP, t, 0.0
        if self._av == _Av.STOP and in_state >= p.avoid_stop_s and v <= p.avoid_moving_m_s:
            self._av, self._av_t, self._backed, in_state = _Av.BACKOFF, t, 0.0, 0.0
        if self._av == _Av.BACKOFF:
            self._backed += v * dt
            cap = 2.0 * p.avoid_backoff_m / max(p.avoid_backoff_speed_m_s, 1e-3) + 0.2
            if self._backed >= p.avoid_backoff_m or rear or in_state >= cap:
                self._av, self._av_t = _Av.WAIT, t
        if self._av == _Av.STOP:
            return 0.0, 0.0, Reason.OBSTACLE_STOP
        if self._av == _Av.BACKOFF:
            return 0.0, -p.avoid_backoff_speed_m_s, Reason.OBSTACLE_BACKOFF
        return 0.0, 0.0, Reason.OBSTACLE_WAIT

    # ---- arbiter -----------------------------------------------------------------------------
    def step(self, obs: Observation) -> DriveCommand:
        if obs.sonar is None:
            raise InvalidObservation("the subsumption planner needs a sonar frame (obs.sonar is None)")
        p, spec = self.params, self.spec
        raw = np.asarray(obs.sonar.ranges_m, dtype=float)[: len(self.bearing)]
        valid = np.isfinite(raw) & (raw > 0)
        rng = np.where(valid, raw, spec.sonar_max_range_m)  # NO_ECHO carries the detection range
        dist, err = goal_in_robot_frame(obs)
        steer, speed, reason = self._goal(dist, norm_angle_rad(err), getattr(obs.goal, "tolerance_m", None))
        layer = Layer.MOVE_TO_GOAL
        if p.follow_wall:
            w = self._wall(obs.t_s, rng, valid, err)
            if w is not None:
                (steer, speed, reason), layer = w, Layer.FOLLOW_WALL
        if p.avoid:
            a = self._avoid(obs.t_s, spec.control_dt_s, rng, valid, speed > 0, obs.speed_m_s)
            if a is not None:
                (steer, speed, reason), layer = a, Layer.AVOID_OBSTACLE
        steer = max(-p.max_steer_rad, min(p.max_steer_rad, steer))
        speed = max(-p.max_speed_m_s, min(p.max_speed_m_s, speed, spec.max_speed_m_s))
        self.layer, self.reason = layer, reason
        if spec.kinematics == "ackermann":
            return DriveCommand(speed, 0.0, max(-spec.max_steer_rad, min(spec.max_steer_rad, steer)))
        if abs(speed) < p.drive_spin_below_m_s:  # drive.c: spin on the spot
            half = steer / math.radians(45.0) * p.drive_spin_m_s
        else:
            half = 0.5 * speed * math.tan(steer)
        return DriveCommand(speed, 2.0 * half / spec.track_m)


