"""A scenario's view of the controller registry: the context controllers are built from when a scenario runs
(`agnav sim SCENARIO --planner NAME`, the SIL, simavr), read from the scenario's robot, lasers and ``[meta]``.

The field of a scenario (:func:`field_from_meta`):

* ``meta.row_method``: how the row follower finds crop rows (default ``ransac``);
* ``meta.follow_offset_m`` (default 1.0 m), ``meta.follow_side`` = the robot's side of the row (``left`` /
  ``right``, default ``right``), ``meta.row_half_width_m`` = from the row's centre line to the face the laser sees
  (default 0: the distance is kept to the face itself): the proximity follower;
* ``meta.first_turn`` (``left`` / ``right``) and ``meta.lanes_per_turn`` (default 1): the row navigator's
  headland turns, for good; a scenario with a ``[field]`` gives it its turn pattern and row spacing instead.

Names and what each needs are in :mod:`agnav_host.planning.registry` (``row-follower``, ``row-navigator``,
``proximity``, ``rut-follower``, any controller with ``+ground-guard`` or ``+mover-guard``). A scenario that lacks
what a controller needs (a laser, a tilted laser, a valid ``meta`` entry) raises :class:`FieldControllerError`
(a ValueError) naming the scenario and what is missing.
"""

from __future__ import annotations

from typing import Any

from ..planning.registry import (
    CONTROLLERS,
    ControllerContext,
    ControllerError,
    FieldDescription,
    make_controller,
    sensors_needed,
    split_controller_name,
)
from .controller import Controller
from .scenario import Scenario

__all__ = ["FieldControllerError", "is_field_controller", "field_from_meta", "scenario_context",
           "make_scenario_controller"]


class FieldControllerError(ControllerError):
    """The scenario cannot run the named controller (the message says why)."""


def is_field_controller(name: str) -> bool:
    """True for a field controller's name, or any name with a wrapper (``+ground-guard``)."""
    try:
        base, wraps = split_controller_name(name)
    except ValueError:
        return False
    return bool(wraps) or CONTROLLERS[base].kind == "field"


def _meta_num(sc: Scenario, key: str, default: float, lo: float) -> float:
    v = sc.meta.get(key, default)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not v >= lo:
        raise FieldControllerError(f"scenario {sc.name!r}: meta.{key} must be a number >= {lo:g}, got {v!r}")
    return float(v)


def field_from_meta(sc: Scenario) -> FieldDescription:
    """The scenario's field description from its ``[meta]`` (keys in the module docstring)."""
    from ..perception import row_method_names

    side = sc.meta.get("follow_side", "right")
    if side not in ("left", "right"):
        raise FieldControllerError(f"scenario {sc.name!r}: meta.follow_side (the robot's side of the row) must be "
                                   f"'left' or 'right', got {side!r}")
    method = sc.meta.get("row_method", "ransac")
    if method not in row_method_names():
        raise FieldControllerError(f"scenario {sc.name!r}: meta.row_method must be one of "
                                   f"{', '.join(row_method_names())}, got {method!r}")
    turn = sc.meta.get("first_turn", "left")
    if turn not in ("left", "right"):
        raise FieldControllerError(f"scenario {sc.name!r}: meta.first_turn must be 'left' or 'right', got {turn!r}")
    lanes = sc.meta.get("lanes_per_turn", 1)
    if isinstance(lanes, bool) or not isinstance(lanes, int) or not 1 <= lanes <= 20:
        raise FieldControllerError(f"scenario {sc.name!r}: meta.lanes_per_turn must be a whole number 1-20, got {lanes!r}")
    task = sc.field  # a whole field: the row navigator drives its pattern
    return FieldDescription(row_side=side, row_offset_m=_meta_num(sc, "follow_offset_m", 1.0, 0.05),
                            row_half_width_m=_meta_num(sc, "row_half_width_m", 0.0, 0.0), row_method=method,
                            first_turn=turn, lanes_per_turn=lanes, pattern=task.pattern if task is not None else "",
                            row_spacing_m=task.row_spacing_m if task is not None else 0.75)


def scenario_context(sc: Scenario, standin: Any = None, field: FieldDescription | None = None) -> ControllerContext:
    """The registry's context for a run of ``sc``: its robot (``sim.runner.robot_spec``), field (``field``, else
    :func:`field_from_meta`), laser mounts and ``[meta.planner_params]``; ``standin``: the stand-in's gains (None:
    from the robot)."""
    from .runner import robot_spec

    table = sc.meta.get("planner_params", {})
    return ControllerContext(spec=robot_spec(sc), field=field if field is not None else field_from_meta(sc),
                             laser_mount=sc.laser.mount if sc.laser is not None else None,
                             tilted=sc.tilted_laser.perception_mount() if sc.tilted_laser is not None else None,
                             params=table if isinstance(table, dict) else {}, standin=standin,
                             where=f"scenario {sc.name!r}")


def make_scenario_controller(sc: Scenario, name: str, standin: Any = None) -> Controller:
    """Controller ``name`` for a run of ``sc`` (UnknownPlanner for an unknown name, FieldControllerError when the
    scenario lacks what it needs)."""
    base, wraps = split_controller_name(name)
    need = sensors_needed(name)
    fielded = CONTROLLERS[base].kind == "field" or bool(wraps)
    if fielded:
        if "tilted_laser" in need and sc.tilted_laser is None:
            raise FieldControllerError(f"{name!r} needs a [tilted_laser] in the scenario; {sc.name!r} has none")
        if CONTROLLERS[base].kind == "field" and "laser" in need and sc.laser is None:
            raise FieldControllerError(f"{name!r} needs a [laser] in the scenario; {sc.name!r} has none")
    # planners and the stand-in: a bad [meta] field entry is no concern of theirs
    ctx = scenario_context(sc, standin, None if fielded else FieldDescription())
    try:
        return make_controller(name, ctx)
    except ControllerError as e:
        if isinstance(e, FieldControllerError):
            raise
        raise FieldControllerError(str(e)) from None
