"""Timed plans: a ref-003 polynomial path plus a drivable speed profile that ends at the set time."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...calib import SPEED_MAX_CM_S, SPEED_MIN_CM_S
from ...types import FloatArray, norm_angle_rad
from ..base import DeadlineMissed, RobotSpec
from ._path import GeoPath, build_path
from ._poly import BoundaryState
from ._profile import LegInfeasible, SpeedLimits, SpeedProfile, concat_profiles, leg_min_time_s, solve_leg

__all__ = ["TimedLimits", "TimedPlan", "plan_timed", "via_state", "check_deadline"]


@dataclass(frozen=True)
class TimedLimits:
    """What a timed plan must respect (SI). Defaults: the ref-003 RC car.

    ``max_steer_rad`` is the largest steering angle ever *commanded* (20 deg, below the 24.6 deg the
    servo reaches); ``plan_steer_rad`` the largest a plan may use, leaving the difference to the
    tracking law for corrections. The speed band is the calibrated one (43.5-200 cm/s) and
    ``accel_m_s2`` the acceleration the plan may ask for. ``radius_m`` / ``footprint_offset_m``: the
    footprint disc and its centre ahead of the rear axle (half the 174 mm wheelbase).

    The end of every plan is the car's real stop: it comes in at v_min, the command drops to 0 and the
    speed controller's lag (``stop_lag_s``) brings it to rest over v_min * lag (about 11 cm), modelled
    as a constant deceleration v_min / (2 lag) (not limited by ``accel_m_s2``, which bounds the commanded
    ramps; the summary reports it as ``stop_decel_mps2``); the ``creep_m`` before it are driven at v_min so the car
    enters the stop at that speed. The plan's *arrival* is when that stop brings the car
    within ``arrive_tol_m`` of the goal; it comes to rest a fraction of a second later."""

    wheelbase_m: float = 0.174
    max_steer_rad: float = math.radians(20.0)
    plan_steer_rad: float = math.radians(17.0)
    v_min_m_s: float = SPEED_MIN_CM_S / 100.0
    v_max_m_s: float = SPEED_MAX_CM_S / 100.0
    accel_m_s2: float = 1.0
    cruise_m_s: float = 0.8  # speed of untimed plans (no arrival time given)
    radius_m: float = 0.16
    footprint_offset_m: float = 0.087
    stop_lag_s: float = 0.25  # speed controller time constant: the car stops over v_min * lag
    arrive_tol_m: float = 0.05  # "arrived" = within this of the goal position
    creep_m: float = 0.3  # last stretch before the stop driven at v_min

    def __post_init__(self) -> None:
        if not 0 < self.plan_steer_rad <= self.max_steer_rad < math.pi / 2:
            raise ValueError("need 0 < plan_steer_rad <= max_steer_rad < 90 deg")
        if not 0 < self.wheelbase_m:
            raise ValueError("wheelbase_m must be > 0")
        SpeedLimits(self.v_min_m_s, self.v_max_m_s, self.accel_m_s2)  # validates the band

    @property
    def speed(self) -> SpeedLimits:
        return SpeedLimits(self.v_min_m_s, self.v_max_m_s, self.accel_m_s2)

    @property
    def plan_kappa_max(self) -> float:
        return math.tan(self.plan_steer_rad) / self.wheelbase_m

    @staticmethod
    def from_spec(spec: RobotSpec, **over: Any) -> "TimedLimits":
        """Limits of a planner's robot: band floor from the speed table (spec.min_speed_m_s, or the
        calibrated 43.5 cm/s when the spec has none), top from spec.max_speed_m_s, steering at most
        20 deg and never beyond the servo's spec.max_steer_rad."""
        vmin = spec.min_speed_m_s if spec.min_speed_m_s > 0 else SPEED_MIN_CM_S / 100.0
        vmax = min(spec.max_speed_m_s, SPEED_MAX_CM_S / 100.0)
        steer = min(math.radians(20.0), spec.max_steer_rad)
        kw: dict[str, Any] = dict(wheelbase_m=spec.wheelbase_m, max_steer_rad=steer, plan_steer_rad=min(math.radians(17.0), steer),
                                  v_min_m_s=vmin, v_max_m_s=max(vmax, vmin + 0.05), accel_m_s2=min(1.0, spec.max_accel_m_s2),
                                  cruise_m_s=max(vmin, 0.8 * vmax), radius_m=spec.radius_m, footprint_offset_m=spec.footprint_offset_m)
        kw.update(over)
        return TimedLimits(**kw)


