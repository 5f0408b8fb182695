"""Scenario files (TOML): parsing, validation with line numbers, and the built-in scenarios.

The schema is documented in docs/scenario_schema.md. Every problem raises :class:`ScenarioError`
naming the field (``circles[2].radius_m``) and the line it is on. ``tomllib`` reports line numbers
only for syntax errors, so for value errors the key's line is found by scanning the text
(:func:`locate_line`).
"""

from __future__ import annotations

import bisect
import math
import re
import tomllib
from dataclasses import dataclass, field, fields, replace
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from ..calib import CalibError, default_speed_table, default_steering_table
from ..toml_input import TomlTooDeep, loads_bounded
from ..types import Goal, Pose2D
from .robots import Ackermann, AckermannParams, DiffDrive, DiffDriveParams, Robot
from .sensors import Laser2D, LaserSpec, SonarRing, SonarSpec, TiltedLaser, laser_preset
from .world import (Hole, Mover, Rut, Step, World, box_segments, plants_along, polyline_length_m, polyline_segments,
                    sine_curve)

__all__ = [
    "ScenarioError",
    "Scenario",
    "load_scenario",
    "parse_scenario",
    "builtin_names",
    "builtin_text",
    "builtin_descriptions",
    "DEFAULT_SCENARIO",
    "locate_line",
    "MAX_STEPS",
    "MAX_CIRCLES",
    "run_length_problem",
    "FieldTask",
]

DEFAULT_SCENARIO = "corridor_obstacles"

#: Most physics steps in one run, ``duration_s / dt_s``: each is a trajectory sample of 8 numbers (64 B), so
#: 2 000 000 steps are 128 MB, e.g. 40 000 s (11 h) at the default ``dt_s`` of 0.02 s. Longer runs are refused
#: before anything is allocated.
MAX_STEPS = 2_000_000
#: Most obstacle circles in one world (``[[circles]]``, the plants of ``[[rows]]``, ``[[weeds]]``), checked
#: before they are made (a crop field of 10 rows of 100 m is about 20 000).
MAX_CIRCLES = 1_000_000

Path_ = tuple[str | int, ...]


MAX_MAGNITUDE = 1e9  # no length (m), time (s) or speed of a scenario is larger; squares of bigger ones overflow


class ScenarioError(ValueError):
    """A scenario file problem: ``field`` (dotted path), ``line`` (1-based, or None) and a message."""

    def __init__(self, field: str, line: int | None, message: str, source: str = "<scenario>") -> None:
        self.field = field
        self.line = line
        self.message = message
        self.source = source
        where = f"{source}:{line}" if line is not None else source
        super().__init__(f"{where}: {field}: {message}" if field else f"{where}: {message}")


def _fmt_path(path: Path_) -> str:
    out = ""
    for p in path:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else p)
    return out or "<root>"


