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
(its plan says ``feasible`` False and carries the new earliest arrival). A candidate is clear when it
has no space-time conflict over the horizon and no static return within the clearance of its
footprint over the sensed stretch.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ...types import FloatArray
from ..base import DeadlineMissed
from ._obstacles import Conflict, SpaceTimeObstacle, first_blocked_s, first_conflict
from ._plan import TimedLimits, TimedPlan, plan_timed, via_state
from ._poly import BoundaryState

__all__ = ["Resolution", "resolve", "YIELD_DWELLS_S"]

YIELD_DWELLS_S = (0.5, 1.0, 2.0, 3.0, 4.5)


@dataclass(frozen=True)
class Resolution:
    """``plan`` (None: nothing clear found), the ``action`` taken ("replan", "yield 1.5 s",
    "deviate left", ...), candidates tried, and the conflict that started it (if any)."""

    plan: TimedPlan | None
    action: str
    tried: int
    conflict: Conflict | None


def _clear(plan: TimedPlan, obstacles: Sequence[SpaceTimeObstacle], points: FloatArray, t_now: float, horizon_s: float,
           margin_m: float, static_clear_m: float, static_range_m: float) -> Conflict | None | bool:
    """None when clear; the Conflict (moving) or True (static) otherwise."""
    if len(points):
        if first_blocked_s(plan, points, 0.0, static_range_m, static_clear_m) is not None:
            return True
    return first_conflict(plan, obstacles, t_now, min(t_now + horizon_s, plan.arrival_s + 1.0), margin_m)


def resolve(start: BoundaryState, goal: BoundaryState, t_now_s: float, arrival_s: float | None, limits: TimedLimits,
            vias: tuple[BoundaryState, ...], obstacles: Sequence[SpaceTimeObstacle], points_xy: FloatArray | None = None, *,
            horizon_s: float = 8.0, margin_m: float = 0.1, static_clear_m: float = 0.1, static_range_m: float = 3.0,
            deadline: float | None = None, extra_vias_xy: Sequence[tuple[str, tuple[float, float]]] = (),
            try_yield: bool = True, try_base: bool = True) -> Resolution:
    """Find a plan from ``start`` to ``goal`` arriving at ``arrival_s`` clear of ``obstacles`` (space-time)
    and ``points_xy`` (static returns, (k, 2) m). ``extra_vias_xy`` are (label, point) deviation points
    to try first among the deviations (the ref-003 static deviation point, for instance);
    ``try_yield`` False skips the waiting candidates (useless against a static blockage), ``try_base``
    False skips the plain replan (the ``extra_vias_xy`` then go first).
    Raises :class:`DeadlineMissed` only when the budget runs out before any clear candidate exists."""
    pts = np.zeros((0, 2)) if points_xy is None else np.asarray(points_xy, dtype=float).reshape(-1, 2)
    tried = 0
    late: tuple[float, TimedPlan, str] | None = None
    first: Conflict | None = None

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

    try:
        base = plan_timed(start, goal, t_now_s, arrival_s, limits, vias, deadline=deadline, auto_via=False)
        if try_base and consider(base, "replan") is not None:
            return Resolution(base, "replan", tried, None)
        if first is None and len(obstacles):
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
        plan_order: list[tuple[str, object]] = []
        if not head_on:
            plan_order += [("yield", d) for d in waits[:2]]
        plan_order += [("dev", d) for d in devs[0]]
        if not head_on:
            plan_order += [("yield", d) for d in waits[2:]]
        plan_order += [("dev", d) for d in devs[1]]
        if head_on:
            plan_order += [("yield", d) for d in waits]
        for kind, arg in plan_order:
            if kind == "yield":
                dwell = float(arg)  # type: ignore[arg-type]
                p = plan_timed(start, goal, t_now_s, arrival_s, limits, vias, dwell_first_s=dwell, deadline=deadline,
                               auto_via=False, path=base.path)
                if consider(p, f"yield {dwell:.1f} s") is not None:
                    return Resolution(p, f"yield {dwell:.1f} s", tried, first)
                continue
            label, xy = arg  # type: ignore[misc]
            d_start = math.hypot(xy[0] - start.x_m, xy[1] - start.y_m)
            d_goal = math.hypot(xy[0] - goal.x_m, xy[1] - goal.y_m)
            if d_start < 0.6 or d_goal < 0.4:
                continue
            nxt = (vias[0].x_m, vias[0].y_m) if vias else (goal.x_m, goal.y_m)
            v = via_state((start.x_m, start.y_m), xy, nxt)
            p = plan_timed(start, goal, t_now_s, arrival_s, limits, (v, *vias), deadline=deadline, auto_via=False,
                           tags=(label,))
            if consider(p, label) is not None:
                return Resolution(p, label, tried, first)
    except DeadlineMissed:
        if late is None:
            raise
    if late is not None:
        return Resolution(late[1], late[2] + " (late)", tried, first)
    return Resolution(None, "no clear candidate", tried, first)
