"""Every controller by name: the one registry the simulator, the SIL and ``agnav run`` build from.

Kinds (:data:`CONTROLLERS`):

* **planners** (``flb``, ``him``, ``vfh``, ``pbf``, ``apf``, ``subsumption``, ``follow-path``, ``timed``): built
  from a :class:`~.base.RobotSpec` by :func:`make_planner`;
* **field controllers** (``row-follower``, ``row-navigator``, ``proximity``, ``rut-follower``): perception
  controllers built from a :class:`FieldDescription` (row side and offset, row method, turn pattern) and the
  lasers' mounting poses;
* the **stand-in** ``goal_seek`` (a reactive gap follower that lets any scenario run end to end).

Wrappers add a safety guard round any of them with a suffix, in order: ``NAME+ground-guard`` (holes and steps
the tilted laser sees become posts in the scan, perception.GroundGuard) and ``NAME+mover-guard`` (people
walking, tracked with the laser, are let by: :class:`~.base.WithMoverGuard`, horizon
``ControllerContext.mover_horizon_s``).

Each entry declares the sensors its steps need (``laser``, ``sonar``, ``tilted_laser``); :func:`sensors_needed`
adds the wrappers' so that a run without them is refused before it starts. A planner module registers nothing
itself; this table is the only place that knows every controller.
"""

from __future__ import annotations

import importlib
from dataclasses import dataclass
from dataclasses import field as dc_field
from typing import Any

import math
from collections.abc import Mapping
from typing import TYPE_CHECKING

from ..types import Pose2D
from .base import Planner, RobotSpec, UnknownPlanner

if TYPE_CHECKING:
    from ..perception import TiltedMount
    from ..sim.controller import Controller, GoalSeekParams

__all__ = ["PLANNERS", "PlannerEntry", "planner_names", "make_planner", "canonical_name", "describe", "sensors_needed",
           "CONTROLLERS", "ControllerEntry", "WRAPPERS", "FieldDescription", "ControllerContext", "ControllerError",
           "controller_names", "split_controller_name", "make_controller", "parse_turn_pattern",
           "ROW_SIDES"]


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
    """The sensors controller ``name`` (wrappers included) needs at every step ("laser", "sonar",
    "tilted_laser"), so that a run without them is refused before it starts rather than stopped at its first
    step."""
    base, wraps = split_controller_name(name)
    need = list(CONTROLLERS[base].sensors)
    for w in wraps:
        need += [s for s in WRAPPERS[w][1] if s not in need]
    return tuple(need)


def describe() -> dict[str, str]:
    """planner name -> one-line summary (the planners only; :data:`CONTROLLERS` has every controller)."""
    return {k: v.summary for k, v in PLANNERS.items()}


# ---- the whole registry: stand-in, planners, field controllers, wrappers ---------------------------------------


class ControllerError(ValueError):
    """A controller cannot be built for this run (the message says what is missing or wrong)."""


ROW_SIDES = ("left", "right")


def parse_turn_pattern(text: str) -> tuple[str, int]:
    """``SIDE[,N]`` -> (first turn side, lanes per turn): ``left`` (next lane on the left, then alternating),
    ``right,2`` (skip one lane each turn). ValueError with the accepted forms."""
    side, _, n = text.strip().lower().partition(",")
    if side not in ROW_SIDES:
        raise ValueError(f"turn pattern {text!r}: SIDE[,N] with SIDE left or right (the first headland turn) and N "
                         "the lanes each turn moves over (default 1)")
    try:
        lanes = int(n) if n.strip() else 1
    except ValueError:
        lanes = 0
    if not 1 <= lanes <= 20:
        raise ValueError(f"turn pattern {text!r}: N, the lanes each turn moves over, must be a whole number 1-20")
    return side, lanes


