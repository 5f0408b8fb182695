"""Several robots, each with its own timed plan: space-time conflicts between the plans and their
resolution by re-timing or deviation, keeping every arrival time where feasible.

Ref 003 runs up to three robots, each planned on its own, and relies on detection to keep them
apart. AgNav plans them in priority order (earliest arrival first, then the order given): each robot's
plan is checked in space-time against the plans already fixed (a robot before its start and after its
arrival is an obstacle at its start or goal pose) and, on a conflict, resolved with
:func:`~._resolve.resolve` treating those plans as moving obstacles with no uncertainty.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from ._obstacles import Conflict, PlanObstacle, first_conflict
from ._plan import TimedLimits, TimedPlan, plan_timed
from ._poly import BoundaryState
from ._resolve import resolve

__all__ = ["RobotTask", "Coordination", "plan_conflicts", "coordinate"]


@dataclass(frozen=True)
class RobotTask:
    """One robot's mission: start state, goal state, absolute arrival time (None: untimed)."""

    name: str
    start: BoundaryState
    goal: BoundaryState
    arrival_s: float | None
    t_start_s: float = 0.0
    limits: TimedLimits = field(default_factory=TimedLimits)


@dataclass
class Coordination:
    """Result of :func:`coordinate`: the plans by robot name, the conflicts of the independent plans
    (``before``) and of the coordinated ones (``after``, empty when all were resolved), what was done
    to each robot, and whether each still meets its arrival time."""

    plans: dict[str, TimedPlan]
    before: list[tuple[str, str, Conflict]]
    after: list[tuple[str, str, Conflict]]
    actions: dict[str, str]
    on_time: dict[str, bool]


def plan_conflicts(plans: dict[str, TimedPlan], margin_m: float = 0.1, dt_s: float = 0.1) -> list[tuple[str, str, Conflict]]:
    """Every pair of plans whose footprints come within ``margin_m``; the first conflict of each pair."""
    names = list(plans)
    out = []
    for i, a in enumerate(names):
        for b in names[i + 1:]:
            pa, pb = plans[a], plans[b]
            t0 = min(pa.t0_s, pb.t0_s)
            t1 = max(pa.arrival_s, pb.arrival_s)
            c = first_conflict(pa, [PlanObstacle(pb, pb.limits.radius_m)], t0, t1, margin_m, dt_s)
            if c is not None:
                out.append((a, b, c))
    return out


def coordinate(tasks: list[RobotTask], margin_m: float = 0.15, dt_s: float = 0.1) -> Coordination:
    """Plan every task, then make the plans conflict-free in priority order (see the module docstring)."""
    indep = {t.name: plan_timed(t.start, t.goal, t.t_start_s, t.arrival_s, t.limits) for t in tasks}
    before = plan_conflicts(indep, margin_m, dt_s)
    order = sorted(range(len(tasks)), key=lambda i: (tasks[i].arrival_s if tasks[i].arrival_s is not None else float("inf"), i))
    fixed: dict[str, TimedPlan] = {}
    actions: dict[str, str] = {}
    for i in order:
        t = tasks[i]
        obstacles = [PlanObstacle(p, p.limits.radius_m) for p in fixed.values()]
        base = indep[t.name]
        horizon = max(base.arrival_s, max((p.arrival_s for p in fixed.values()), default=0.0)) - t.t_start_s + 1.0
        if not obstacles or first_conflict(base, obstacles, t.t_start_s, t.t_start_s + horizon, margin_m, dt_s) is None:
            fixed[t.name] = base
            actions[t.name] = "as planned"
            continue
        res = resolve(t.start, t.goal, t.t_start_s, t.arrival_s, t.limits, base.states[1:-1], obstacles, None,
                      horizon_s=horizon, margin_m=margin_m)
        if res.plan is None:
            fixed[t.name] = base
            actions[t.name] = "unresolved"
        else:
            fixed[t.name] = res.plan
            actions[t.name] = res.action
    plans = {t.name: fixed[t.name] for t in tasks}
    after = plan_conflicts(plans, margin_m - 1e-6, dt_s)
    on_time = {n: p.feasible for n, p in plans.items()}
    return Coordination(plans, before, after, actions, on_time)