class _TomlScan:
    """Where each key, table header and array element of a TOML text starts: a small scanner over the whole
    text (not line by line), so that multi-line strings and arrays neither hide nor invent keys and an
    element of a multi-line array has its own line. It reads only positions, so it assumes valid TOML (the
    text has been parsed by tomllib first) and stops quietly at anything it does not follow."""

    _BARE = re.compile(r"[A-Za-z0-9_\-]+")
    _SCALAR_END = re.compile(r"[,\]}\n#]")

    def __init__(self, text: str) -> None:
        self.t = text
        self.i = 0
        self.newlines = [m.start() for m in re.finditer("\n", text)]
        self.entries: list[tuple[Path_, int]] = []

    def line(self, pos: int) -> int:
        return bisect.bisect_left(self.newlines, pos) + 1

    def peek(self, n: int = 1) -> str:
        return self.t[self.i : self.i + n]

    def skip(self, newlines: bool) -> None:
        """Past blanks and comments (and line ends when ``newlines``)."""
        while self.i < len(self.t):
            ch = self.t[self.i]
            if ch in " \t\r" or (newlines and ch == "\n"):
                self.i += 1
            elif ch == "#":
                nl = self.t.find("\n", self.i)
                self.i = len(self.t) if nl < 0 else nl
            else:
                return

    def expect(self, s: str) -> None:
        if not self.t.startswith(s, self.i):
            raise ValueError(f"expected {s!r} at {self.i}")
        self.i += len(s)

    def string(self) -> str:
        """Past a string of any of the four kinds (basic, literal, multi-line of each); its raw text."""
        t, st = self.t, self.i
        q = t[st] * 3 if t.startswith(t[st] * 3, st) else t[st]
        j = st + len(q)
        while True:
            k = t.find(q, j)
            if k < 0 or (len(q) == 1 and "\n" in t[j:k]):
                raise ValueError("unterminated string")
            if q[0] == '"' and _escaped(t, k):
                j = k + 1
                continue
            break
        end = k + len(q)
        if len(q) == 3:  # up to two quotes just before the closing three belong to the string
            while end < len(t) and end - k < 5 and t[end] == q[0]:
                end += 1
        self.i = end
        return t[st:end]

    def key(self) -> tuple[str, ...]:
        """A dotted key (bare or quoted parts) -> its parts."""
        parts = []
        while True:
            self.skip(False)
            if self.peek() in ('"', "'"):
                parts.append(tomllib.loads(f"k = {self.string()}")["k"])
            else:
                m = self._BARE.match(self.t, self.i)
                if not m:
                    raise ValueError(f"expected a key at {self.i}")
                parts.append(m.group())
                self.i = m.end()
            self.skip(False)
            if self.peek() != ".":
                return tuple(parts)
            self.i += 1

    def value(self, path: Path_) -> None:
        self.skip(False)
        ch = self.peek()
        if ch in ('"', "'"):
            self.string()
        elif ch in ("[", "{"):
            close = "]" if ch == "[" else "}"
            self.i += 1
            n = 0
            while True:
                self.skip(True)
                if self.peek() == close:
                    break
                if ch == "[":
                    self.entries.append(((*path, n), self.line(self.i)))
                    self.value((*path, n))
                    n += 1
                else:
                    self.key_value(path)
                self.skip(True)
                if self.peek() != ",":
                    break
                self.i += 1
            self.expect(close)
        else:  # number, boolean, date
            m = self._SCALAR_END.search(self.t, self.i)
            self.i = len(self.t) if m is None else m.start()

    def key_value(self, table: Path_) -> None:
        at = self.line(self.i)
        key = self.key()
        for n in range(1, len(key) + 1):  # a.b.c = 1: a, a.b and a.b.c are all on this line
            self.entries.append(((*table, *key[:n]), at))
        self.expect("=")
        self.value((*table, *key))

    def run(self) -> list[tuple[Path_, int]]:
        arrays: dict[Path_, int] = {}  # [[name]] tables seen -> index of the last one
        table: Path_ = ()
        try:
            while True:
                self.skip(True)
                if self.i >= len(self.t):
                    break
                at = self.line(self.i)
                if self.peek() == "[":
                    many = self.peek(2) == "[["
                    self.i += 2 if many else 1
                    name = self.key()
                    self.expect("]]" if many else "]")
                    table = ()
                    for part in name[:-1]:  # [a.b] after [[a]] is b of a's last table
                        table = (*table, part)
                        if table in arrays:
                            table = (*table, arrays[table])
                    table = (*table, name[-1])
                    if many:
                        arrays[table] = arrays.get(table, -1) + 1
                        table = (*table, arrays[table])
                    for n in range(1, len(table) + 1):  # [[goals]]: ("goals",) too, on its first header
                        self.entries.append((table[:n], at))
                else:
                    self.key_value(table)
        except (ValueError, IndexError, RecursionError, tomllib.TOMLDecodeError):
            pass  # not TOML this scanner follows: what was found so far
        return self.entries


def _escaped(text: str, k: int) -> bool:
    """True when the character at ``k`` follows an odd number of backslashes."""
    n = 0
    while k - n - 1 >= 0 and text[k - n - 1] == "\\":
        n += 1
    return n % 2 == 1


def _key_index(text: str) -> list[tuple[Path_, int]]:
    """(path, line) for every table header, key (inline-table keys too) and array element in a TOML text; an
    ``[[name]]`` table's path holds its index, as does an element's: ``("walls", 0, "points", 2)``."""
    return _TomlScan(text).run()


def locate_line(text: str, path: Path_) -> int | None:
    """Line (1-based) of the deepest key on ``path`` found in ``text``; None if none matches."""
    index = _key_index(text)
    for n in range(len(path), 0, -1):
        want = tuple(path[:n])
        for key, line in index:
            if key == want:
                return line
    return None