@dataclass(frozen=True)
class FieldDescription:
    """The field a field controller works in (SI units).

    ``row_side``: the robot's side of the row it follows at ``row_offset_m`` (proximity; ``right`` = the row is on
    the robot's left); ``row_half_width_m``: from the row's centre line to the face the laser sees;
    ``row_method``: how crop rows are found in a scan (perception.row_method_names: ``ransac``, ``lsq``, ...);
    ``pattern``: the row navigator's turns in the Field Robot Event's notation (``S-1L-2R-F``, see
    :mod:`.row_navigator`); without one it turns ``lanes_per_turn`` lanes to ``first_turn`` and then to alternate
    sides for good; ``row_spacing_m``: the rows' spacing; ``reverse``: the row navigator may back up on the
    headland (False: omega turns where the lanes are closer than two turning radii)."""

    row_side: str = "right"
    row_offset_m: float = 1.0
    row_half_width_m: float = 0.0
    row_method: str = "ransac"
    first_turn: str = "left"
    lanes_per_turn: int = 1
    pattern: str = ""
    row_spacing_m: float = 0.75
    reverse: bool = True

    def problem(self) -> str:
        """Why this description cannot be used ("" when it can)."""
        from ..perception import row_method_names

        if self.row_side not in ROW_SIDES:
            return f"row side (the robot's side of the row) must be 'left' or 'right', got {self.row_side!r}"
        if not (isinstance(self.row_offset_m, (int, float)) and math.isfinite(self.row_offset_m) and self.row_offset_m >= 0.05):
            return f"row offset must be a number >= 0.05 m, got {self.row_offset_m!r}"
        if not (isinstance(self.row_half_width_m, (int, float)) and math.isfinite(self.row_half_width_m)
                and self.row_half_width_m >= 0):
            return f"row half width must be a number >= 0 m, got {self.row_half_width_m!r}"
        if self.row_method not in row_method_names():
            return f"row method must be one of {', '.join(row_method_names())}, got {self.row_method!r}"
        if self.first_turn not in ROW_SIDES or not 1 <= self.lanes_per_turn <= 20:
            return f"turn pattern must be left or right and 1-20 lanes, got {self.first_turn!r}, {self.lanes_per_turn!r}"
        if self.pattern:
            from .row_navigator import PatternError, parse_pattern

            try:
                parse_pattern(self.pattern)
            except PatternError as e:
                return str(e)
        if not (isinstance(self.row_spacing_m, (int, float)) and math.isfinite(self.row_spacing_m)
                and 0.2 <= self.row_spacing_m <= 10.0):
            return f"row spacing must be a number 0.2-10 m, got {self.row_spacing_m!r}"
        return ""


@dataclass(frozen=True)
class ControllerContext:
    """What a controller is built from: the robot, the field, where the lasers sit, per-planner parameters.

    ``laser_mount`` is the horizontal scanner's pose on the robot (None: no laser); ``tilted`` the tilted
    scanner's (None: none); ``params`` maps a planner name to its parameter table; ``standin`` the stand-in's
    gains (None: derived from ``spec``); ``where`` names the run in error messages."""

    spec: RobotSpec = dc_field(default_factory=RobotSpec)
    field: FieldDescription = dc_field(default_factory=FieldDescription)
    laser_mount: Pose2D | None = None
    tilted: "TiltedMount | None" = None
    params: Mapping[str, Any] = dc_field(default_factory=dict)
    standin: "GoalSeekParams | None" = None
    mover_horizon_s: float = 2.0
    where: str = "this run"


@dataclass(frozen=True)
class ControllerEntry:
    kind: str  # "planner", "field" or "stand-in"
    summary: str
    sensors: tuple[str, ...] = ()  # "laser", "sonar", "tilted_laser"


CONTROLLERS: dict[str, ControllerEntry] = {
    "goal_seek": ControllerEntry("stand-in", "reactive gap following to the goal on the laser (a stand-in)", ("laser",)),
    **{n: ControllerEntry("planner", e.summary, e.sensors) for n, e in PLANNERS.items()},
    "row-follower": ControllerEntry("field", "centre line between two crop rows from the laser (row method; refs 004/000)",
                                    ("laser",)),
    "row-navigator": ControllerEntry("field", "a whole field: follow a lane, find the rows' end, count the rows on "
                                              "the headland, turn into the lane the pattern names (S-1L-2R-F), stop "
                                              "at F (ref 000; the Field Robot Event)", ("laser",)),
    "proximity": ControllerEntry("field", "one row at the row offset, the robot on the row side of it (ref 000)", ("laser",)),
    "rut-follower": ControllerEntry("field", "the ruts' midline from the tilted laser (ref 000)", ("tilted_laser",)),
}
WRAPPERS: dict[str, tuple[str, tuple[str, ...]]] = {
    "ground-guard": ("holes and steps the tilted laser sees added to the scan as posts (ref 000)", ("tilted_laser",)),
    "mover-guard": ("people walking, tracked with the laser, let by (stand while one would come near)", ("laser",)),
}
_CONTROLLER_ALIASES = {**_ALIASES, "row_follower": "row-follower", "rut_follower": "rut-follower",
                       "row_navigator": "row-navigator", "proximity-follower": "proximity",
                       "proximity_follower": "proximity", "goal-seek": "goal_seek"}