def check_deadline(deadline: float | None, what: str) -> None:
    """Raise :class:`DeadlineMissed` when the perf_counter time ``deadline`` has passed."""
    if deadline is not None and time.perf_counter() > deadline:
        raise DeadlineMissed(f"{what}: planning budget exhausted")


@dataclass(frozen=True)
class TimedPlan:
    """A path, a speed profile along it and the verdict.

    ``t0_s``: absolute time the profile starts. ``requested_arrival_s``: what was asked (None:
    untimed); ``arrival_s``: when this plan arrives (the request when feasible, else the earliest).
    ``feasible`` is False when the request cannot be met; ``reason`` then says why and
    ``earliest_arrival_s`` gives the earliest feasible arrival (None when no timing helps, e.g. a
    turn tighter than the steering allows)."""

    path: GeoPath
    profile: SpeedProfile
    t0_s: float
    requested_arrival_s: float | None
    feasible: bool
    reason: str
    earliest_arrival_s: float | None
    limits: TimedLimits
    states: tuple[BoundaryState, ...]
    tags: tuple[str, ...] = field(default=())
    settle_s: float = 0.0  # from arrival (within arrive_tol_m) to rest, s

    @property
    def arrival_s(self) -> float:
        """When the plan reaches the goal (within ``limits.arrive_tol_m``), absolute s."""
        return self.t0_s + self.profile.duration_s - self.settle_s

    @property
    def duration_s(self) -> float:
        """From the plan's start to its arrival, s."""
        return self.profile.duration_s - self.settle_s

    @property
    def goal(self) -> BoundaryState:
        return self.states[-1]

    @property
    def max_steering_rad(self) -> float:
        return math.atan(self.limits.wheelbase_m * self.path.max_abs_kappa)

    @property
    def max_speed_m_s(self) -> float:
        return self.profile.max_speed_m_s

    def at(self, t_s: FloatArray | float) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
        """Reference (x, y, yaw, kappa, speed, arc length) at absolute times ``t_s``."""
        s, v = self.profile.eval(np.asarray(t_s, dtype=float) - self.t0_s)
        x, y, yaw, k = self.path.sample(s)
        return x, y, yaw, k, v, s

    def footprint_at(self, t_s: FloatArray) -> FloatArray:
        """Footprint-disc centres (n, 2) at absolute times, m (the robot waits at its final pose after
        the end and before the start)."""
        x, y, yaw, _, _, _ = self.at(t_s)
        off = self.limits.footprint_offset_m
        return np.column_stack((x + off * np.cos(yaw), y + off * np.sin(yaw)))

    def summary(self) -> dict[str, Any]:
        """JSON-ready description (the ``agnav plan --json`` keys)."""
        return {
            "feasible": self.feasible,
            "reason": self.reason,
            "earliest_arrival_s": None if self.earliest_arrival_s is None else round(self.earliest_arrival_s - self.t0_s, 3),
            "requested_arrival_s": None if self.requested_arrival_s is None else round(self.requested_arrival_s - self.t0_s, 3),
            "duration_s": round(self.duration_s, 3),
            "path_length_m": round(self.path.length_m, 3),
            "max_steering_deg": round(math.degrees(self.max_steering_rad), 2),
            "steering_limit_deg": round(math.degrees(self.limits.plan_steer_rad), 2),
            "max_speed_mps": round(self.max_speed_m_s, 3),
            "cruise_speed_mps": round(self.profile.cruise_speed_m_s, 3),
            "speed_band_mps": [round(self.limits.v_min_m_s, 3), round(self.limits.v_max_m_s, 3)],
            "accel_limit_mps2": self.limits.accel_m_s2,
            # the car's own stop from v_min when the command drops to 0 (its speed controller's lag), not
            # a commanded ramp: the acceleration limit applies to the ramps only
            "stop_decel_mps2": round(self.limits.v_min_m_s / (2.0 * self.limits.stop_lag_s), 3) if "stop" in self.profile.kind else 0.0,
            "dwell_s": round(self.profile.dwell_s, 3),
            "polynomial_forms": list(self.path.forms),
            "via_points": [[round(s.x_m, 3), round(s.y_m, 3)] for s in self.states[1:-1]],
        }