class _Reader:
    """Typed access to the parsed TOML with errors that carry the field and line."""

    def __init__(self, text: str, source: str) -> None:
        self.text = text
        self.source = source

    def error(self, path: Path_, message: str) -> ScenarioError:
        return ScenarioError(_fmt_path(path), locate_line(self.text, path), message, self.source)

    def keys(self, d: dict[str, Any], path: Path_, allowed: set[str]) -> None:
        for k in d:
            if k not in allowed:
                raise self.error((*path, k), f"unknown key; allowed: {', '.join(sorted(allowed))}")

    def table(self, d: dict[str, Any], key: str, path: Path_, required: bool = False) -> dict[str, Any]:
        if key not in d:
            if required:
                raise self.error(path, f"missing required table [{_fmt_path((*path, key))}]")
            return {}
        v = d[key]
        if not isinstance(v, dict):
            raise self.error((*path, key), "must be a table")
        return v

    def tables(self, d: dict[str, Any], key: str) -> list[dict[str, Any]]:
        v = d.get(key, [])
        if not isinstance(v, list) or not all(isinstance(x, dict) for x in v):
            raise self.error((key,), f"must be an array of tables ([[{key}]])")
        return v

    def num(self, d: dict[str, Any], key: str, path: Path_, default: float | None = None, *,
            lo: float | None = None, hi: float | None = None, lo_open: bool = False, required: bool = False) -> float:
        if key not in d:
            if required or default is None:
                raise self.error(path, f"missing required field '{key}'")
            return default
        v = d[key]
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise self.error((*path, key), f"must be a finite number, got {v!r}")
        v = float(v)
        if abs(v) > MAX_MAGNITUDE and (hi is None or hi > MAX_MAGNITUDE or lo is None or lo < -MAX_MAGNITUDE):
            raise self.error((*path, key), f"must be within +-{MAX_MAGNITUDE:g} (metres, seconds, ...), got {v:g}")
        if lo is not None and (v <= lo if lo_open else v < lo):
            raise self.error((*path, key), f"must be {'>' if lo_open else '>='} {lo:g}, got {v:g}")
        if hi is not None and v > hi:
            raise self.error((*path, key), f"must be <= {hi:g}, got {v:g}")
        return v

    def opt_num(self, d: dict[str, Any], key: str, path: Path_, **kw: Any) -> float | None:
        return self.num(d, key, path, **kw) if key in d else None

    def integer(self, d: dict[str, Any], key: str, path: Path_, default: int, lo: int = 0) -> int:
        v = d.get(key, default)
        if isinstance(v, bool) or not isinstance(v, int):
            raise self.error((*path, key), f"must be an integer, got {v!r}")
        if v < lo:
            raise self.error((*path, key), f"must be >= {lo}, got {v}")
        if v > 10**9:
            raise self.error((*path, key), f"must be <= 1000000000, got {v}")
        return v

    def string(self, d: dict[str, Any], key: str, path: Path_, default: str | None = None, choices: tuple[str, ...] | None = None) -> str:
        if key not in d:
            if default is None:
                raise self.error(path, f"missing required field '{key}'")
            return default
        v = d[key]
        if not isinstance(v, str):
            raise self.error((*path, key), f"must be a string, got {v!r}")
        if choices is not None and v not in choices:
            raise self.error((*path, key), f"must be one of {', '.join(choices)}; got {v!r}")
        return v

    def boolean(self, d: dict[str, Any], key: str, path: Path_, default: bool) -> bool:
        v = d.get(key, default)
        if not isinstance(v, bool):
            raise self.error((*path, key), f"must be true or false, got {v!r}")
        return v

    def points(self, d: dict[str, Any], key: str, path: Path_, min_count: int = 2) -> np.ndarray:
        if key not in d:
            raise self.error(path, f"missing required field '{key}'")
        v = d[key]
        if not isinstance(v, list) or len(v) < min_count:
            raise self.error((*path, key), f"must be a list of at least {min_count} [x_m, y_m] points")
        for i, p in enumerate(v):
            if not _finite_numbers(p, 2):
                raise self.error((*path, key, i), f"must be a [x_m, y_m] pair of numbers, got {p!r}")
            if max(abs(p[0]), abs(p[1])) > MAX_MAGNITUDE:
                raise self.error((*path, key, i), f"must be within +-{MAX_MAGNITUDE:g} m, got {p!r}")
        return np.asarray(v, dtype=float)

    def pose(self, d: dict[str, Any], key: str, path: Path_) -> Pose2D:
        t = self.table(d, key, path, required=True)
        p = (*path, key)
        self.keys(t, p, {"x_m", "y_m", "yaw_deg"})
        return Pose2D(self.num(t, "x_m", p, required=True), self.num(t, "y_m", p, required=True),
                      math.radians(self.num(t, "yaw_deg", p, 0.0)))


@dataclass(frozen=True)
class FieldTask:
    """A scenario's ``[field]``: the field's navigation task as the Field Robot Event sets it.

    ``pattern``: the turn pattern in the event's notation (``S-1L-2R-F``: S start, nL / nR the n-th lane to the
    left / right of the one just driven, F finish), the route the run is scored on and the row navigator's default;
    ``time_limit_s``: the task's time (the event's 3 min): distance counts until then, and a field finished sooner
    earns the time bonus; ``row_spacing_m``: the distance between rows the robot is told (its row detector's prior).
    With a field, plants and weeds are soft: the robot may brush them, the referee counts the stems it runs over
    (``plants_touched``) instead of ending the run."""

    pattern: str
    time_limit_s: float = 180.0
    row_spacing_m: float = 0.75


@dataclass
class Scenario:
    """Everything needed to run one simulation (geometry, robot, sensors, goals)."""

    name: str
    description: str
    world: World
    robot_kind: str
    robot_params: DiffDriveParams | AckermannParams
    start: Pose2D
    goals: list[Goal]
    duration_s: float = 120.0
    dt_s: float = 0.02
    control_hz: float = 15.0
    max_speed_m_s: float = 0.5
    laser: Laser2D | None = None
    tilted_laser: TiltedLaser | None = None
    sonar: SonarRing | None = None
    meta: dict[str, Any] = field(default_factory=dict)
    field: FieldTask | None = None  # a whole field: [field] (its rows are the [[rows]], in order across the field)

    def make_robot(self) -> Robot:
        r: Robot
        if self.robot_kind == "ackermann":
            assert isinstance(self.robot_params, AckermannParams)
            r = Ackermann(self.robot_params)
        else:
            assert isinstance(self.robot_params, DiffDriveParams)
            r = DiffDrive(self.robot_params)
        r.reset(self.start)
        return r