def controller_names() -> list[str]:
    """Every base name :func:`make_controller` builds, in the registry's order (wrappers go on as suffixes)."""
    return list(CONTROLLERS)


def split_controller_name(name: str) -> tuple[str, tuple[str, ...]]:
    """``him+ground-guard`` -> (``him``, (``ground-guard``,)); the base resolved through the aliases, each wrapper
    checked. :class:`UnknownPlanner` (a ValueError) names what is unknown and lists the names."""
    parts = [p.strip() for p in name.split("+")]
    base = _CONTROLLER_ALIASES.get(parts[0].lower(), parts[0].lower())
    if base not in CONTROLLERS:
        raise UnknownPlanner(f"unknown planner {parts[0]!r}; known: {', '.join(CONTROLLERS)} "
                             f"(wrappers: {', '.join('+' + w for w in WRAPPERS)})")
    wraps = []
    for w in parts[1:]:
        wn = w.lower().replace("_", "-")
        if wn not in WRAPPERS:
            raise UnknownPlanner(f"unknown wrapper {'+' + w!r} in {name!r}; known: {', '.join('+' + k for k in WRAPPERS)}")
        wraps.append(wn)
    return base, tuple(wraps)


def _drive_limits(spec: RobotSpec) -> Any:
    from ..perception import DriveLimits

    if spec.kinematics == "ackermann":
        return DriveLimits(kinematics="ackermann", wheelbase_m=spec.wheelbase_m, max_steer_rad=spec.max_steer_rad)
    return DriveLimits(kinematics="diff_drive", max_yaw_rate_rad_s=spec.max_yaw_rate_rad_s,
                       min_turn_radius_m=max(0.3, 0.5 * spec.track_m))


def _need_laser(ctx: ControllerContext, name: str) -> Pose2D:
    if ctx.laser_mount is None:
        raise ControllerError(f"{name!r} needs a laser; {ctx.where} has none")
    return ctx.laser_mount


def _need_tilted(ctx: ControllerContext, name: str) -> "TiltedMount":
    if ctx.tilted is None:
        raise ControllerError(f"{name!r} needs a tilted laser; {ctx.where} has none")
    return ctx.tilted


def _field_controller(base: str, ctx: ControllerContext, label: str) -> "Controller":
    from ..perception import (
        ProximityFollower,
        ProximityFollowerParams,
        RowFollower,
        RowFollowerParams,
        RutFollower,
        RutFollowerParams,
    )

    spec, f = ctx.spec, ctx.field
    why = f.problem()
    if why:
        raise ControllerError(f"{label!r} in {ctx.where}: {why}")
    limits = _drive_limits(spec)
    if base == "rut-follower":
        return RutFollower(RutFollowerParams(tilted=_need_tilted(ctx, label), limits=limits,
                                             speed_m_s=min(0.4, spec.max_speed_m_s)))
    mount = _need_laser(ctx, label)
    if base in ("row-follower", "row-navigator"):
        follower = RowFollowerParams(method=f.row_method, speed_m_s=min(0.4, spec.max_speed_m_s), limits=limits,
                                     mount=mount)
        if base == "row-follower":
            return RowFollower(follower)
        return _row_navigator(spec, f, follower)
    return ProximityFollower(ProximityFollowerParams(
        side="left" if f.row_side == "right" else "right",  # the row is on the robot's other side
        distance_m=float(f.row_offset_m), row_half_width_m=float(f.row_half_width_m),
        speed_m_s=min(0.5, spec.max_speed_m_s), limits=limits, mount=mount))