def via_state(prev_xy: tuple[float, float], via_xy: tuple[float, float], next_xy: tuple[float, float]) -> BoundaryState:
    """A pass-through state at ``via_xy``: heading along the mean of the incoming and outgoing chords,
    steering 0 (ref 003 table 5.1 passes its waypoints with phi = 0)."""
    a1 = math.atan2(via_xy[1] - prev_xy[1], via_xy[0] - prev_xy[0])
    a2 = math.atan2(next_xy[1] - via_xy[1], next_xy[0] - via_xy[0])
    return BoundaryState(via_xy[0], via_xy[1], norm_angle_rad(a1 + 0.5 * norm_angle_rad(a2 - a1)), 0.0)


def plan_timed(start: BoundaryState, goal: BoundaryState, t_start_s: float, arrival_s: float | None,
               limits: TimedLimits | None = None, vias: tuple[BoundaryState, ...] = (), *,
               dwell_first_s: float = 0.0, deadline: float | None = None, tags: tuple[str, ...] = (),
               auto_via: bool = True, path: GeoPath | None = None) -> TimedPlan:
    """Plan from ``start`` (its speed and steering are the current ones) through ``vias`` to ``goal``
    (reached at rest), arriving at the absolute time ``arrival_s`` (None: untimed, at the cruise speed).

    ``auto_via``: when the direct polynomial needs more steering than allowed and no via points were
    given, try a few via points (ahead of the start, behind the goal, beside the chord) and keep the
    shortest path that fits the steering limit.
    ``path``: reuse this geometry (it must run through exactly these states; re-timing candidates).
    ``dwell_first_s``: brake now and wait this long before going on (the "yield" retiming).
    Never raises for an impossible request: the plan comes back with ``feasible`` False, the reason and
    the earliest arrival, timed for that earliest arrival so it can still be driven. ``deadline``
    (a time.perf_counter() value) raises :class:`DeadlineMissed` when passed.
    """
    lim = limits or TimedLimits()
    check_deadline(deadline, "plan_timed")
    steer0 = max(-lim.plan_steer_rad, min(lim.plan_steer_rad, start.steer_rad))
    s0 = BoundaryState(start.x_m, start.y_m, start.yaw_rad, steer0, max(0.0, start.speed_m_s))
    states = (s0, *vias, goal)
    try:
        direct_error: ValueError | None = None
        if path is None:
            try:
                path = build_path(list(states), lim.wheelbase_m)
            except ValueError as e:
                # e.g. a goal behind the start: the direct leg would need a cusp (an in-place reversal);
                # a generated via point may still give a drivable loop
                if not (auto_via and not vias):
                    raise
                direct_error = e
        # a generated via point when there is no direct path, or the direct one turns too tight
        if auto_via and not vias and (path is None or math.atan(lim.wheelbase_m * path.max_abs_kappa) > lim.plan_steer_rad):
            found = _auto_via(s0, goal, lim, deadline)
            if found is not None:
                path, states = found
            elif direct_error is not None:
                raise direct_error
    except ValueError as e:
        empty = SpeedProfile(np.array([0.0]), np.zeros(0), np.zeros(0), np.zeros(0), ())
        dummy = GeoPath(np.array([[s0.x_m, s0.y_m]]), np.array([s0.yaw_rad]), np.zeros(1), np.zeros(1), (), (0.0,))
        return TimedPlan(dummy, empty, t_start_s, arrival_s, False, f"no path: {_no_path_reason(s0, goal, e)}", None,
                         lim, states, tags)
    sp = lim.speed
    S = path.length_m
    v0 = s0.speed_m_s
    reasons: list[str] = []
    feasible = True
    steer_need = math.atan(lim.wheelbase_m * path.max_abs_kappa)
    if steer_need > lim.plan_steer_rad + 1e-6:
        feasible = False
        reasons.append(f"the path needs {math.degrees(steer_need):.1f} deg of steering, the limit is "
                       f"{math.degrees(lim.plan_steer_rad):.1f} deg (turn too tight for the distance; move the goal "
                       f"or give a via point)")
    # brake first when dwelling was asked for
    pre: list[SpeedProfile] = []
    s_pre = 0.0
    t_pre = 0.0
    if dwell_first_s > 0:
        a = sp.accel_m_s2
        d_brake = v0 * v0 / (2 * a)
        brake: SpeedProfile | None = None
        if v0 > 1e-6 and d_brake >= S:
            # no room to stop at the allowed deceleration before the path ends: brake harder over what is
            # left (what the car would have to do) and say so
            feasible = False
            reasons.append(f"asked to stop and wait, but braking from {v0:.2f} m/s at {a:.2f} m/s^2 takes "
                           f"{d_brake:.2f} m and only {S:.2f} m of path are left")
            d_brake = S
            if S > 1e-6:
                a_hard = v0 * v0 / (2.0 * S)
                brake = SpeedProfile(np.array([0.0, v0 / a_hard]), np.array([0.0]), np.array([v0]), np.array([-a_hard]), ("ramp",))
        elif v0 > 1e-6 and d_brake > 0:
            brake = solve_leg(d_brake, v0 / a, v0, 0.0, sp)
        if brake is not None:
            pre.append(brake)
            s_pre, t_pre = d_brake, brake.duration_s
        pre.append(solve_leg(0.0, dwell_first_s, 0.0, 0.0, sp))
        t_pre += dwell_first_s
        v0 = 0.0
    d_rest = S - s_pre
    # the stop tail: in at v_min, lag stop over v_min * lag (see TimedLimits)
    a_stop = lim.v_min_m_s / (2.0 * lim.stop_lag_s)
    d_tail = lim.v_min_m_s * lim.stop_lag_s
    d_reach = lim.v_min_m_s ** 2 / (2.0 * sp.accel_m_s2)  # from rest up to v_min
    use_tail = d_rest > 2.0 * d_tail and lim.v_min_m_s > 0
    if use_tail and v0 < lim.v_min_m_s and (d_rest - d_tail - min(lim.creep_m, max(0.0, d_rest - 3.0 * d_tail))
                                            < d_reach - v0 * v0 / (2.0 * sp.accel_m_s2)):
        use_tail = False  # too short to speed up to v_min before the tail: end at rest instead
    if use_tail:
        settle = math.sqrt(2.0 * min(lim.arrive_tol_m, d_tail) / a_stop)
        t_tail = 2.0 * lim.stop_lag_s
        # a short creep at v_min first, so that the speed controller has settled when the stop starts
        d_creep = min(lim.creep_m, max(0.0, d_rest - 3.0 * d_tail))
        t_creep = d_creep / lim.v_min_m_s
        tail = SpeedProfile(np.array([0.0, t_creep, t_creep + t_tail]), np.array([0.0, d_creep]),
                            np.array([lim.v_min_m_s, lim.v_min_m_s]), np.array([0.0, -a_stop]), ("cruise", "stop"))
        if d_creep <= 0:
            tail = SpeedProfile(np.array([0.0, t_tail]), np.array([0.0]), np.array([lim.v_min_m_s]), np.array([-a_stop]), ("stop",))
        d_main, v_end, t_after = d_rest - d_tail - d_creep, lim.v_min_m_s, t_creep + t_tail - settle
    else:
        settle, tail, d_main, v_end, t_after = 0.0, None, d_rest, 0.0, 0.0
    t_min = t_pre + leg_min_time_s(d_main, v0, v_end, sp) + t_after
    if arrival_s is None:
        from ._profile import leg_time_s

        tau = t_pre + t_after + leg_time_s(d_main, v0, v_end, min(lim.cruise_m_s, sp.v_max_m_s), sp.accel_m_s2)
        tau = max(tau, t_min) if math.isfinite(tau) else t_min
    else:
        tau = arrival_s - t_start_s
    earliest = t_start_s + t_min if math.isfinite(t_min) else None
    try:
        leg = solve_leg(d_main, tau - t_pre - t_after, v0, v_end, sp)
    except LegInfeasible as e:
        feasible = False
        if math.isfinite(e.min_time_s):
            reasons.append(f"arrival in {tau:.2f} s is too early: {S:.2f} m need an average of {S / max(tau, 1e-9):.2f} m/s; "
                           f"with v_max {sp.v_max_m_s:.2f} m/s, {sp.accel_m_s2:.2f} m/s^2 and the stop at v_min the "
                           f"earliest arrival is in {t_min:.2f} s")
            leg = solve_leg(d_main, e.min_time_s, v0, v_end, sp)
        else:
            reasons.append(e.reason)
            # timed as if the car were already slow enough (from rest, or at v_min into the tail when
            # even that is too short from rest)
            v_fb = 0.0 if math.isfinite(leg_min_time_s(d_main, 0.0, v_end, sp)) else v_end
            leg = solve_leg(d_main, max(leg_min_time_s(d_main, v_fb, v_end, sp), 1e-3), v_fb, v_end, sp)
            earliest = None
    if tail is None and lim.v_min_m_s > 0 and d_main > 1e-6 and v0 < lim.v_min_m_s and leg.max_speed_m_s < lim.v_min_m_s - 1e-9:
        # the whole move would stay below the calibrated band, where the car does not move at all
        feasible = False
        reasons.append(f"the goal is {d_main:.2f} m away, less than the car's smallest move of {d_reach + d_tail:.2f} m "
                       f"(from rest up to v_min {lim.v_min_m_s:.2f} m/s at {sp.accel_m_s2:.2f} m/s^2, then its stop)")
        earliest = None
    parts = pre + [leg] + ([tail] if tail is not None else [])
    profile = concat_profiles(parts) if len(parts) > 1 else leg
    if feasible:
        reason = "ok"
    else:
        reason = "; ".join(reasons)
    if steer_need > lim.plan_steer_rad + 1e-6:
        earliest = None  # no timing fixes the geometry
    return TimedPlan(path, profile, t_start_s, arrival_s, feasible, reason, earliest, lim, states, tags, settle)


