"""Host planners on one interface: observation (pose, goal, laser scan and/or sonar ring, tracked
obstacles) -> :class:`~agnav_host.types.DriveCommand`, chosen by name.

Public surface::

    Planner, RobotSpec                                                        (base)
    PlanningError, NoPathFound, DeadlineMissed, InvalidObservation, UnknownPlanner
    make_planner, planner_names, canonical_name, describe, PLANNERS          (registry)
    PathFollower, PathFollowerParams                                          (ref 000 path following)

Planners (by name): ``flb``, ``him``, ``vfh``, ``pbf``, ``apf``, ``subsumption``, ``follow-path``.
Each planner's parameter dataclass lives in its module (``flb.FlbParams``, ``vfh.VfhParams``, ...).
The benchmark is :mod:`agnav_host.planning.bench`; docs in docs/planning.md.
"""

from .base import (
    DeadlineMissed,
    InvalidObservation,
    NoPathFound,
    Planner,
    PlanningError,
    RobotSpec,
    UnknownPlanner,
)
from .follow_path import PathFollower, PathFollowerParams
from .registry import PLANNERS, canonical_name, describe, make_planner, planner_names

__all__ = [
    "Planner", "RobotSpec", "PlanningError", "NoPathFound", "DeadlineMissed",
    "InvalidObservation", "UnknownPlanner", "make_planner", "planner_names", "canonical_name", "describe", "PLANNERS",
    "PathFollower", "PathFollowerParams",
]
