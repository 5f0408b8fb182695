"""Planner interface shared by every host planner (no implementations here).

A planner turns one :class:`~agnav_host.types.Observation` (pose, current goal, laser scan and/or
sonar ring, optional tracked obstacles in ``obs.extras["obstacles"]``) into one
:class:`~agnav_host.types.DriveCommand`. Planners are built from a :class:`RobotSpec` (what the
robot is and can do) through :mod:`agnav_host.planning.registry`; ``reset()`` clears all run state
and ``step()`` is called once per control period.

Goals carry an optional ``arrival_s``; a timed planner reads it together with ``obs.t_s``, so the
same protocol serves it. Observation extras a planner may use (all optional):

``goals``       list[Goal], the whole mission, in order
``goal_index``  int, index of ``obs.goal`` in ``goals``
``path``        (n, 2) array, a planned path in the world frame, m
``obstacles``   (n, 3) array of circles (cx, cy, radius) in the world frame, m (perception tracks)
``meta``        the scenario's ``[meta]`` table

Frames: REP-103, x forward, y left, angles CCW positive; SI units everywhere.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np

from ..types import DriveCommand, FloatArray, Goal, Observation, ScanXY, norm_angle_rad

if TYPE_CHECKING:
    from ..perception._tracking import Track

__all__ = [
    "Planner",
    "RobotSpec",
    "PlanningError",
    "NoPathFound",
    "DeadlineMissed",
    "InvalidObservation",
    "UnknownPlanner",
    "LocalView",
    "local_view",
    "goal_in_robot_frame",
    "drive_command",
    "free_distances_m",
    "clip",
    "arc_blocked",
    "arc_footprint_centres",
    "way_blocked",
]


# ---- errors ------------------------------------------------------------------------------------


class PlanningError(Exception):
    """Base of every planning failure."""


class NoPathFound(PlanningError):
    """The planner proved there is no way to the goal from what it knows."""


class DeadlineMissed(PlanningError):
    """A bounded computation ran out of its time or iteration budget."""


class InvalidObservation(PlanningError):
    """The observation lacks what the planner needs (e.g. no scan for a laser planner)."""


class UnknownPlanner(PlanningError, ValueError):
    """A planner name that the registry does not know; the message lists the known names."""


# ---- protocols ---------------------------------------------------------------------------------


@runtime_checkable
class Planner(Protocol):
    """Observation -> DriveCommand. ``name`` is the registry name."""

    name: str

    def reset(self) -> None: ...

    def step(self, obs: Observation) -> DriveCommand: ...


# ---- robot description -------------------------------------------------------------------------


@dataclass(frozen=True)
class RobotSpec:
    """What a planner needs to know about the robot (SI units).

    ``kinematics`` is ``"diff_drive"`` or ``"ackermann"``. ``footprint_offset_m``: the footprint
    disc's centre ahead of the reference point (Ackermann: half the wheelbase). Sonar fields describe
    the ring (bearings of sensor i = i * spacing); ``control_dt_s`` is the planner period;
    ``stop_lag_s`` the drive's speed lag (first-order time constant), used for stopping distances.
    """

    kinematics: str = "diff_drive"
    radius_m: float = 0.225
    max_speed_m_s: float = 0.5
    min_speed_m_s: float = 0.0
    max_yaw_rate_rad_s: float = 1.2
    max_accel_m_s2: float = 1.0
    track_m: float = 0.4
    wheelbase_m: float = 0.174
    max_steer_rad: float = math.radians(24.6)
    footprint_offset_m: float = 0.0
    control_dt_s: float = 1.0 / 15.0
    stop_lag_s: float = 0.12
    sonar_count: int = 12
    sonar_spacing_rad: float = math.radians(30.0)
    sonar_mount_radius_m: float = 0.225
    sonar_max_range_m: float = 4.0

    def __post_init__(self) -> None:
        if self.kinematics not in ("diff_drive", "ackermann"):
            raise ValueError(f"RobotSpec.kinematics must be 'diff_drive' or 'ackermann', got {self.kinematics!r}")
        for k in ("radius_m", "max_speed_m_s", "max_yaw_rate_rad_s", "control_dt_s", "max_accel_m_s2"):
            if not getattr(self, k) > 0:
                raise ValueError(f"RobotSpec.{k} must be > 0, got {getattr(self, k)}")


def clip(v: float, lo: float, hi: float) -> float:
    return lo if v < lo else hi if v > hi else v


BRAKE_MARGIN_M = 0.05  # the braking guard looks this far along the arc beyond the stopping distance


def drive_command(spec: RobotSpec, speed_m_s: float, yaw_rate_rad_s: float, view: "LocalView | None" = None,
                  obs: Observation | None = None) -> DriveCommand:
    """A (speed, yaw rate) wish turned into the robot's command, limits applied.

    Differential drive: speed and yaw rate clipped. Ackermann: the yaw rate becomes the virtual
    front-wheel angle ``atan(L w / v)`` (no turning on the spot: |v| is taken as at least 0.2 m/s for
    the angle, a stop steering like a slow forward move; reversing, the angle changes sign so that the
    yaw rate keeps the asked sign), and a forward speed is at least ``min_speed_m_s``. A turn on the spot
    (speed 0, yaw rate at least TURN_ON_SPOT_RAD_S) is driven forward at the slowest speed and full lock
    when that arc is clear, from standing the other way round when only that is (:func:`_forward_turn_side`),
    as a :class:`ForwardTurn`; else the car stands.

    ``view`` (the planner's obstacle points): braking guard. When a point lies in the footprint's way
    along the arc the command drives, within the stopping distance (one control period plus the drive's
    lag at the commanded speed, plus BRAKE_MARGIN_M), the speed becomes 0 and the turn is kept. A
    planner's slow-down near an obstacle is otherwise lost on a car whose slowest speed is its
    calibrated minimum. With ``obs`` the arc the robot is on now (its yaw rate over its speed) is checked
    too: a car's steering takes a while to reach the commanded angle; and a car told to stop while it
    still rolls gets a steering angle whose roll-out is clear (a planner turning "on the spot" to a side
    steered it into the box it had stopped for)."""
    v = clip(speed_m_s, -spec.max_speed_m_s, spec.max_speed_m_s)
    w = clip(yaw_rate_rad_s, -spec.max_yaw_rate_rad_s, spec.max_yaw_rate_rad_s)
    if spec.kinematics == "diff_drive":
        if view is not None and v > 0.0 and _brake_now(spec, view, v, w / v, obs):
            v = 0.0
        return DriveCommand(v, w)
    turn = _forward_turn_side(spec, w, view, obs) if v == 0.0 and abs(w) >= TURN_ON_SPOT_RAD_S else 0.0
    if turn:
        v, steer = spec.min_speed_m_s, math.copysign(spec.max_steer_rad, turn)
    else:
        if v > 0.0:
            v = max(v, spec.min_speed_m_s)
        steer = clip(math.atan2(spec.wheelbase_m * w * (-1.0 if v < 0.0 else 1.0), max(abs(v), 0.2)), -spec.max_steer_rad, spec.max_steer_rad)
    if view is not None and v > 0.0 and _brake_now(spec, view, v, math.tan(steer) / spec.wheelbase_m, obs):
        v = 0.0
    if view is not None and obs is not None and v == 0.0 and obs.speed_m_s > 0.1:
        steer = _roll_out_steer(spec, view, obs, steer)
    return ForwardTurn(v, 0.0, steer) if turn and v > 0.0 else DriveCommand(v, 0.0, steer)


@dataclass(frozen=True)
class ForwardTurn(DriveCommand):
    """:func:`drive_command`'s stand-in on a car for a wish to turn on the spot: the slowest speed at full
    lock. A :class:`MoverGuard` lets it go only while no moving track comes near (``forward_turn`` in
    :meth:`MoverGuard.stand`): the car would otherwise have stood there."""


#: the roll-out check tries the steering angles the wheels pass through this far apart (rad)
ROLL_OUT_SWING_STEP_RAD = math.radians(5.0)
#: Ackermann: a wish to turn on the spot at least this fast (rad/s) becomes a forward turn at full lock
TURN_ON_SPOT_RAD_S = 0.05
#: ... and, with a MoverGuard, when no moving track comes within this much more than its margin (m)
FORWARD_TURN_MOVER_MARGIN_M = 0.5
#: ... nor while a track that has moved (a walker, moving now or not: one turning round at the end of its
#: beat slows, or leaves a track coasting on the old way) is this close to the robot (m, clearance)
FORWARD_TURN_WALKER_CLEAR_M = 1.5
#: ... when the full-lock arc is clear this far beyond the stopping distance at the slowest speed (m): a turn
#: begun only to be stopped a step later (the next point in the way) leaves the car rolling into it
FORWARD_TURN_CLEAR_M = 0.3


def _forward_turn_side(spec: RobotSpec, w: float, view: "LocalView | None", obs: Observation | None) -> float:
    """Which way (+1 left, -1 right, 0 none) a car drives a wish to turn on the spot at yaw rate ``w``: forward
    at full lock that way when it is clear (:func:`_forward_turn_clear`); from standing, the other way round
    when only that is (a loop to the same heading: the car used to stand there until the run timed out)."""
    if _forward_turn_clear(spec, w, view, obs):
        return math.copysign(1.0, w)
    if obs is not None and abs(obs.speed_m_s) <= 0.1 and _forward_turn_clear(spec, -w, view, obs):
        return -math.copysign(1.0, w)
    return 0.0


def _forward_turn_clear(spec: RobotSpec, w: float, view: "LocalView | None", obs: Observation | None) -> bool:
    """A car cannot turn on the spot (it stood there until the run timed out): drive the turn forward at its
    slowest speed and full lock instead, when its obstacle points are known, the full-lock arc is clear (see
    FORWARD_TURN_CLEAR_M) and the goal is not already reached (a planner turning to the goal's heading
    there would set the car circling)."""
    if view is None or obs is None or spec.min_speed_m_s <= 0.0:
        return False
    if math.hypot(obs.goal.x_m - obs.pose.x_m, obs.goal.y_m - obs.pose.y_m) <= obs.goal.tolerance_m:
        return False
    if len(view.xy) == 0:
        return True
    lock = math.copysign(spec.max_steer_rad, w)
    reach = _stopping_reach_m(spec, max(spec.min_speed_m_s, abs(obs.speed_m_s))) + FORWARD_TURN_CLEAR_M
    pts = _from_reference_point(spec, view)
    return _swing_clear(spec, pts, _steer_now(spec, obs, lock), lock, reach)


def _steer_now(spec: RobotSpec, obs: Observation, standing: float) -> float:
    """The steering angle the car is on (from its yaw rate over its speed) while it rolls; ``standing`` when
    it does not (its wheels then swing without moving it)."""
    if abs(obs.speed_m_s) <= 0.1:
        return standing
    return clip(math.atan(spec.wheelbase_m * obs.yaw_rate_rad_s / obs.speed_m_s), -spec.max_steer_rad, spec.max_steer_rad)


def _swing_clear(spec: RobotSpec, pts: FloatArray, now: float, to: float, reach_m: float) -> bool:
    """No point in the footprint's way over ``reach_m`` along any arc between the steering angle the car is
    on and ``to`` (rad): the wheels pass through them while it rolls."""
    swing = np.linspace(now, to, max(2, int(abs(to - now) / ROLL_OUT_SWING_STEP_RAD) + 2))
    return not any(arc_blocked(0.0, 0.0, 0.0, math.tan(a) / spec.wheelbase_m, reach_m, pts, spec.radius_m,
                               spec.footprint_offset_m) for a in swing)


def _stopping_reach_m(spec: RobotSpec, v_m_s: float) -> float:
    """How far along its arc the braking guard looks at ``v_m_s``: one control period plus the drive's lag
    of travel, plus BRAKE_MARGIN_M."""
    return BRAKE_MARGIN_M + v_m_s * (spec.control_dt_s + spec.stop_lag_s)


def _from_reference_point(spec: RobotSpec, view: "LocalView") -> FloatArray:
    """The view's points (centred on the footprint) in the frame of the robot's reference point."""
    off = spec.footprint_offset_m
    return view.xy + np.array([off, 0.0]) if off else view.xy


def _roll_out_steer(spec: RobotSpec, view: "LocalView", obs: Observation, steer: float) -> float:
    """A car told to stop still rolls (its speed lag) along whatever its wheels point to: the steering
    asked for when that roll-out is clear, else the first clear of the angle it is on, straight ahead and
    full lock either way; the angle it is on when none is. Clear means every arc between the angle the car is
    on and the candidate (the wheels swing through them while it rolls: swung straight across, a car grazed
    the box it had stopped for)."""
    if len(view.xy) == 0:
        return steer
    reach = _stopping_reach_m(spec, obs.speed_m_s)
    pts = _from_reference_point(spec, view)
    now = _steer_now(spec, obs, steer)
    for cand in (steer, now, 0.0, spec.max_steer_rad, -spec.max_steer_rad):
        cand = clip(cand, -spec.max_steer_rad, spec.max_steer_rad)
        if _swing_clear(spec, pts, now, cand, reach):
            return cand
    return now


def _brake_now(spec: RobotSpec, view: "LocalView", v_m_s: float, kappa_1_m: float, obs: Observation | None) -> bool:
    """True when ``view``'s points block the footprint's way within the stopping distance from the larger
    of ``v_m_s`` and the robot's speed, along the commanded arc or (with ``obs``, moving) the one it is on."""
    if len(view.xy) == 0:
        return False
    v = v_m_s if obs is None else max(v_m_s, abs(obs.speed_m_s))
    return way_blocked(_from_reference_point(spec, view), kappa_1_m, _stopping_reach_m(spec, v), spec.radius_m,
                       spec.footprint_offset_m, obs)


# ---- geometry helpers --------------------------------------------------------------------------


def goal_in_robot_frame(obs: Observation, goal: Goal | None = None) -> tuple[float, float]:
    """(distance m, bearing rad) of the goal from the robot's reference point and heading."""
    g = obs.goal if goal is None else goal
    dx, dy = g.x_m - obs.pose.x_m, g.y_m - obs.pose.y_m
    return math.hypot(dx, dy), norm_angle_rad(math.atan2(dy, dx) - obs.pose.yaw_rad)


@dataclass(frozen=True)
class LocalView:
    """Obstacle points around the robot, robot frame (origin at the footprint centre, x forward).

    ``xy`` (k, 2) m; ``range_m`` (k,) distance from the footprint centre, m; ``bearing_rad`` (k,)
    sorted ascending. ``no_return_rad`` holds the bearings of laser beams without a return (open
    directions), rad.
    """

    xy: ScanXY
    range_m: FloatArray
    bearing_rad: FloatArray
    no_return_rad: FloatArray

    def sector_min(self, lo_rad: float, hi_rad: float, default: float) -> float:
        """Smallest range among points with bearing in [lo, hi], m; ``default`` when none."""
        i0 = int(np.searchsorted(self.bearing_rad, lo_rad, "left"))
        i1 = int(np.searchsorted(self.bearing_rad, hi_rad, "right"))
        return float(self.range_m[i0:i1].min()) if i1 > i0 else default


_TRIG_CACHE: dict[tuple[float, float, int], tuple[FloatArray, FloatArray, FloatArray]] = {}


def _trig(a0: float, inc: float, n: int) -> tuple[FloatArray, FloatArray, FloatArray]:
    key = (a0, inc, n)
    t = _TRIG_CACHE.get(key)
    if t is None:
        a = a0 + inc * np.arange(n, dtype=np.float64)
        t = (a, np.cos(a), np.sin(a))
        if len(_TRIG_CACHE) > 32:
            _TRIG_CACHE.clear()
        _TRIG_CACHE[key] = t
    return t


def local_view(obs: Observation, spec: RobotSpec, use_laser: bool = True, use_sonar: bool = False,
               use_tracks: bool = True, resolution_rad: float = math.radians(1.0)) -> LocalView:
    """Gather the laser returns (and/or sonar ranges, tracked obstacle circles) as robot-frame points.

    Laser beams finer than ``resolution_rad`` are grouped and only the nearest return of each group
    is kept (a 1/3 deg TiM561 scan becomes 270 points), which bounds every planner's work per step.
    Raises :class:`InvalidObservation` when a requested sensor is missing from ``obs``.
    """
    chunks: list[FloatArray] = []
    no_ret = np.zeros(0)
    c0, s0 = math.cos(obs.pose.yaw_rad), math.sin(obs.pose.yaw_rad)
    off = spec.footprint_offset_m
    if use_laser:
        scan = obs.scan
        if scan is None:
            raise InvalidObservation("this planner needs a laser scan (obs.scan is None)")
        r = scan.ranges_m
        a, ca, sa = _trig(scan.angle_min_rad, scan.angle_increment_rad, len(r))
        k = int(resolution_rad / abs(scan.angle_increment_rad) + 1e-9) if scan.angle_increment_rad else 1
        if k > 1 and len(r) >= k:
            # nearest return of each group of k beams; the last group may be short (padded with no return)
            m = -(-len(r) // k) * k
            rr = np.full(m, np.inf)
            rr[:len(r)] = np.where(np.isfinite(r) & (r > 0.0), r, np.inf)
            g = rr.reshape(-1, k)
            pick = np.minimum(np.arange(0, m, k) + g.argmin(axis=1), len(r) - 1)
            r, a, ca, sa = r[pick], a[pick], ca[pick], sa[pick]
        sp = scan.pose if scan.pose is not None else obs.pose
        # sensor pose relative to the robot reference point, robot frame
        dx, dy = sp.x_m - obs.pose.x_m, sp.y_m - obs.pose.y_m
        mx, my = c0 * dx + s0 * dy - off, -s0 * dx + c0 * dy
        dyaw = norm_angle_rad(sp.yaw_rad - obs.pose.yaw_rad)
        ok = np.isfinite(r) & (r > 0.0)
        if not ok.all():
            no_ret = norm_angle_rad(a[~ok] + dyaw)
        rr = r[ok]
        if dyaw == 0.0:
            px, py = rr * ca[ok], rr * sa[ok]
        else:
            cd, sd = math.cos(dyaw), math.sin(dyaw)
            lx, ly = rr * ca[ok], rr * sa[ok]
            px, py = cd * lx - sd * ly, sd * lx + cd * ly
        chunks.append(np.column_stack((px + mx, py + my)))
    if use_sonar:
        son = obs.sonar
        if son is None:
            raise InvalidObservation("this planner needs a sonar frame (obs.sonar is None)")
        rng = np.asarray(son.ranges_m, dtype=float)
        b = spec.sonar_spacing_rad * np.arange(len(rng))
        ok = np.isfinite(rng)
        d = rng[ok] + spec.sonar_mount_radius_m
        chunks.append(np.column_stack((d * np.cos(b[ok]) - off, d * np.sin(b[ok]))))
    if use_tracks:
        circ = obs.extras.get("obstacles")
        if circ is not None and len(circ):  # type: ignore[arg-type]
            c = np.asarray(circ, dtype=float).reshape(-1, 3)
            ang = np.linspace(0.0, 2.0 * math.pi, 12, endpoint=False)
            wx = (c[:, 0:1] + c[:, 2:3] * np.cos(ang)).ravel() - obs.pose.x_m
            wy = (c[:, 1:2] + c[:, 2:3] * np.sin(ang)).ravel() - obs.pose.y_m
            chunks.append(np.column_stack((c0 * wx + s0 * wy - off, -s0 * wx + c0 * wy)))
    xy = np.concatenate(chunks) if len(chunks) > 1 else (chunks[0] if chunks else np.zeros((0, 2)))
    rng_m = np.hypot(xy[:, 0], xy[:, 1])
    bear = np.arctan2(xy[:, 1], xy[:, 0])
    order = np.argsort(bear, kind="stable")
    return LocalView(xy[order], rng_m[order], bear[order], no_ret)


def free_distances_m(points_xy: FloatArray, directions_rad: FloatArray, half_width_m: float, horizon_m: float) -> FloatArray:
    """How far a disc of radius ``half_width_m`` at the origin can travel straight along each direction.

    ``points_xy`` (k, 2) robot frame, m; ``directions_rad`` (d,). Returns (d,) m, capped at ``horizon_m``.
    """
    d = np.asarray(directions_rad, dtype=float)
    out = np.full(len(d), horizon_m)
    if len(points_xy) == 0:
        return out
    near = points_xy[(np.abs(points_xy[:, 0]) < horizon_m + half_width_m) & (np.abs(points_xy[:, 1]) < horizon_m + half_width_m)]
    if len(near) == 0:
        return out
    ux, uy = np.cos(d)[:, None], np.sin(d)[:, None]
    px, py = near[None, :, 0], near[None, :, 1]
    along = px * ux + py * uy
    lat = np.abs(px * uy - py * ux)
    block = (lat < half_width_m) & (along > -half_width_m)
    dist = along - np.sqrt(np.maximum(half_width_m**2 - lat**2, 0.0))
    dist = np.where(block, np.maximum(dist, 0.0), np.inf)
    free: FloatArray = np.minimum(out, dist.min(axis=1))
    return free


def arc_blocked(x_m: float, y_m: float, yaw_rad: float, kappa_1_m: float, length_m: float, points_xy: FloatArray,
                radius_m: float, footprint_offset_m: float, ds_m: float = 0.05) -> bool:
    """True when a point ((k, 2) m, in the frame of the pose) lies inside the footprint disc
    (``radius_m``, centred ``footprint_offset_m`` ahead of the reference point) anywhere along the arc of
    curvature ``kappa_1_m`` (1/m, CCW positive) from the pose over ``length_m``, both ends included: the
    way the robot goes if it keeps its turn. The planners' last line of defence (timed, follow-path)."""
    if len(points_xy) == 0 or length_m < 0.0:
        return False
    s = np.append(np.arange(0.0, length_m, ds_m), length_m)  # the end itself too
    cx, cy = arc_footprint_centres(x_m, y_m, yaw_rad, kappa_1_m, s, footprint_offset_m)
    reach = length_m + footprint_offset_m + radius_m
    near = np.hypot(points_xy[:, 0] - x_m, points_xy[:, 1] - y_m) <= reach
    if not near.any():
        return False
    pts = points_xy[near]
    d2 = (cx[:, None] - pts[None, :, 0]) ** 2 + (cy[:, None] - pts[None, :, 1]) ** 2
    return bool((d2 < radius_m * radius_m).any())


def way_blocked(points_xy: FloatArray, kappa_1_m: float, length_m: float, radius_m: float, footprint_offset_m: float,
                obs: Observation | None = None) -> bool:
    """:func:`arc_blocked` from the origin along the commanded arc (``kappa_1_m``) or, with ``obs`` while the
    robot moves (over 0.1 m/s), along the arc it is on (its yaw rate over its speed): a car's steering takes
    a while to reach the commanded angle. ``points_xy`` in the frame of the reference point."""
    if arc_blocked(0.0, 0.0, 0.0, kappa_1_m, length_m, points_xy, radius_m, footprint_offset_m):
        return True
    if obs is None or abs(obs.speed_m_s) <= 0.1:
        return False
    return arc_blocked(0.0, 0.0, 0.0, obs.yaw_rate_rad_s / obs.speed_m_s, length_m, points_xy, radius_m, footprint_offset_m)


def arc_footprint_centres(x_m: float, y_m: float, yaw_rad: float, kappa_1_m: float, s_m: FloatArray,
                          footprint_offset_m: float) -> tuple[FloatArray, FloatArray]:
    """The footprint disc's centres (``footprint_offset_m`` ahead of the reference point) at arc lengths
    ``s_m`` along the arc of curvature ``kappa_1_m`` (1/m, CCW positive) from the pose, m."""
    if abs(kappa_1_m) < 1e-6:
        yaw = np.full(len(s_m), yaw_rad)
        x, y = x_m + s_m * math.cos(yaw_rad), y_m + s_m * math.sin(yaw_rad)
    else:
        yaw = yaw_rad + kappa_1_m * s_m
        x = x_m + (np.sin(yaw) - math.sin(yaw_rad)) / kappa_1_m
        y = y_m - (np.cos(yaw) - math.cos(yaw_rad)) / kappa_1_m
    return x + footprint_offset_m * np.cos(yaw), y + footprint_offset_m * np.sin(yaw)


# ---- people walking: the tracker's moving tracks, and when to stand for them ----------------------------


class MoverGuard:
    """Moving obstacles from perception's laser tracker, and the rule that lets them by: the robot stands
    while driving on along its arc (at least at the speed it has) would meet a moving track, predicted at
    constant velocity, within ``horizon_s`` (``margin_m`` of clearance), unless standing would be met as
    soon (a person crossing ahead is let by; one heading for where the robot stands is not waited for).

    ``update(obs)`` once per step (every scan, so that the tracks stay tracked), then ``stand(obs, v, w)``.
    The tracker costs 0.30-0.80 ms per step (0.68 ms in plant rows with the movers-only update used here),
    which is why the planners that use it have it off by default (``horizon_s`` 0)."""

    def __init__(self, spec: RobotSpec, horizon_s: float, margin_m: float = 0.1) -> None:
        from ..perception._tracking import ObstacleTracker, TrackerParams

        self.spec, self.horizon_s, self.margin_m = spec, horizon_s, margin_m
        self.tracker = ObstacleTracker(TrackerParams(max_coast_s=1.0, max_grow_m=0.15, max_shrink_m=0.15))
        self.moving: list[Track] = []  # the tracker's moving tracks at the last update
        self.walkers: list[Track] = []  # tracks that have moved, moving or not now (a walker turning round slows)
        self.stops = 0  # steps the robot stood for a moving track

    @property
    def on(self) -> bool:
        return self.horizon_s > 0.0

    def update(self, obs: Observation) -> None:
        if self.on and obs.scan is not None and obs.scan.pose is not None:
            self.walkers = self.tracker.update(obs.scan, obs.t_s, movers_only=True)
            self.moving = [tr for tr in self.walkers if tr.moving]

    def stand(self, obs: Observation, v_m_s: float, w_rad_s: float, forward_turn: bool = False) -> bool:
        """True when the robot should stand this step instead of driving at ``v_m_s`` / ``w_rad_s``.
        ``forward_turn`` (a car's :class:`ForwardTurn`, where it would otherwise stand): it goes only when
        no moving track comes within ``FORWARD_TURN_MOVER_MARGIN_M`` more of either the arc or where it
        stands over the horizon, and no track that has ever moved is within ``FORWARD_TURN_WALKER_CLEAR_M``
        now (a car turning forward where it used to stand met walkers the plain rule let it drive past:
        contacts while moving 8 -> 17 in the walker yards; three of them beside a walker turning round)."""
        if not self.on or v_m_s <= 0.0:
            return False
        if forward_turn and any(math.hypot(tr.x_m - obs.pose.x_m, tr.y_m - obs.pose.y_m) - tr.radius_m - self.spec.radius_m
                                < FORWARD_TURN_WALKER_CLEAR_M for tr in self.walkers):
            self.stops += 1
            return True
        if not self.moving:
            return False
        ts = np.arange(0.0, self.horizon_s + 1e-9, 0.1)
        s = max(v_m_s, abs(obs.speed_m_s)) * ts
        gx, gy = arc_footprint_centres(obs.pose.x_m, obs.pose.y_m, obs.pose.yaw_rad, w_rad_s / v_m_s, s,
                                       self.spec.footprint_offset_m)  # footprint centre driving on
        hx, hy = gx[0], gy[0]  # ... and standing
        first_go = first_stand = math.inf
        for tr in self.moving:
            ox, oy = tr.x_m + tr.vx_m_s * ts, tr.y_m + tr.vy_m_s * ts
            lim = tr.radius_m + self.spec.radius_m + self.margin_m + (FORWARD_TURN_MOVER_MARGIN_M if forward_turn else 0.0)
            hit = np.flatnonzero(np.hypot(gx - ox, gy - oy) < lim)
            if len(hit):
                first_go = min(first_go, float(ts[hit[0]]))
            hit = np.flatnonzero(np.hypot(hx - ox, hy - oy) < lim)
            if len(hit):
                first_stand = min(first_stand, float(ts[hit[0]]))
        if forward_turn:
            stand = first_go < math.inf or first_stand < math.inf
        else:
            stand = first_go < math.inf and first_go <= first_stand
        self.stops += stand
        return stand

    def stand_for(self, obs: Observation, cmd: DriveCommand) -> bool:
        """:meth:`stand` for a robot command: its yaw rate from the steering angle on a car, and a
        :class:`ForwardTurn` checked as one."""
        if cmd.speed_m_s <= 0.0:
            return False
        if cmd.steer_rad is not None:
            w = cmd.speed_m_s * math.tan(cmd.steer_rad) / self.spec.wheelbase_m
        else:
            w = cmd.yaw_rate_rad_s
        return self.stand(obs, cmd.speed_m_s, w, isinstance(cmd, ForwardTurn))


class WithMoverGuard:
    """A reactive planner with a :class:`MoverGuard` around it (registry: ``mover_horizon_s`` in the
    planner's parameters): each step the wrapped planner's command is kept unless the guard says stand,
    then the speed is 0 and the turn kept. Attributes not found here are the wrapped planner's."""

    def __init__(self, planner: "Planner", horizon_s: float) -> None:
        self.planner = planner
        self.guard = MoverGuard(planner.spec, horizon_s)  # type: ignore[attr-defined]

    def __getattr__(self, name: str) -> Any:
        return getattr(self.planner, name)

    def reset(self) -> None:
        self.planner.reset()
        self.guard = MoverGuard(self.guard.spec, self.guard.horizon_s, self.guard.margin_m)

    def step(self, obs: Observation) -> DriveCommand:
        cmd = self.planner.step(obs)
        self.guard.update(obs)
        if self.guard.stand_for(obs, cmd):
            return DriveCommand(0.0, cmd.yaw_rate_rad_s, cmd.steer_rad)
        return cmd