def _row_navigator(spec: RobotSpec, f: FieldDescription, follower: Any) -> "Controller":
    """The row navigator for ``spec`` on field ``f``: its turns from the pattern (or the first side and lane count,
    for good); a differential drive turns no tighter than its track (the firmware's 45 deg steering limit turns it
    like a car of wheelbase = track); a car that cannot crawl (a speed table with a least speed) never reverses."""
    from dataclasses import replace

    from ..perception import DriveLimits, RowParams
    from .row_navigator import RowNavigator, RowNavigatorParams, Turn, parse_pattern

    limits = follower.limits
    if spec.kinematics == "diff_drive":
        limits = DriveLimits(kinematics="diff_drive", max_yaw_rate_rad_s=spec.max_yaw_rate_rad_s,
                             min_turn_radius_m=max(0.3, spec.track_m))
    rows = replace(RowParams(), expected_spacing_m=float(f.row_spacing_m))
    speed = max(follower.speed_m_s, 1.05 * spec.min_speed_m_s)  # a car's least speed (its speed table's first step)
    # in a field of gaps and weeds: a detection far off the lane it is in, or of the wrong spacing, counts little
    follower = replace(follower, limits=limits, rows=rows, speed_m_s=speed, gate_m=0.05, gate_rad=math.radians(5.0),
                       gate_spacing=0.15)
    turns = parse_pattern(f.pattern) if f.pattern else (Turn(f.first_turn, f.lanes_per_turn),)
    return RowNavigator(RowNavigatorParams(
        follower=follower, pattern=turns, finish=bool(f.pattern), row_spacing_m=float(f.row_spacing_m),
        radius_m=spec.radius_m, footprint_offset_m=spec.footprint_offset_m,
        reverse=f.reverse and not (spec.kinematics == "ackermann" and spec.min_speed_m_s > 0.0),
        min_speed_m_s=1.05 * spec.min_speed_m_s))


def _standin_params(spec: RobotSpec) -> "GoalSeekParams":
    from ..sim.controller import GoalSeekParams

    if spec.kinematics == "ackermann":
        return GoalSeekParams(kinematics="ackermann", radius_m=spec.radius_m, max_speed_m_s=spec.max_speed_m_s,
                              min_speed_m_s=spec.min_speed_m_s, wheelbase_m=spec.wheelbase_m,
                              max_steer_rad=spec.max_steer_rad, margin_m=0.1, lookahead_m=2.5,
                              footprint_offset_m=spec.footprint_offset_m)
    return GoalSeekParams(kinematics="diff_drive", radius_m=spec.radius_m, max_speed_m_s=spec.max_speed_m_s)


def make_controller(name: str, ctx: ControllerContext | None = None) -> "Controller":
    """Build controller ``name`` (a base name of :data:`CONTROLLERS` with optional ``+wrapper`` suffixes) for
    ``ctx``. UnknownPlanner for an unknown name, ControllerError when the run lacks what it needs, ValueError
    for bad planner parameters."""
    from ..sim.controller import GoalSeek

    c = ctx or ControllerContext()
    base, wraps = split_controller_name(name)
    entry = CONTROLLERS[base]
    ctrl: Any
    if entry.kind == "planner":
        table = c.params.get(base) if isinstance(c.params, Mapping) else None
        ctrl = make_planner(base, c.spec, dict(table) if isinstance(table, Mapping) else None)
    elif entry.kind == "stand-in":
        ctrl = GoalSeek(c.standin or _standin_params(c.spec))
    else:
        ctrl = _field_controller(base, c, name)
    for w in wraps:
        if w == "ground-guard":
            from ..perception import GroundGuard, GroundGuardParams

            ctrl = GroundGuard(ctrl, GroundGuardParams(_need_tilted(c, name)))
        else:
            from .base import WithMoverGuard

            if base == "timed":
                raise ControllerError("'timed+mover-guard': the timed planner tracks people itself (no mover guard)")
            if not hasattr(ctrl, "spec"):
                raise ControllerError(f"{name!r}: the mover guard goes round a planner, not a field controller")
            ctrl = WithMoverGuard(ctrl, c.mover_horizon_s)
    return ctrl  # type: ignore[no-any-return]


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

        planner = WithMoverGuard(planner, float(horizon))
    return planner
