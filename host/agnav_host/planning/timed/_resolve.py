"""Conflict resolution that keeps the arrival time: re-timing first, then deviation points.

Candidates, in order of how little they change (the first clear and feasible one wins):

1. the catch-up replan itself (same path shape from the current state, same arrival time);
2. *yield* briefly (0.5, 1 s): brake, wait for the obstacle to pass, then catch up (same path);
3. *deviate*: a via point beside the predicted conflict (behind a crossing obstacle, or to either side
   of the path), with the same arrival time; the given deviation points (003's) first;
4. longer yields, then wider deviations.

An oncoming obstacle (moving against the robot's heading) is passed, not waited for, as in 003
(fig. 4.4 b): its deviations go first and the waits last.

When no candidate keeps the arrival time, the clear candidate with the earliest arrival is returned
(its plan says ``feasible`` False and carries the new earliest arrival). When none is clear even late,
the same path driven as fast as the car can (*hurry*, early) is the last candidate against movers: a
car that stops where a crossing obstacle is heading is hit standing. A candidate is clear when it
has no space-time conflict over the horizon and no static return within the clearance of its
footprint over the sensed stretch.

Bounded work. Building and checking one candidate costs about 0.5 ms, and a full list has up to ~17,
so one call evaluates at most ``max_candidates`` of them (the base plan, needed to order the list,
counts as one; a call that goes on with a search and must rebuild it builds at least two). When the list is not finished the result says where to go on (``next_index``) and
carries the best late candidate so far; the caller continues at its next control step from there,
keeping its current plan meanwhile (the list is rebuilt from the new state, so the continuation is
approximate: the candidates of one search differ by one control step of motion). Before any
deviation candidate is built, every one whose via point itself is blocked by a static return is
dropped at once (vectorised; exact: the path passes through its via point).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from ...types import FloatArray
from ..base import DeadlineMissed
from ._obstacles import Conflict, SpaceTimeObstacle, first_blocked_s, first_conflict, path_prefix_blocked
from ._path import GeoPath
from ._plan import TimedLimits, TimedPlan, plan_timed, via_state
from ._poly import BoundaryState

__all__ = ["Resolution", "resolve", "hurry_plan", "YIELD_DWELLS_S"]

YIELD_DWELLS_S = (0.5, 1.0, 2.0, 3.0, 4.5)


@dataclass(frozen=True)
class Resolution:
    """``plan`` (None: nothing clear found yet), the ``action`` taken ("replan", "yield 1.5 s",
    "deviate left", ...), candidates built and checked in this call (``tried``), candidates dropped by
    the via-point screen (``screened``), the conflict that started it (if any), ``next_index``: where
    the search goes on at the next call (None: finished), and ``late``: the clear but late candidate
    with the earliest arrival found so far ((arrival, plan, label) or None)."""

    plan: TimedPlan | None
    action: str
    tried: int
    conflict: Conflict | None
    next_index: int | None = None
    late: tuple[float, TimedPlan, str] | None = None
    screened: int = 0


def _clear(plan: TimedPlan, obstacles: Sequence[SpaceTimeObstacle], points: FloatArray, t_now: float, horizon_s: float,
           margin_m: float, static_clear_m: float, static_range_m: float) -> Conflict | None | bool:
    """None when clear; the Conflict (moving) or True (static) otherwise."""
    if len(points):
        if first_blocked_s(plan, points, 0.0, static_range_m, static_clear_m) is not None:
            return True
    return first_conflict(plan, obstacles, t_now, min(t_now + horizon_s, plan.arrival_s + 1.0), margin_m)


def _via_blocked(vias: list[BoundaryState], points: FloatArray, limits: TimedLimits, clear_m: float) -> np.ndarray:
    """(m,) True where the footprint disc at a via point comes within ``clear_m`` of a static point."""
    if not vias or len(points) == 0:
        return np.zeros(len(vias), dtype=bool)
    off = limits.footprint_offset_m
    c = np.array([(v.x_m + off * math.cos(v.yaw_rad), v.y_m + off * math.sin(v.yaw_rad)) for v in vias])
    d2 = (c[:, None, 0] - points[None, :, 0]) ** 2 + (c[:, None, 1] - points[None, :, 1]) ** 2
    lim = limits.radius_m + clear_m
    return np.asarray(d2.min(axis=1) < lim * lim)


def resolve(start: BoundaryState, goal: BoundaryState, t_now_s: float, arrival_s: float | None, limits: TimedLimits,
            vias: tuple[BoundaryState, ...], obstacles: Sequence[SpaceTimeObstacle], points_xy: FloatArray | None = None, *,
            horizon_s: float = 8.0, margin_m: float = 0.1, static_clear_m: float = 0.1, static_range_m: float = 3.0,
            deadline: float | None = None, extra_vias_xy: Sequence[tuple[str, tuple[float, float]]] = (),
            try_yield: bool = True, try_base: bool = True, start_index: int = 0, max_candidates: int | None = None,
            late: tuple[float, TimedPlan, str] | None = None) -> Resolution:
    """Find a plan from ``start`` to ``goal`` arriving at ``arrival_s`` clear of ``obstacles`` (space-time)
    and ``points_xy`` (static returns, (k, 2) m). ``extra_vias_xy`` are (label, point) deviation points
    to try first among the deviations (the ref-003 static deviation point, for instance);
    ``try_yield`` False skips the waiting candidates (useless against a static blockage), ``try_base``
    False skips the plain replan (the ``extra_vias_xy`` then go first).
    ``start_index``/``max_candidates``/``late``: continue a search (see the module docstring); the
    defaults run the whole list in one call. Index 0 is the plain replan, i + 1 the i-th candidate after it.
    Raises :class:`DeadlineMissed` only when the budget runs out before any clear candidate exists."""
    pts = np.zeros((0, 2)) if points_xy is None else np.asarray(points_xy, dtype=float).reshape(-1, 2)
    tried = 0
    screened = 0
    first: Conflict | None = None
    budget = math.inf if max_candidates is None else max(1, int(max_candidates))

    def consider(plan: TimedPlan, action: str) -> TimedPlan | None:
        nonlocal tried, late, first
        tried += 1
        if plan.profile.duration_s <= 0 and plan.path.length_m > 0:
            return None
        if not plan.feasible and plan.earliest_arrival_s is None:
            return None
        c = _clear(plan, obstacles, pts, t_now_s, horizon_s, margin_m, static_clear_m, static_range_m)
        if c is None:
            if plan.feasible:
                return plan
            if late is None or plan.arrival_s < late[0]:
                late = (plan.arrival_s, plan, action)
        elif isinstance(c, Conflict) and first is None:
            first = c
        return None

    def finish(plan: TimedPlan | None, action: str, nxt: int | None = None) -> Resolution:
        return Resolution(plan, action, tried, first, nxt, late, screened)

    try:
        # the plain replan: a candidate itself, the path the waits reuse and where the conflict is
        need_base = (try_base and start_index == 0) or try_yield or len(obstacles) > 0
        first_i = max(start_index - 1, 0)  # into ``order`` below
        base = plan_timed(start, goal, t_now_s, arrival_s, limits, vias, deadline=deadline, auto_via=False) if need_base else None
        if base is not None and try_base and start_index == 0:
            if consider(base, "replan") is not None:
                return finish(base, "replan")
        elif base is not None:
            tried += 1  # built to order the list: counts as work
            budget = max(budget, 2.0)  # and one candidate of the list at least, or the search would not move on
        if first is None and base is not None and len(obstacles):
            first = first_conflict(base, obstacles, t_now_s, min(t_now_s + horizon_s, base.arrival_s + 1.0), margin_m)
        # deviation points: the given ones, then beside the predicted conflict
        devs: list[list[tuple[str, tuple[float, float]]]] = [list(extra_vias_xy), []]
        head_on = False
        c0 = first
        if c0 is not None:
            px, py = c0.robot_xy
            ox, oy = c0.obstacle_xy
            need = math.hypot(px - ox, py - oy) - c0.gap_m + 0.15
            vx, vy = c0.obstacle_v
            sp = math.hypot(vx, vy)
            assert base is not None
            _, _, yaw_b, _, _, _ = base.at(c0.t_s)
            hx, hy = math.cos(float(yaw_b)), math.sin(float(yaw_b))
            head_on = sp > 0.1 and (vx * hx + vy * hy) < -0.7 * sp  # 003: an oncoming obstacle is passed, not waited for
            dirs: list[tuple[str, float, float]] = []
            if sp > 0.1 and not head_on:
                dirs.append(("behind", -vx / sp, -vy / sp))
            lx, ly = -hy, hx  # left of the path
            side = 1.0 if (ox - px) * lx + (oy - py) * ly < 0 else -1.0  # away from the obstacle first
            dirs.append(("left" if side > 0 else "right", side * lx, side * ly))
            dirs.append(("right" if side > 0 else "left", -side * lx, -side * ly))
            for k, bucket in ((1.0, 0), (1.6, 1)):
                for name, ux, uy in dirs:
                    devs[bucket].append((f"deviate {name}", (ox + k * need * ux, oy + k * need * uy)))
        waits = YIELD_DWELLS_S if try_yield else ()
        # order: small waits, first deviations, longer waits, wider deviations (oncoming: deviations first)
        order: list[tuple[str, object]] = []
        if not head_on:
            order += [("yield", d) for d in waits[:2]]
        order += [("dev", d) for d in devs[0]]
        if not head_on:
            order += [("yield", d) for d in waits[2:]]
        order += [("dev", d) for d in devs[1]]
        if head_on:
            order += [("yield", d) for d in waits]
        # deviation candidates as states; drop those too near the ends or with a blocked via point
        nxt_xy = (vias[0].x_m, vias[0].y_m) if vias else (goal.x_m, goal.y_m)
        dev_state: dict[int, BoundaryState] = {}
        for i, (kind, arg) in enumerate(order):
            if kind != "dev" or i < first_i:
                continue
            xy = arg[1]  # type: ignore[index]
            if math.hypot(xy[0] - start.x_m, xy[1] - start.y_m) < 0.6 or math.hypot(xy[0] - goal.x_m, xy[1] - goal.y_m) < 0.4:
                continue
            dev_state[i] = via_state((start.x_m, start.y_m), xy, nxt_xy)
        keys = list(dev_state)
        for i, bad in zip(keys, _via_blocked([dev_state[i] for i in keys], pts, limits, static_clear_m)):
            if bad:
                del dev_state[i]
                screened += 1
        # a deviation whose first leg already runs into a static return is not clear whatever its other legs
        # and its timing (consider() would refuse it): it is not built further (the same verdict, less work)
        blocked_prefix: Callable[[GeoPath], bool] | None = None
        if len(pts):
            def blocked_prefix(g: GeoPath) -> bool:
                return path_prefix_blocked(g, limits, pts, static_range_m, static_clear_m)
        for i in range(first_i, len(order)):
            kind, arg = order[i]
            if kind == "dev" and i not in dev_state:
                continue
            if tried >= budget:
                return finish(None, f"searching ({i + 1} of {len(order) + 1} candidates)", i + 1)
            if kind == "yield":
                dwell = float(arg)  # type: ignore[arg-type]
                assert base is not None
                p = plan_timed(start, goal, t_now_s, arrival_s, limits, vias, dwell_first_s=dwell, deadline=deadline,
                               auto_via=False, path=base.path)
                if consider(p, f"yield {dwell:.1f} s") is not None:
                    return finish(p, f"yield {dwell:.1f} s")
                continue
            label = arg[0]  # type: ignore[index]
            p = plan_timed(start, goal, t_now_s, arrival_s, limits, (dev_state[i], *vias), deadline=deadline, auto_via=False,
                           tags=(label,), reject_prefix=blocked_prefix)
            if consider(p, label) is not None:
                return finish(p, label)
        if late is None and try_yield and base is not None:
            # nothing clear, early or late: the car may be standing where a crossing obstacle will walk
            # (waiting there is no refuge); as fast as the car can go along the same path is the last try
            p = hurry_plan(start, goal, t_now_s, limits, vias, base, deadline)
            tried += 1
            if _clear(p, obstacles, pts, t_now_s, horizon_s, margin_m, static_clear_m, static_range_m) is None:
                return finish(p, "hurry (early)")
    except DeadlineMissed:
        if late is None:
            raise
    if late is not None:
        return finish(late[1], late[2] + " (late)")
    return finish(None, "no clear candidate")


def hurry_plan(start: BoundaryState, goal: BoundaryState, t_now_s: float, limits: TimedLimits,
               vias: tuple[BoundaryState, ...], base: TimedPlan | None = None, deadline: float | None = None) -> TimedPlan:
    """The path from ``start`` through ``vias`` to ``goal`` (``base``'s when given: it must start at ``start``)
    driven as fast as the limits allow; the plan says ``feasible`` False, as it arrives early."""
    return plan_timed(start, goal, t_now_s, t_now_s, limits, vias, deadline=deadline, auto_via=False,
                      path=None if base is None else base.path)