def _no_path_reason(s0: BoundaryState, goal: BoundaryState, err: ValueError) -> str:
    """Why no path was found, in the user's terms where the geometry says more than ``err``."""
    bearing = math.atan2(goal.y_m - s0.y_m, goal.x_m - s0.x_m)
    behind = math.cos(norm_angle_rad(bearing - s0.yaw_rad)) < 0.0
    if behind and abs(norm_angle_rad(goal.yaw_rad - s0.yaw_rad)) < math.radians(45.0):
        return ("the goal is behind the start with the same heading: it needs reversing (or a loop wider than the "
                "via-point search), which the planner does not do; give a via point or a goal ahead of the start")
    if behind:
        return ("the goal is behind the start: it needs reversing or a turn the planner could not fit; give a via "
                f"point or a goal ahead of the start ({err})")
    return str(err)


def _auto_via(s0: BoundaryState, goal: BoundaryState, lim: TimedLimits,
              deadline: float | None) -> tuple[GeoPath, tuple[BoundaryState, ...]] | None:
    """Shortest steering-feasible path through one generated via point, or None.

    The candidates are a 9 x 9 grid over the box around start and goal, grown by four minimum turning
    radii (coarse paths for the search, the winner rebuilt at full resolution)."""
    r_min = 1.0 / lim.plan_kappa_max
    pad = 4.0 * r_min
    xs = np.linspace(min(s0.x_m, goal.x_m) - pad, max(s0.x_m, goal.x_m) + pad, 9)
    ys = np.linspace(min(s0.y_m, goal.y_m) - pad, max(s0.y_m, goal.y_m) + pad, 9)
    best: tuple[float, tuple[BoundaryState, ...]] | None = None
    for vx in xs:
        check_deadline(deadline, "auto via")
        for vy in ys:
            xy = [(s0.x_m, s0.y_m), (float(vx), float(vy)), (goal.x_m, goal.y_m)]
            if min(math.hypot(vx - s0.x_m, vy - s0.y_m), math.hypot(vx - goal.x_m, vy - goal.y_m)) < r_min:
                continue
            st = (s0, via_state(xy[0], xy[1], xy[2]), goal)
            try:
                p = build_path(list(st), lim.wheelbase_m, spacing_m=1e9)
            except ValueError:
                continue
            if math.atan(lim.wheelbase_m * p.max_abs_kappa) <= 0.95 * lim.plan_steer_rad and (best is None or p.length_m < best[0]):
                best = (p.length_m, st)
    if best is None:
        return None
    path = build_path(list(best[1]), lim.wheelbase_m)
    if math.atan(lim.wheelbase_m * path.max_abs_kappa) > lim.plan_steer_rad:
        return None
    return path, best[1]