_TOP_KEYS = {"scenario", "robot", "laser", "tilted_laser", "sonar", "goals", "walls", "boxes", "circles",
             "polygons", "movers", "rows", "weeds", "holes", "steps", "ruts", "field", "meta"}


def _laser_spec(rd: _Reader, t: dict[str, Any], path: Path_, default_model: str) -> LaserSpec:
    model = rd.string(t, "model", path, default_model)
    try:
        spec = laser_preset(model)
    except ValueError as e:
        raise rd.error((*path, "model"), str(e)) from None
    over: dict[str, Any] = {}
    for k in ("range_std_m", "dropout_prob", "mixed_pixel_prob", "max_range_m"):
        if k in t:
            over[k] = rd.num(t, k, path, lo=0.0, lo_open=k == "max_range_m", hi=1.0 if k.endswith("prob") else None)
    if "no_return" in t:
        nr = rd.string(t, "no_return", path, choices=("nan", "inf", "zero"))
        over["no_return"] = {"nan": math.nan, "inf": math.inf, "zero": 0.0}[nr]
    try:
        return LaserSpec(**{**{f.name: getattr(spec, f.name) for f in fields(spec)}, **over})
    except ValueError as e:
        raise rd.error(path, str(e)) from None


def _robot(rd: _Reader, data: dict[str, Any]) -> tuple[str, DiffDriveParams | AckermannParams, Pose2D, float]:
    path: Path_ = ("robot",)
    t = rd.table(data, "robot", (), required=True)
    kind = rd.string(t, "model", path, choices=("diff_drive", "ackermann"))
    cls = DiffDriveParams if kind == "diff_drive" else AckermannParams
    numeric = {f.name for f in fields(cls) if f.type in ("float", float)}
    angle_deg = {"max_steer_deg": "max_steer_rad", "max_steer_rate_deg_s": "max_steer_rate_rad_s"} if kind == "ackermann" else {}
    rd.keys(t, path, {"model", "start", "max_speed_m_s", "calib"} | (numeric - set(angle_deg.values())) | set(angle_deg))
    start = rd.pose(t, "start", path)
    kw: dict[str, Any] = {}
    for k in t:
        if k in numeric:
            kw[k] = rd.num(t, k, path, lo=0.0)
        elif k in angle_deg:
            kw[angle_deg[k]] = math.radians(rd.num(t, k, path, lo=0.0, lo_open=True, hi=89.0))
    calib = rd.table(t, "calib", path)
    if calib:
        cp = (*path, "calib")
        if kind != "ackermann":
            raise rd.error(cp, "calibration tables apply to the ackermann model only")
        rd.keys(calib, cp, {"tables", "steer_scale", "steer_offset_pwm", "speed_scale", "speed_offset_pwm"})
        rd.string(calib, "tables", cp, "default", choices=("default",))
        try:
            steer, speed = default_steering_table(), default_speed_table()
            kw["ctrl_steer"], kw["ctrl_speed"] = steer, speed
            kw["true_steer"] = steer.miscalibrated(rd.num(calib, "steer_scale", cp, 1.0, lo=0.0, lo_open=True),
                                                   rd.num(calib, "steer_offset_pwm", cp, 0.0))
            kw["true_speed"] = speed.miscalibrated(rd.num(calib, "speed_scale", cp, 1.0, lo=0.0, lo_open=True),
                                                   rd.num(calib, "speed_offset_pwm", cp, 0.0))
        except CalibError as e:
            raise rd.error(cp, str(e)) from None
    try:
        params = cls(**kw)
    except ValueError as e:
        raise rd.error(path, str(e)) from None
    vmax_default = 0.5 if kind == "diff_drive" else 1.0
    vmax = rd.num(t, "max_speed_m_s", path, vmax_default, lo=0.0, lo_open=True)
    return kind, params, start, vmax


def _finite_numbers(v: Any, n: int) -> bool:
    """True for a TOML list of ``n`` finite numbers (booleans are not numbers here)."""
    return (isinstance(v, list) and len(v) == n
            and all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in v))


def _finite_box(v: Any) -> bool:
    """True for ``[xmin_m, ymin_m, xmax_m, ymax_m]``: four finite numbers."""
    return _finite_numbers(v, 4)


def _check_meta(rd: _Reader, meta: dict[str, Any]) -> None:
    """The ``[meta]`` entries the host itself reads, checked when the file is loaded (the rest is passed
    through to the planners): ``path`` ([[x_m, y_m], ...], >= 2 points, follow-path's given path) and
    ``landmarks`` ([[x_m, y_m, radius_m], ...], radius_m > 0, the SIL host's surveyed posts)."""
    mp: Path_ = ("meta",)
    if "path" in meta:
        rd.points(meta, "path", mp)
    rows = meta.get("landmarks")
    if rows is None:
        return
    if not isinstance(rows, list):
        raise rd.error((*mp, "landmarks"), f"must be a list of [x_m, y_m, radius_m] rows, got {rows!r}")
    for i, r in enumerate(rows):
        if not _finite_numbers(r, 3) or not r[2] > 0:
            raise rd.error((*mp, "landmarks", i), f"must be a [x_m, y_m, radius_m] row of finite numbers with "
                                                  f"radius_m > 0, got {r!r}")


