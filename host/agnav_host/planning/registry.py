"""Planners by name. The CLI (``agnav sim --planner NAME``), the benchmark and the simulator all
build planners through :func:`make_planner`.

Names: ``flb``, ``him``, ``vfh``, ``pbf``, ``apf``, ``subsumption``, ``follow-path`` (``follow_path``
is accepted too). A planner module registers nothing itself; this table is the only place that
knows every planner (planners import :mod:`.base` only).
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from typing import Any

from .base import Planner, RobotSpec, UnknownPlanner

__all__ = ["PLANNERS", "PlannerEntry", "planner_names", "make_planner", "canonical_name", "describe", "sensors_needed"]


@dataclass(frozen=True)
class PlannerEntry:
    module: str  # relative to agnav_host.planning
    cls: str
    summary: str
    sensors: tuple[str, ...] = ()  # what every step needs: "laser" (obs.scan), "sonar" (obs.sonar)


PLANNERS: dict[str, PlannerEntry] = {
    "flb": PlannerEntry("flb", "FlbPlanner", "fuzzy-logic planner, 3 laser sectors, 27 rules, CLA defuzzification (ref 000)", ("laser",)),
    "him": PlannerEntry("him", "HimPlanner", "human-inspired method: direct path or best escape point, D = L + P (ref 000)", ("laser",)),
    "vfh": PlannerEntry("vfh", "VfhPlanner", "vector field histogram: polar histogram, valleys, steer to the best valley", ("laser",)),
    "pbf": PlannerEntry("pbf", "PbfPlanner", "potential-field planner: attractive goal, repulsive laser points", ("laser",)),
    "apf": PlannerEntry("apf", "ApfPlanner", "APF waypoint controller with passive motion safety (ref 001)", ("laser",)),
    "subsumption": PlannerEntry("subsumption", "SubsumptionPlanner", "sonar-ring subsumption, mirror of firmware behaviour.c (ref 002)", ("sonar",)),
    "follow-path": PlannerEntry("follow_path", "FollowPathPlanner", "path following controller (ref 000) on a grid-planned or given path"),
    "timed": PlannerEntry("timed.planner", "TimedPlanner", "time-critical planner: arrive at a set pose at a set time, replan to keep it (ref 003)"),
}

_ALIASES = {"follow_path": "follow-path", "followpath": "follow-path"}


def planner_names() -> list[str]:
    """Registered planner names, in the registry's order."""
    return list(PLANNERS)


def canonical_name(name: str) -> str:
    """The registry name for ``name`` (aliases resolved); :class:`UnknownPlanner` on a miss."""
    n = _ALIASES.get(name.strip().lower(), name.strip().lower())
    if n not in PLANNERS:
        raise UnknownPlanner(f"unknown planner {name!r}; known: {', '.join(PLANNERS)}")
    return n


def sensors_needed(name: str) -> tuple[str, ...]:
    """The sensors planner ``name`` needs at every step ("laser", "sonar"), so that a run without them is
    refused before it starts rather than stopped at its first step."""
    return PLANNERS[canonical_name(name)].sensors


def describe() -> dict[str, str]:
    """name -> one-line summary."""
    return {k: v.summary for k, v in PLANNERS.items()}


def make_planner(name: str, spec: RobotSpec | None = None, params: Any = None) -> Planner:
    """Build the named planner for ``spec`` (defaults: the 0.45 m differential drive of refs 001/002).

    ``params`` is that planner's frozen parameter dataclass (``FlbParams``, ``VfhParams``, ...), a
    dict of its fields (validated by the dataclass), or None for its defaults. A dict may also hold
    ``mover_horizon_s`` (s, 0-10) for any planner but ``timed``: people walking are tracked with the laser
    and let by (:class:`~agnav_host.planning.base.MoverGuard`; follow-path has the field itself)."""
    entry = PLANNERS[canonical_name(name)]
    mod = importlib.import_module(f"{__package__}.{entry.module}")
    cls = getattr(mod, entry.cls)
    horizon = 0.0
    if isinstance(params, dict):
        params = dict(params)
        if "mover_horizon_s" in params and "mover_horizon_s" not in getattr(cls.params_cls, "__dataclass_fields__", {}):
            # any other planner: people walking through the same MoverGuard, wrapped round it
            horizon = params.pop("mover_horizon_s")
            if not isinstance(horizon, (int, float)) or isinstance(horizon, bool) or not 0.0 <= horizon <= 10.0:
                raise ValueError(f"bad parameters for planner {name!r}: mover_horizon_s must be 0-10 s, got {horizon!r}")
            if entry is PLANNERS["timed"]:
                raise ValueError("bad parameters for planner 'timed': it always tracks movers (no mover_horizon_s)")
        try:
            params = cls.params_cls(**params)
        except TypeError as e:
            raise ValueError(f"bad parameters for planner {name!r}: {e}") from None
    planner: Planner = cls(spec or RobotSpec(), params)
    if horizon > 0.0:
        from .base import WithMoverGuard

        planner = WithMoverGuard(planner, float(horizon))  # type: ignore[assignment]
    return planner
