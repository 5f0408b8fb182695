"""The perception controllers by name, built from a scenario's field: `agnav sim SCENARIO --planner NAME`
(ideal runner, SIL or simavr) runs them like the host planners.

Names (``field_controller_names``):

* ``row-follower``: the centre line between two crop rows (perception.RowFollower); detection method from the
  scenario's ``meta.row_method`` (default ``ransac``).
* ``proximity``: one row at a set distance (perception.ProximityFollower, ref 000): ``meta.follow_offset_m``
  (default 1.0 m), ``meta.follow_side`` = the robot's side of the row (``left`` / ``right``, default
  ``right``), ``meta.row_half_width_m`` = from the row's centre line to the face the laser sees (default 0:
  the distance is kept to the face itself).
* ``rut-follower``: the midline of the ruts seen by the scenario's ``[tilted_laser]`` (perception.RutFollower).
* ``NAME+ground-guard``: any of these or a host planner or the stand-in, with the holes and steps the tilted
  laser sees added to its scan as posts (perception.GroundGuard), e.g. ``goal_seek+ground-guard``.

Speeds: the controller's default (0.5 m/s proximity, 0.4 m/s rows and ruts) or the robot's top speed if lower.
A scenario that lacks what a controller needs (a laser, a tilted laser, a valid ``meta`` entry) raises
:class:`FieldControllerError` (a ValueError) naming the scenario and what is missing.
"""

from __future__ import annotations

from typing import Callable

from .controller import Controller
from .scenario import Scenario

__all__ = ["FIELD_CONTROLLERS", "GUARD_SUFFIX", "FieldControllerError", "field_controller_names", "is_field_controller",
           "make_field_controller"]

FIELD_CONTROLLERS: dict[str, str] = {
    "row-follower": "centre line between two crop rows from the laser (meta.row_method, default ransac; refs 004/000)",
    "proximity": "one row at meta.follow_offset_m (default 1 m), the robot on meta.follow_side of it (ref 000)",
    "rut-follower": "the ruts' midline from the scenario's tilted laser (ref 000)",
}
GUARD_SUFFIX = "+ground-guard"
_ALIASES = {"row_follower": "row-follower", "rut_follower": "rut-follower", "proximity-follower": "proximity",
            "proximity_follower": "proximity"}


class FieldControllerError(ValueError):
    """The scenario cannot run the named field controller (the message says why)."""


def field_controller_names() -> list[str]:
    return list(FIELD_CONTROLLERS)


def _canonical(name: str) -> str:
    n = name.strip().lower()
    return _ALIASES.get(n, n)


def _split_guard(name: str) -> tuple[str, bool]:
    n = name.strip()
    for suffix in (GUARD_SUFFIX, GUARD_SUFFIX.replace("-", "_")):
        if n.lower().endswith(suffix):
            return n[: -len(suffix)], True
    return n, False


def is_field_controller(name: str) -> bool:
    """True for the names this module builds (a base name, or anything with ``+ground-guard``)."""
    base, guard = _split_guard(name)
    return guard or _canonical(base) in FIELD_CONTROLLERS


def _limits(sc: Scenario) -> "object":
    from ..perception import DriveLimits
    from .runner import robot_spec

    spec = robot_spec(sc)
    if spec.kinematics == "ackermann":
        return DriveLimits(kinematics="ackermann", wheelbase_m=spec.wheelbase_m, max_steer_rad=spec.max_steer_rad)
    return DriveLimits(kinematics="diff_drive", max_yaw_rate_rad_s=spec.max_yaw_rate_rad_s,
                       min_turn_radius_m=max(0.3, 0.5 * spec.track_m))


def _tilted_mount(sc: Scenario, name: str) -> "object":
    if sc.tilted_laser is None:
        raise FieldControllerError(f"{name!r} needs a [tilted_laser] in the scenario; {sc.name!r} has none")
    return sc.tilted_laser.perception_mount()


def _meta_num(sc: Scenario, key: str, default: float, lo: float) -> float:
    v = sc.meta.get(key, default)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not v >= lo:
        raise FieldControllerError(f"scenario {sc.name!r}: meta.{key} must be a number >= {lo:g}, got {v!r}")
    return float(v)


def _base_controller(sc: Scenario, name: str) -> Controller:
    from ..perception import (
        ProximityFollower,
        ProximityFollowerParams,
        RowFollower,
        RowFollowerParams,
        RutFollower,
        RutFollowerParams,
        row_method_names,
    )

    if name == "rut-follower":
        return RutFollower(RutFollowerParams(tilted=_tilted_mount(sc, name), limits=_limits(sc),  # type: ignore[arg-type]
                                             speed_m_s=min(0.4, sc.max_speed_m_s)))
    if sc.laser is None:
        raise FieldControllerError(f"{name!r} needs a [laser] in the scenario; {sc.name!r} has none")
    if name == "row-follower":
        method = sc.meta.get("row_method", "ransac")
        if method not in row_method_names():
            raise FieldControllerError(f"scenario {sc.name!r}: meta.row_method must be one of "
                                       f"{', '.join(row_method_names())}, got {method!r}")
        return RowFollower(RowFollowerParams(method=method, speed_m_s=min(0.4, sc.max_speed_m_s), limits=_limits(sc),  # type: ignore[arg-type]
                                             mount=sc.laser.mount))
    # proximity
    side = sc.meta.get("follow_side", "right")
    if side not in ("left", "right"):
        raise FieldControllerError(f"scenario {sc.name!r}: meta.follow_side (the robot's side of the row) must be "
                                   f"'left' or 'right', got {side!r}")
    return ProximityFollower(ProximityFollowerParams(
        side="left" if side == "right" else "right",  # the row is on the robot's other side
        distance_m=_meta_num(sc, "follow_offset_m", 1.0, 0.05), row_half_width_m=_meta_num(sc, "row_half_width_m", 0.0, 0.0),
        speed_m_s=min(0.5, sc.max_speed_m_s), limits=_limits(sc), mount=sc.laser.mount))  # type: ignore[arg-type]


def make_field_controller(sc: Scenario, name: str, make_other: Callable[[Scenario, str], Controller]) -> Controller:
    """The controller ``name`` for ``sc``; ``make_other`` builds a base name that is not a field controller
    (a host planner, the stand-in) for ``+ground-guard``."""
    base, guard = _split_guard(name)
    b = _canonical(base)
    try:
        inner = _base_controller(sc, b) if b in FIELD_CONTROLLERS else make_other(sc, base)
    except FieldControllerError as e:  # name what was asked for: 'rut-follower+ground-guard', not 'rut-follower'
        raise FieldControllerError(str(e).replace(repr(b), repr(name), 1)) from None
    if not guard:
        return inner
    from ..perception import GroundGuard, GroundGuardParams

    return GroundGuard(inner, GroundGuardParams(_tilted_mount(sc, name)))  # type: ignore[arg-type]