def _field_task(rd: _Reader, data: dict[str, Any], world: World) -> FieldTask | None:
    """The ``[field]`` table (None without one): the pattern checked for its notation, at least two rows (one
    lane); plants and weeds become soft."""
    if "field" not in data:
        return None
    fp: Path_ = ("field",)
    ft = rd.table(data, "field", ())
    rd.keys(ft, fp, {"pattern", "time_limit_s", "row_spacing_m"})
    from ..planning.row_navigator import PatternError, parse_pattern

    pattern = rd.string(ft, "pattern", fp)
    try:
        parse_pattern(pattern)
    except PatternError as e:
        raise rd.error((*fp, "pattern"), str(e)) from None
    if len(world.row_lines) < 2:
        raise rd.error(fp, f"a field needs at least two [[rows]] (one lane between them); this scenario has "
                           f"{len(world.row_lines)}")
    world.soft_kinds = ("plant", "weed")
    return FieldTask(pattern, rd.num(ft, "time_limit_s", fp, 180.0, lo=0.0, lo_open=True),
                     rd.num(ft, "row_spacing_m", fp, 0.75, lo=0.0, lo_open=True))


def run_length_problem(duration_s: float, dt_s: float, what: str = "duration_s") -> str | None:
    """Why a run of ``duration_s`` s in physics steps of ``dt_s`` s is refused (more than :data:`MAX_STEPS`
    steps, with the memory its trajectory would need), or None. ``what`` names the duration in the message."""
    n = duration_s / dt_s
    if n <= MAX_STEPS:
        return None
    gib = (n + 1) * 64 / 2**30
    return (f"{duration_s:g} s in steps of dt_s {dt_s:g} s is {n:.3g} physics steps ({gib:.3g} GiB of trajectory); "
            f"at most {MAX_STEPS} steps: {what} <= {MAX_STEPS * dt_s:g} s at this dt_s")


def _room_for_circles(rd: _Reader, world: World, n: float, path: Path_, what: str) -> None:
    """Refuse ``n`` more obstacle circles (``what`` says where they come from) when the world would then hold
    more than :data:`MAX_CIRCLES`; called before they are made."""
    have = len(world.circles)
    if have + n > MAX_CIRCLES:
        raise rd.error(path, f"{what} would make {n:.3g} obstacle circles{f' more than the {have} before' if have else ''}; "
                             f"at most {MAX_CIRCLES} in a scenario")


