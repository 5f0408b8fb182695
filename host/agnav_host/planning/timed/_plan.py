"""Timed plans: a ref-003 polynomial path plus a drivable speed profile that ends at the set time."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from functools import lru_cache
from typing import Any, Callable

import numpy as np

from ...calib import SPEED_MAX_CM_S, SPEED_MIN_CM_S
from ...types import FloatArray, norm_angle_rad
from ..base import DeadlineMissed, RobotSpec
from ._path import GeoPath
from ._poly import BoundaryState
from ._candidates import NO_LOOP_TURN_RAD, cc_candidate, dubins_candidate, poly_candidate, reeds_shepp_candidates, via_candidate
from ._profile import LegInfeasible, SpeedLimits, SpeedProfile, concat_profiles, leg_min_time_s, leg_time_s, solve_leg

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
    #: steering rate a plan may ask of the servo, rad/s: two thirds of the hobby servo's 300 deg/s, the rest is the tracker's
    steer_rate_rad_s: float = math.radians(200.0)
    #: straight run-in at the goal of a continuous-curvature path, m: the tracker settles on the goal heading
    #: there (ending on a full-lock turn leaves it 2-3 deg off)
    run_in_m: float = 0.3
    #: top reverse speed, m/s; 0 = no reverse side in the speed calibration (the ref-003 car), so no Reeds-Shepp paths
    reverse_v_max_m_s: float = 0.0

    def __post_init__(self) -> None:
        if not 0 < self.plan_steer_rad <= self.max_steer_rad < math.pi / 2:
            raise ValueError("need 0 < plan_steer_rad <= max_steer_rad < 90 deg")
        if not 0 < self.wheelbase_m:
            raise ValueError("wheelbase_m must be > 0")
        if not self.steer_rate_rad_s > 0:
            raise ValueError("steer_rate_rad_s must be > 0")
        if not (self.reverse_v_max_m_s == 0.0 or self.reverse_v_max_m_s > self.v_min_m_s):
            raise ValueError(f"reverse_v_max_m_s must be 0 (no reverse) or above v_min {self.v_min_m_s:g} m/s")
        SpeedLimits(self.v_min_m_s, self.v_max_m_s, self.accel_m_s2)  # validates the band

    @property
    def speed(self) -> SpeedLimits:
        return SpeedLimits(self.v_min_m_s, self.v_max_m_s, self.accel_m_s2)

    def with_reverse_from(self, speed_table: Any) -> "TimedLimits":
        """These limits with the reverse side of a speed :class:`~agnav_host.calib.CalibTable` (its largest
        reverse speed; none when the table has no negative side)."""
        neg = tuple(getattr(speed_table, "neg_value", ()))
        top = min(float(neg[-1]), float(getattr(speed_table, "value_max", neg[-1]))) if neg else 0.0
        return replace(self, reverse_v_max_m_s=top if top > self.v_min_m_s else 0.0)

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
        return np.column_stack(self.footprint_xy(t_s))

    def footprint_xy(self, t_s: FloatArray) -> tuple[FloatArray, FloatArray]:
        """The x and y columns of :meth:`footprint_at` (the same values)."""
        x, y, yaw = self.path.sample_xy_yaw(self.profile.s_at(np.asarray(t_s, dtype=float) - self.t0_s))
        off = self.limits.footprint_offset_m
        return x + off * np.cos(yaw), y + off * np.sin(yaw)

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
            "path_type": self.path.kind,
            "reverse_m": round(self.path.reverse_m, 3),
            "via_points": [[round(s.x_m, 3), round(s.y_m, 3)] for s in self.states[1:-1]],
        }


def via_state(prev_xy: tuple[float, float], via_xy: tuple[float, float], next_xy: tuple[float, float]) -> BoundaryState:
    """A pass-through state at ``via_xy``: heading along the mean of the incoming and outgoing chords,
    steering 0 (ref 003 table 5.1 passes its waypoints with phi = 0)."""
    a1 = math.atan2(via_xy[1] - prev_xy[1], via_xy[0] - prev_xy[0])
    a2 = math.atan2(next_xy[1] - via_xy[1], next_xy[0] - via_xy[0])
    return BoundaryState(via_xy[0], via_xy[1], norm_angle_rad(a1 + 0.5 * norm_angle_rad(a2 - a1)), 0.0)


#: top speeds the continuous-curvature candidates are built for below v_max, m/s: the servo's steering rate
#: makes the clothoids of a slower path sharper, so it fits nearer goals (a slow plan is capped there)
CC_SPEED_CAPS_M_S = (1.0, 0.6, 0.45)


def plan_timed(start: BoundaryState, goal: BoundaryState, t_start_s: float, arrival_s: float | None,
               limits: TimedLimits | None = None, vias: tuple[BoundaryState, ...] = (), *,
               dwell_first_s: float = 0.0, deadline: float | None = None, tags: tuple[str, ...] = (),
               auto_via: bool = True, path: GeoPath | None = None,
               reject_prefix: Callable[[GeoPath], bool] | None = None) -> TimedPlan:
    """Plan from ``start`` (its speed and steering are the current ones) through ``vias`` to ``goal``
    (reached at rest), arriving at the absolute time ``arrival_s`` (None: untimed, at the cruise speed).

    The geometry is the ref-003 polynomial where it fits the steering limit and the time, else the path
    families (:mod:`._families`): continuous-curvature paths first, then Dubins paths with their stops,
    then Reeds-Shepp paths when ``limits`` has a reverse side. With via points every leg is the polynomial
    or, where that does not fit, the shortest continuous-curvature leg. ``auto_via`` False keeps a plan
    through no via points to the polynomial and the continuous-curvature family (the cheaper set a
    replanning call builds); the earliest arrival is then the earliest of those.
    ``path``: reuse this geometry (it must run through exactly these states; re-timing candidates).
    ``dwell_first_s``: brake now and wait this long before going on (the "yield" retiming).
    ``reject_prefix`` (with via points): a test of the path's first leg; when it says True no path is built
    (the plan comes back with no path, as when no leg fits).
    Never raises for an impossible request: the plan comes back with ``feasible`` False, the reason and
    the earliest arrival, timed for that earliest arrival so it can still be driven. ``deadline``
    (a time.perf_counter() value) raises :class:`DeadlineMissed` when passed.
    """
    lim = limits or TimedLimits()
    check_deadline(deadline, "plan_timed")
    steer0 = max(-lim.plan_steer_rad, min(lim.plan_steer_rad, start.steer_rad))
    s0 = BoundaryState(start.x_m, start.y_m, start.yaw_rad, steer0, max(0.0, start.speed_m_s))
    states = (s0, *vias, goal)
    tau = None if arrival_s is None else arrival_s - t_start_s
    if path is not None:
        return _plan_on(path, s0, states, t_start_s, arrival_s, tau, lim, dwell_first_s, tags)
    if math.hypot(goal.x_m - s0.x_m, goal.y_m - s0.y_m) < 1e-6 and not vias and \
            abs(norm_angle_rad(goal.yaw_rad - s0.yaw_rad)) < 1e-6:
        return _no_path(s0, states, t_start_s, arrival_s, lim, tags, "the start is the goal: there is nothing to drive")
    tried: list[TimedPlan] = []
    why_not = ""

    def fits(p: TimedPlan) -> bool:
        return p.feasible

    # 1. the ref-003 polynomials (the smoothest) where they fit the steering limit and the time
    if vias:
        geo = via_candidate(list(states), lim, lim.v_max_m_s, reject_prefix)
        if geo is not None:
            p = _plan_on(geo, s0, states, t_start_s, arrival_s, tau, lim, dwell_first_s, tags)
            if fits(p):
                return p
            tried.append(p)
    else:
        geo, why_not = poly_candidate(list(states), lim)
        if geo is not None:
            p = _plan_on(geo, s0, states, t_start_s, arrival_s, tau, lim, dwell_first_s, tags)
            if fits(p):
                return p
            tried.append(p)
    check_deadline(deadline, "plan_timed")
    # 2. continuous-curvature paths, the gentlest clothoids first (the servo follows them up to v_max)
    caps = [lim.v_max_m_s] + [c for c in CC_SPEED_CAPS_M_S if lim.v_min_m_s + 0.01 <= c < lim.v_max_m_s]
    if not auto_via:
        caps = caps[:1] + caps[-1:] if len(caps) > 1 else caps
    for k, cap in enumerate(caps):
        if vias:
            if k == 0 or not auto_via:
                continue  # the via legs above already are the continuous-curvature ones at v_max
            cands = [via_candidate(list(states), lim, cap)]
        else:  # with the straight run-in at the goal (the tracker settles there), else without it (sooner)
            turn = math.inf if auto_via else NO_LOOP_TURN_RAD
            cands = [cc_candidate(s0, goal, lim, cap, max_turn_rad=turn)]
            if auto_via:  # a replanning call keeps the run-in: the car it drives must stop on the heading
                cands.append(cc_candidate(s0, goal, lim, cap, run_in=False))
        for geo in cands:
            if geo is None:
                continue
            p = _plan_on(geo, s0, states, t_start_s, arrival_s, tau, lim, dwell_first_s, tags)
            if fits(p):
                return _shorter_reversing(p, s0, goal, states, t_start_s, arrival_s, tau, lim, dwell_first_s, tags) \
                    if auto_via and not vias and lim.reverse_v_max_m_s > 0.0 else p
            tried.append(p)
    if not vias and auto_via:
        check_deadline(deadline, "plan_timed")
        smallest = _smallest_move_m(lim)
        # 3. Dubins paths, stopping at each curvature jump to turn the wheels at rest
        dub = dubins_candidate(s0, goal, lim, smallest)
        geos: list[GeoPath] = [] if dub is None else [dub]
        # 4. Reeds-Shepp paths where the robot has a reverse side
        if lim.reverse_v_max_m_s > 0.0:
            geos += reeds_shepp_candidates(s0, goal, lim, smallest)
        for geo in geos:
            p = _plan_on(geo, s0, states, t_start_s, arrival_s, tau, lim, dwell_first_s, tags)
            if fits(p):
                return p
            tried.append(p)
    timed = [p for p in tried if p.earliest_arrival_s is not None]
    if timed:  # none meets the time: the earliest arrival over the candidates
        best = min(timed, key=lambda p: p.earliest_arrival_s)  # type: ignore[arg-type,return-value]
        first = tried[0]
        if first is not best and first.earliest_arrival_s is None:  # say why the direct path does not do
            return replace(best, reason=f"{first.path.kind}: {first.reason}; {best.path.kind}: {best.reason}")
        return best
    if tried:
        return tried[0]
    return _no_path(s0, states, t_start_s, arrival_s, lim, tags, _no_path_reason(s0, goal, why_not))


#: a forward path this many times longer than a Reeds-Shepp one (a loop round to a goal just behind) gives way to it
REVERSE_PREFERRED_RATIO = 1.5


def _shorter_reversing(p: TimedPlan, s0: BoundaryState, goal: BoundaryState, states: tuple[BoundaryState, ...],
                       t_start_s: float, arrival_s: float | None, tau: float | None, lim: TimedLimits,
                       dwell_first_s: float, tags: tuple[str, ...]) -> TimedPlan:
    """``p`` (a feasible forward plan), or a feasible Reeds-Shepp plan when that is much shorter."""
    for geo in reeds_shepp_candidates(s0, goal, lim, _smallest_move_m(lim)):
        if geo.reverse_m <= 0.0 or REVERSE_PREFERRED_RATIO * geo.length_m >= p.path.length_m:
            continue
        q = _plan_on(geo, s0, states, t_start_s, arrival_s, tau, lim, dwell_first_s, tags)
        if q.feasible:
            return q
    return p


def _smallest_move_m(lim: TimedLimits) -> float:
    """Shortest move the car can make from rest to rest: up to v_min, then its stop."""
    return lim.v_min_m_s ** 2 / (2.0 * lim.accel_m_s2) + 2.0 * lim.v_min_m_s * lim.stop_lag_s


def _no_path(s0: BoundaryState, states: tuple[BoundaryState, ...], t_start_s: float, arrival_s: float | None,
             lim: TimedLimits, tags: tuple[str, ...], why: str) -> TimedPlan:
    empty = SpeedProfile(np.array([0.0]), np.zeros(0), np.zeros(0), np.zeros(0), ())
    dummy = GeoPath(np.array([[s0.x_m, s0.y_m]]), np.array([s0.yaw_rad]), np.zeros(1), np.zeros(1), (), (0.0,), "none")
    return TimedPlan(dummy, empty, t_start_s, arrival_s, False, f"no path: {why}", None, lim, states, tags)


def _tail_for(d_rest: float, v0: float, lim: TimedLimits, sp: SpeedLimits,
              final: bool) -> tuple[float, float, SpeedProfile | None, float, float]:
    """(d_main, v_end, tail profile or None, time after the main leg, settle) of a piece of ``d_rest`` m
    ending at rest: in at v_min, lag stop (see :class:`TimedLimits`). ``final``: the plan's end, where
    arrival is within ``arrive_tol_m``; elsewhere (a stop on the way) the car must be at rest."""
    a_stop = lim.v_min_m_s / (2.0 * lim.stop_lag_s)
    d_tail = lim.v_min_m_s * lim.stop_lag_s
    d_reach = lim.v_min_m_s ** 2 / (2.0 * sp.accel_m_s2)  # from rest up to v_min
    use_tail = d_rest > 2.0 * d_tail and lim.v_min_m_s > 0
    if use_tail and v0 < lim.v_min_m_s and (d_rest - d_tail - min(lim.creep_m, max(0.0, d_rest - 3.0 * d_tail))
                                            < d_reach - v0 * v0 / (2.0 * sp.accel_m_s2)):
        use_tail = False  # too short to speed up to v_min before the tail: end at rest instead
    if not use_tail:
        return d_rest, 0.0, None, 0.0, 0.0
    settle = math.sqrt(2.0 * min(lim.arrive_tol_m, d_tail) / a_stop) if final else 0.0
    t_tail = 2.0 * lim.stop_lag_s
    # a short creep at v_min first, so that the speed controller has settled when the stop starts
    d_creep = min(lim.creep_m, max(0.0, d_rest - 3.0 * d_tail))
    t_creep = d_creep / lim.v_min_m_s
    tail = SpeedProfile(np.array([0.0, t_creep, t_creep + t_tail]), np.array([0.0, d_creep]),
                        np.array([lim.v_min_m_s, lim.v_min_m_s]), np.array([0.0, -a_stop]), ("cruise", "stop"))
    if d_creep <= 0:
        tail = SpeedProfile(np.array([0.0, t_tail]), np.array([0.0]), np.array([lim.v_min_m_s]), np.array([-a_stop]), ("stop",))
    return d_rest - d_tail - d_creep, lim.v_min_m_s, tail, t_creep + t_tail - settle, settle


@lru_cache(maxsize=64)
def _speed_limits(v_min_m_s: float, v_max_m_s: float, accel_m_s2: float) -> SpeedLimits:
    """SpeedLimits (frozen, validated once per band)."""
    return SpeedLimits(v_min_m_s, v_max_m_s, accel_m_s2)


def _plan_on(path: GeoPath, s0: BoundaryState, states: tuple[BoundaryState, ...], t_start_s: float,
             arrival_s: float | None, tau_req: float | None, lim: TimedLimits, dwell_first_s: float,
             tags: tuple[str, ...]) -> TimedPlan:
    """Time ``path`` for the request: the speed law, the verdict, the reason and the earliest arrival."""
    S = path.length_m
    v0 = s0.speed_m_s
    reasons: list[str] = []
    feasible = True
    steer_need = math.atan(lim.wheelbase_m * path.max_abs_kappa)
    if steer_need > lim.plan_steer_rad + 1e-6:
        feasible = False
        reasons.append(f"the path needs {math.degrees(steer_need):.1f} deg of steering, the limit is "
                       f"{math.degrees(lim.plan_steer_rad):.1f} deg")
    # pieces between the stops the path needs (cusps, curvature jumps), each with its speed band
    bounds = [0.0] + [st for st, _ in path.stops] + [S]
    dwells = [dw for _, dw in path.stops]
    pieces: list[tuple[float, SpeedLimits]] = []
    for a, b in zip(bounds[:-1], bounds[1:]):
        rev = path.direction is not None and float(np.interp(0.5 * (a + b), path.s, path.direction)) < 0.0
        top = lim.reverse_v_max_m_s if rev else lim.v_max_m_s
        top = min(top, path.speed_cap_m_s)
        if top <= lim.v_min_m_s + 1e-6:
            sp = _speed_limits(lim.v_min_m_s, lim.v_min_m_s + 1e-6, lim.accel_m_s2)
            feasible = False
            reasons.append(f"the servo's steering rate allows only {top:.2f} m/s on this path, below the speed band")
        else:
            sp = _speed_limits(lim.v_min_m_s, top, lim.accel_m_s2)
        pieces.append((b - a, sp))
    if v0 > path.speed_cap_m_s + 1e-6:
        feasible = False
        reasons.append(f"at {v0:.2f} m/s the servo's steering rate cannot follow this path's clothoids "
                       f"(up to {path.speed_cap_m_s:.2f} m/s)")
    if v0 > 1e-6 and path.stops and path.stops[0][0] < v0 * v0 / (2.0 * lim.accel_m_s2):
        feasible = False
        reasons.append(f"the path's first stop is {path.stops[0][0]:.2f} m away, less than the braking distance from {v0:.2f} m/s")
    # brake first when dwelling was asked for (first piece)
    pre: list[SpeedProfile] = []
    s_pre = 0.0
    t_pre = 0.0
    sp0 = pieces[0][1]
    if dwell_first_s > 0:
        a = sp0.accel_m_s2
        d_brake = v0 * v0 / (2 * a)
        S0 = pieces[0][0]
        brake: SpeedProfile | None = None
        if v0 > 1e-6 and d_brake >= S0:
            # no room to stop at the allowed deceleration before the path ends: brake harder over what is
            # left (what the car would have to do) and say so
            feasible = False
            reasons.append(f"asked to stop and wait, but braking from {v0:.2f} m/s at {a:.2f} m/s^2 takes "
                           f"{d_brake:.2f} m and only {S0:.2f} m of path are left")
            d_brake = S0
            if S0 > 1e-6:
                a_hard = v0 * v0 / (2.0 * S0)
                brake = SpeedProfile(np.array([0.0, v0 / a_hard]), np.array([0.0]), np.array([v0]), np.array([-a_hard]), ("ramp",))
        elif v0 > 1e-6 and d_brake > 0:
            brake = solve_leg(d_brake, v0 / a, v0, 0.0, sp0)
        if brake is not None:
            pre.append(brake)
            s_pre, t_pre = d_brake, brake.duration_s
        pre.append(solve_leg(0.0, dwell_first_s, 0.0, 0.0, sp0))
        t_pre += dwell_first_s
        v0 = 0.0
    # per piece: the main leg (d, v_start, v_end, limits), its tail and the time after it
    legs: list[tuple[float, float, float, SpeedLimits, SpeedProfile | None, float]] = []
    settle = 0.0
    d_reach = lim.v_min_m_s ** 2 / (2.0 * lim.accel_m_s2)
    d_tail = lim.v_min_m_s * lim.stop_lag_s
    for k, (d, sp) in enumerate(pieces):
        last = k == len(pieces) - 1
        v_s = v0 if k == 0 else 0.0
        d_rest = d - (s_pre if k == 0 else 0.0)
        d_main, v_end, tail, t_after, st = _tail_for(d_rest, v_s, lim, sp, last)
        if last:
            settle = st
        legs.append((d_main, v_s, v_end, sp, tail, t_after))
    t_mins = [leg_min_time_s(d, vs, ve, sp) for d, vs, ve, sp, _, _ in legs]
    t_min = t_pre + sum(t_mins) + sum(t for *_, t in legs) + sum(dwells)
    if tau_req is None:
        tau = t_pre + sum(dwells) + sum(t for *_, t in legs)
        for (d, vs, ve, sp, _, _), tm in zip(legs, t_mins):
            tc = leg_time_s(d, vs, ve, min(lim.cruise_m_s, sp.v_max_m_s), sp.accel_m_s2)
            tau += tc if math.isfinite(tc) else tm
        tau = max(tau, t_min) if math.isfinite(tau) else t_min
    else:
        tau = tau_req
    earliest: float | None = t_start_s + t_min if math.isfinite(t_min) else None
    spare = tau - t_min
    total_d = sum(max(d, 0.0) for d, *_ in legs) or 1.0
    parts: list[SpeedProfile] = list(pre)
    late = spare < -1e-6 and math.isfinite(t_min)
    if late:
        feasible = False
        reasons.append(f"arrival in {tau:.2f} s is too early: {S:.2f} m need an average of {S / max(tau, 1e-9):.2f} m/s; "
                       f"with v_max {min(lim.v_max_m_s, path.speed_cap_m_s):.2f} m/s, {lim.accel_m_s2:.2f} m/s^2 and the stop at v_min the "
                       f"earliest arrival is in {t_min:.2f} s")
    for k, ((d, vs, ve, sp, tail, _), tm) in enumerate(zip(legs, t_mins)):
        if k > 0:
            parts.append(solve_leg(0.0, dwells[k - 1], 0.0, 0.0, sp))
        try:
            if not math.isfinite(tm):
                raise LegInfeasible(f"cannot {'brake' if ve < vs else 'speed up'} from {vs:.2f} to {ve:.2f} m/s within {d:.2f} m",
                                    math.inf)
            share = 0.0 if late or not math.isfinite(spare) else spare * max(d, 0.0) / total_d
            leg = solve_leg(d, tm + share, vs, ve, sp)
        except LegInfeasible as e:
            feasible = False
            reasons.append(e.reason)
            # timed as if the car were already slow enough (from rest, or at v_min into the tail when
            # even that is too short from rest)
            v_fb = 0.0 if math.isfinite(leg_min_time_s(d, 0.0, ve, sp)) else ve
            leg = solve_leg(d, max(leg_min_time_s(d, v_fb, ve, sp), 1e-3), v_fb, ve, sp)
            earliest = None
        if tail is None and lim.v_min_m_s > 0 and d > 1e-6 and vs < lim.v_min_m_s and leg.max_speed_m_s < lim.v_min_m_s - 1e-9:
            # the move would stay below the calibrated band, where the car does not move at all
            feasible = False
            reasons.append(f"{'the goal' if len(legs) == 1 else 'a piece between two stops'} is {d:.2f} m away, less than the "
                           f"car's smallest move of {d_reach + d_tail:.2f} m (from rest up to v_min {lim.v_min_m_s:.2f} m/s at "
                           f"{lim.accel_m_s2:.2f} m/s^2, then its stop)")
            earliest = None
        parts.append(leg)
        if tail is not None:
            parts.append(tail)
    profile = concat_profiles(parts) if len(parts) > 1 else parts[0]
    if steer_need > lim.plan_steer_rad + 1e-6:
        earliest = None  # no timing fixes the geometry
    reason = "ok" if feasible else "; ".join(dict.fromkeys(reasons))
    return TimedPlan(path, profile, t_start_s, arrival_s, feasible, reason, earliest, lim, states, tags, settle)


def _no_path_reason(s0: BoundaryState, goal: BoundaryState, why: str) -> str:
    """Why no path was found, in the user's terms."""
    return why or "no path family reaches the goal from the start within the steering limit"