def parse_scenario(text: str, source: str = "<scenario>") -> Scenario:
    """Parse and validate a scenario from TOML text; raises ScenarioError."""
    try:
        data = loads_bounded(text)
    except TomlTooDeep as e:
        raise ScenarioError("<toml>", e.line, str(e).split(": ", 1)[1], source) from None
    except tomllib.TOMLDecodeError as e:
        m = re.search(r"line (\d+)", str(e))
        line = int(m.group(1)) if m else None
        if line is None and "end of document" in str(e):  # a truncated file: the error is on its last line
            line = max(1, len(text.splitlines()))
        raise ScenarioError("<toml>", line, f"TOML syntax error: {e}", source) from None
    if not data:  # an empty file, or comments only: say so rather than name the first missing table
        raise ScenarioError("", None, "no scenario in the file (it is empty or holds only comments); a scenario "
                            "needs at least a [scenario] table with a name and a [robot] table (docs/scenario_schema.md)",
                            source)
    rd = _Reader(text, source)
    rd.keys(data, (), _TOP_KEYS)
    sc = rd.table(data, "scenario", (), required=True)
    sp: Path_ = ("scenario",)
    rd.keys(sc, sp, {"name", "description", "duration_s", "dt_s", "control_hz", "world_seed", "bounds"})
    name = rd.string(sc, "name", sp)
    description = rd.string(sc, "description", sp, "")
    duration = rd.num(sc, "duration_s", sp, 120.0, lo=0.0, lo_open=True)
    dt = rd.num(sc, "dt_s", sp, 0.02, lo=0.0, lo_open=True, hi=0.5)
    control_hz = rd.num(sc, "control_hz", sp, 15.0, lo=0.0, lo_open=True)
    if control_hz * dt > 1.0 + 1e-9:  # the controller runs at most once per physics step
        raise rd.error((*sp, "control_hz"), f"must be <= 1 / dt_s = {1.0 / dt:g}, got {control_hz:g}")
    too_long = run_length_problem(duration, dt)
    if too_long:  # blame the step when it was set below the default, else the duration
        raise rd.error((*sp, "dt_s" if "dt_s" in sc and dt < 0.02 else "duration_s"), too_long)
    wrng = np.random.default_rng(rd.integer(sc, "world_seed", sp, 0))

    kind, params, start, vmax = _robot(rd, data)
    world = World()

    for i, w in enumerate(rd.tables(data, "walls")):
        p: Path_ = ("walls", i)
        rd.keys(w, p, {"points", "closed"})
        world.add_segments(polyline_segments(rd.points(w, "points", p), rd.boolean(w, "closed", p, False)))
    for i, b in enumerate(rd.tables(data, "boxes")):
        p = ("boxes", i)
        rd.keys(b, p, {"x_m", "y_m", "size_x_m", "size_y_m", "yaw_deg"})
        world.add_segments(box_segments(rd.num(b, "x_m", p, required=True), rd.num(b, "y_m", p, required=True),
                                        rd.num(b, "size_x_m", p, required=True, lo=0.0, lo_open=True),
                                        rd.num(b, "size_y_m", p, required=True, lo=0.0, lo_open=True),
                                        math.radians(rd.num(b, "yaw_deg", p, 0.0))), kind="box")
    for i, c in enumerate(rd.tables(data, "circles")):
        p = ("circles", i)
        rd.keys(c, p, {"x_m", "y_m", "radius_m"})
        world.add_circles(np.array([rd.num(c, "x_m", p, required=True), rd.num(c, "y_m", p, required=True),
                                    rd.num(c, "radius_m", p, required=True, lo=0.0, lo_open=True)]))
    for i, g in enumerate(rd.tables(data, "polygons")):
        p = ("polygons", i)
        rd.keys(g, p, {"points"})
        world.add_segments(polyline_segments(rd.points(g, "points", p, 3), closed=True), kind="polygon")
    for i, mv in enumerate(rd.tables(data, "movers")):
        p = ("movers", i)
        rd.keys(mv, p, {"radius_m", "speed_m_s", "waypoints", "loop", "start_s"})
        wp = rd.points(mv, "waypoints", p, 1)
        world.movers.append(Mover(rd.num(mv, "radius_m", p, 0.25, lo=0.0, lo_open=True),
                                  rd.num(mv, "speed_m_s", p, 1.2, lo=0.0),
                                  tuple((float(a), float(b)) for a, b in wp), rd.boolean(mv, "loop", p, True),
                                  rd.num(mv, "start_s", p, 0.0, lo=0.0)))
    for i, r in enumerate(rd.tables(data, "rows")):
        p = ("rows", i)
        rd.keys(r, p, {"points", "start", "length_m", "amplitude_m", "wavelength_m", "count", "spacing_m",
                       "plant_spacing_m", "plant_radius_m", "cluster", "jitter_m", "gaps"})
        count = rd.integer(r, "count", p, 1, lo=1)
        spacing = rd.num(r, "spacing_m", p, 0.75, lo=0.0, lo_open=True)
        if "points" in r and "start" in r:
            raise rd.error((*p, "start"), "give either 'points' or 'start' + 'length_m', not both")
        if "points" in r:
            base = rd.points(r, "points", p)
            d0 = base[1] - base[0]
            normal = np.array([-d0[1], d0[0]]) / max(float(np.hypot(*d0)), 1e-12)
        else:
            st = rd.pose(r, "start", p)
            base = sine_curve(st.x_m, st.y_m, st.yaw_rad, rd.num(r, "length_m", p, required=True, lo=0.0, lo_open=True),
                              rd.num(r, "amplitude_m", p, 0.0, lo=0.0), rd.num(r, "wavelength_m", p, 10.0, lo=0.0, lo_open=True))
            normal = np.array([-math.sin(st.yaw_rad), math.cos(st.yaw_rad)])
        gaps = []
        for j, gp in enumerate(r.get("gaps", [])):
            if (not isinstance(gp, list) or len(gp) != 2 or not all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in gp)
                    or gp[0] > gp[1]):
                raise rd.error((*p, "gaps", j), f"must be [start_m, end_m] along the row with start <= end, got {gp!r}")
            gaps.append((float(gp[0]), float(gp[1])))
        plant_spacing = rd.num(r, "plant_spacing_m", p, 0.15, lo=0.0, lo_open=True)
        cluster = rd.integer(r, "cluster", p, 3, lo=1)
        length = polyline_length_m(base)
        _room_for_circles(rd, world, (length // plant_spacing + 1) * cluster * count,
                          (*p, "plant_spacing_m" if "plant_spacing_m" in r else "count"),
                          f"{length:.4g} m of row every {plant_spacing:g} m x cluster {cluster} x count {count}")
        for k in range(count):
            world.row_lines.append(base + k * spacing * normal)
            plants = plants_along(world.row_lines[-1], plant_spacing,
                                  rd.num(r, "plant_radius_m", p, 0.05, lo=0.0, lo_open=True), wrng,
                                  cluster, rd.num(r, "jitter_m", p, 0.02, lo=0.0), gaps)
            world.add_circles(plants, kind="plant")
            # each plant's stem: the mean of its circles (plants_along lays them plant by plant)
            world.row_plants.append(plants[:, :2].reshape(-1, max(1, cluster), 2).mean(axis=1))
    for i, w in enumerate(rd.tables(data, "weeds")):
        p = ("weeds", i)
        rd.keys(w, p, {"region", "count", "radius_m"})
        reg: Any = w.get("region")
        if not (_finite_box(reg) and reg[0] < reg[2] and reg[1] < reg[3]):
            raise rd.error((*p, "region"), f"must be [xmin_m, ymin_m, xmax_m, ymax_m], finite numbers with min < max, "
                                           f"got {reg!r}")
        n = rd.integer(w, "count", p, 10)
        _room_for_circles(rd, world, n, (*p, "count"), "this many weeds")
        rad = rd.num(w, "radius_m", p, 0.02, lo=0.0, lo_open=True)
        xy = wrng.uniform((reg[0], reg[1]), (reg[2], reg[3]), (n, 2))
        world.add_circles(np.column_stack((xy, np.full(n, rad))), kind="weed")
    for i, h in enumerate(rd.tables(data, "holes")):
        p = ("holes", i)
        rd.keys(h, p, {"x_m", "y_m", "size_x_m", "size_y_m", "depth_m", "yaw_deg", "shape"})
        world.holes.append(Hole(rd.num(h, "x_m", p, required=True), rd.num(h, "y_m", p, required=True),
                                rd.num(h, "size_x_m", p, required=True, lo=0.0, lo_open=True),
                                rd.num(h, "size_y_m", p, required=True, lo=0.0, lo_open=True),
                                rd.num(h, "depth_m", p, required=True, lo=0.0, lo_open=True),
                                math.radians(rd.num(h, "yaw_deg", p, 0.0)),
                                rd.string(h, "shape", p, "box", choices=("box", "ellipse")) == "ellipse"))
    for i, s in enumerate(rd.tables(data, "steps")):
        p = ("steps", i)
        rd.keys(s, p, {"x_m", "y_m", "yaw_deg", "height_m", "width_m", "depth_m"})
        world.steps.append(Step(rd.num(s, "x_m", p, required=True), rd.num(s, "y_m", p, required=True),
                                math.radians(rd.num(s, "yaw_deg", p, 0.0)), rd.num(s, "height_m", p, required=True),
                                rd.num(s, "width_m", p, math.inf, lo=0.0, lo_open=True), rd.num(s, "depth_m", p, math.inf, lo=0.0, lo_open=True)))
    for i, r in enumerate(rd.tables(data, "ruts")):
        p = ("ruts", i)
        rd.keys(r, p, {"points", "width_m", "depth_m", "count", "spacing_m"})
        cnt = rd.integer(r, "count", p, 1, lo=1)
        if cnt > 2:
            raise rd.error((*p, "count"), f"must be 1 or 2, got {cnt}")
        world.ruts.append(Rut(tuple((float(a), float(b)) for a, b in rd.points(r, "points", p)),
                              rd.num(r, "width_m", p, 0.2, lo=0.0, lo_open=True), rd.num(r, "depth_m", p, 0.1, lo=0.0, lo_open=True),
                              rd.num(r, "spacing_m", p, 0.0 if cnt == 1 else 1.2, lo=0.0), cnt))

    goals: list[Goal] = []
    for i, g in enumerate(rd.tables(data, "goals")):
        p = ("goals", i)
        rd.keys(g, p, {"x_m", "y_m", "yaw_deg", "arrival_s", "tolerance_m"})
        yaw = rd.opt_num(g, "yaw_deg", p)
        goals.append(Goal(rd.num(g, "x_m", p, required=True), rd.num(g, "y_m", p, required=True),
                          None if yaw is None else math.radians(yaw), rd.opt_num(g, "arrival_s", p, lo=0.0),
                          rd.num(g, "tolerance_m", p, 0.3, lo=0.0, lo_open=True)))
    if not goals:
        raise ScenarioError("goals", None, "at least one [[goals]] entry is required", source)

    laser = None
    if "laser" in data:
        lt = rd.table(data, "laser", ())
        rd.keys(lt, ("laser",), {"model", "mount", "range_std_m", "dropout_prob", "mixed_pixel_prob", "max_range_m", "no_return"})
        laser = Laser2D(_laser_spec(rd, lt, ("laser",), "tim561"), rd.pose(lt, "mount", ("laser",)) if "mount" in lt else Pose2D())
    tilted = None
    if "tilted_laser" in data:
        tp: Path_ = ("tilted_laser",)
        tt = rd.table(data, "tilted_laser", ())
        rd.keys(tt, tp, {"model", "mount", "height_m", "tilt_deg", "range_std_m", "dropout_prob", "mixed_pixel_prob",
                         "max_range_m", "no_return", "fov_deg", "resolution_deg"})
        tspec = _laser_spec(rd, tt, tp, "lms200")
        # the beams: field of view and step (defaults from the model), e.g. a narrower fan across the track
        fov = math.radians(rd.num(tt, "fov_deg", tp, math.degrees(tspec.fov_rad), lo=0.0, lo_open=True, hi=359.0))
        res = math.radians(rd.num(tt, "resolution_deg", tp, math.degrees(tspec.resolution_rad), lo=0.0, lo_open=True, hi=90.0))
        height = rd.num(tt, "height_m", tp, 0.5, lo=0.0, lo_open=True)
        tilt = math.radians(rd.num(tt, "tilt_deg", tp, 20.0, lo=0.0, lo_open=True, hi=89.0))
        mount = rd.pose(tt, "mount", tp) if "mount" in tt else Pose2D()
        try:
            tilted = TiltedLaser(replace(tspec, fov_rad=fov, resolution_rad=res), height, tilt, mount)
        except ValueError as e:
            raise rd.error(tp, str(e)) from None
    sonar = None
    if "sonar" in data:
        so = rd.table(data, "sonar", ())
        sop: Path_ = ("sonar",)
        allowed = {f.name for f in fields(SonarSpec)} - {"spacing_rad", "cone_rad"} | {"enabled", "cone_deg", "spacing_deg"}
        rd.keys(so, sop, allowed)
        if rd.boolean(so, "enabled", sop, True):
            kw: dict[str, Any] = {}
            for key in so:
                if key in ("count", "rays_per_cone"):
                    kw[key] = rd.integer(so, key, sop, 12, lo=1)
                elif key in ("cone_deg", "spacing_deg"):
                    kw[key.replace("_deg", "_rad")] = math.radians(rd.num(so, key, sop, lo=0.0, lo_open=True, hi=179.0))
                elif key != "enabled":
                    kw[key] = rd.num(so, key, sop, lo=0.0)
            try:
                sonar = SonarRing(SonarSpec(**kw))
            except ValueError as e:
                raise rd.error(sop, str(e)) from None

    meta = rd.table(data, "meta", ())
    _check_meta(rd, meta)
    task = _field_task(rd, data, world)
    bounds = sc.get("bounds")
    if bounds is not None:
        if not (_finite_box(bounds) and bounds[0] < bounds[2] and bounds[1] < bounds[3]):
            raise rd.error((*sp, "bounds"), f"must be [xmin_m, ymin_m, xmax_m, ymax_m], finite numbers with min < max, "
                                            f"got {bounds!r}")
        world.bounds = tuple(float(x) for x in bounds)  # type: ignore[assignment]
    else:
        xs = [start.x_m] + [g.x_m for g in goals]
        ys = [start.y_m] + [g.y_m for g in goals]
        if len(world.segments):
            xs += world.segments[:, [0, 2]].ravel().tolist()
            ys += world.segments[:, [1, 3]].ravel().tolist()
        if len(world.circles):
            xs += world.circles[:, 0].tolist()
            ys += world.circles[:, 1].tolist()
        world.bounds = (min(xs) - 1, min(ys) - 1, max(xs) + 1, max(ys) + 1)

    return Scenario(name, description, world, kind, params, start, goals, duration, dt, control_hz, vmax,
                    laser, tilted, sonar, dict(meta), task)


def _scenario_dir() -> Any:
    return resources.files("agnav_host.sim").joinpath("scenarios")


def builtin_names() -> list[str]:
    """Names of the built-in scenarios, sorted."""
    return sorted(p.name[:-5] for p in _scenario_dir().iterdir() if p.name.endswith(".toml"))


def builtin_text(name: str) -> str:
    """TOML text of a built-in scenario; KeyError lists the names on a miss."""
    f = _scenario_dir().joinpath(f"{name}.toml")
    if not f.is_file():
        raise KeyError(f"unknown scenario {name!r}; built-ins: {', '.join(builtin_names())}")
    return str(f.read_text(encoding="utf-8"))


def builtin_descriptions() -> dict[str, str]:
    """name -> one-line description of every built-in scenario."""
    out = {}
    for n in builtin_names():
        d = tomllib.loads(builtin_text(n)).get("scenario", {}).get("description", "")
        out[n] = d.strip().splitlines()[0] if d.strip() else ""
    return out


_UTF8_BOM = b"\xef\xbb\xbf"
_UTF16_BOMS = (b"\xff\xfe", b"\xfe\xff")


def _decode(data: bytes, source: str) -> str:
    """A scenario file's bytes as text: UTF-8, a leading UTF-8 byte-order mark (Windows editors) dropped.
    Anything else is a :class:`ScenarioError` naming the line of the first byte that is not UTF-8."""
    if data.startswith(_UTF8_BOM):
        data = data[len(_UTF8_BOM):]
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as e:
        line = data.count(b"\n", 0, e.start) + 1
        what = "UTF-16 text" if data.startswith(_UTF16_BOMS) else f"not UTF-8 text (byte 0x{data[e.start]:02x})"
        raise ScenarioError("", line, f"cannot read scenario file: {what}; save it as UTF-8", source) from None


def load_scenario(name_or_path: str | Path | None = None) -> Scenario:
    """A built-in scenario by name, a scenario file by path, or the default when None."""
    if name_or_path is None:
        name_or_path = DEFAULT_SCENARIO
    s = str(name_or_path)
    if s in builtin_names():
        return parse_scenario(builtin_text(s), f"<builtin:{s}>")
    p = Path(s)
    if p.suffix == ".toml" or p.exists():
        try:
            data = p.read_bytes()
        except OSError as e:
            raise ScenarioError("", None, f"cannot read scenario file: {e.strerror}", str(p)) from None
        return parse_scenario(_decode(data, str(p)), str(p))
    raise ScenarioError("", None, f"unknown scenario {s!r} (neither a built-in name nor a .toml file); built-ins: "
                        f"{', '.join(builtin_names())}", s)
