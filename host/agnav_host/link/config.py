"""Host configuration: one TOML file, every key optional (docs/user_guide.md lists them with units).

Looked up in this order: ``--config PATH``, ``$AGNAV_CONFIG``, ``~/.config/agnav/host.toml``
(``$XDG_CONFIG_HOME`` respected); a missing default file means all defaults. Unknown sections or
keys are errors (a typo must not silently fall back to a default), and so are values out of range
(:data:`RULES`: rates, speeds and timeouts finite and > 0, MAVLink ids 1..255, min < max pairs,
enumerated strings, planner names from the planner registry). Every error reads
``FILE: [section] key: reason``. Command-line options override the file.

:func:`to_toml` writes a config back as TOML that :func:`load_config` reads (``agnav config``).
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

from ..toml_input import TomlTooDeep, loads_bounded

__all__ = ["HostConfig", "LinkConfig", "RunConfig", "CalibrationConfig", "ArduPilotConfig", "VizConfig", "RobotConfig",
           "FieldConfig", "LaserConfig",
           "ConfigError", "load_config", "default_config_path", "config_template", "to_toml", "validate_config",
           "SECTIONS", "RULES"]

SECTIONS = ("link", "run", "robot", "field", "laser", "tilted_laser", "calibration", "ardupilot", "viz")


class ConfigError(ValueError):
    """A bad host config; ``where`` is the (section, key) it is about, for the line in the file."""

    def __init__(self, message: str, where: tuple[str, ...] = ()) -> None:
        super().__init__(message)
        self.where = where


@dataclass
class LinkConfig:
    device: str = "serial:/dev/ttyUSB0:57600"  # or tcp:HOST:PORT, udp:HOST:PORT
    baud: int = 57600                  # baud of a serial device given without one
    sysid: int = 255                   # host MAVLink system id (GCS)
    compid: int = 190                  # host component id
    target_system: int = 0             # robot system id; 0 = first heartbeat seen
    heartbeat_hz: float = 1.0          # GCS heartbeat rate, Hz
    link_timeout_s: float = 3.0        # silence that marks the link lost, s
    reconnect_delay_s: float = 0.5     # between attempts to reopen a failed transport, s
    budget_bytes_s: float = 1500.0     # telemetry receive budget, B/s
    budget_window_s: float = 5.0       # averaging window of the receive rate, s
    log_dir: str = "logs"              # where run/calibrate write their .tlog
    key_file: str = ""                 # signing key; "" = ~/.config/agnav/signing.key if signing
    signing: bool = False              # sign outgoing frames
    require_signed: bool = False       # drop unsigned incoming frames


@dataclass
class RunConfig:
    control_hz: float = 10.0           # host planner / setpoint rate, Hz (>= 5: firmware link timeout)
    planner: str = ""                  # default planner; "" = firmware layers only
    max_speed_m_s: float = 0.6         # clamp on planner speed, m/s
    status_hz: float = 2.0             # status line rate, Hz
    goal_tolerance_m: float = 0.3      # goal reached radius for host planners, m
    start_x_m: float = 0.0             # the robot's start pose in the frame goals are given in, m
    start_y_m: float = 0.0
    start_yaw_deg: float = 0.0         # deg, counter-clockwise from +x
    landmarks_file: str = ""           # surveyed marker posts (CSV x_m,y_m,radius_m) to localise on; "" = odometry


@dataclass
class RobotConfig:
    """The host's view of the robot for planners; kinematics, wheelbase, track and top speed come from the
    firmware's parameters (DRIVE_KIND, WHEELBASE_MM, TRACK_MM, MAX_SPEED_MM_S)."""

    radius_m: float = 0.225            # footprint disc radius, m
    max_steer_deg: float = 0.0         # steering limit planners use, deg; 0 = the firmware's MAX_STEER_CDEG
    min_speed_m_s: float = 0.0         # slowest speed the drive holds (an RC car's dead band), m/s
    max_accel_m_s2: float = 1.0        # acceleration limit, m/s^2
    max_yaw_rate_rad_s: float = 1.2    # differential drive: turn-rate limit, rad/s
    footprint_offset_m: float = -1.0   # footprint centre ahead of the reference point, m; < 0 = half the wheelbase
                                       # for a car, 0 for a differential drive
    stop_lag_s: float = 0.0            # the drive's speed time constant, s; 0 = 0.25 s car, 0.12 s differential


@dataclass
class FieldConfig:
    """The field the field controllers work in (row-follower, row-navigator, proximity, rut-follower)."""

    row_side: str = "right"            # the robot's side of the row it follows (proximity): left or right
    row_offset_m: float = 1.0          # distance kept from the row (proximity), m
    row_half_width_m: float = 0.0      # row centre line to the face the laser sees, m
    row_method: str = "ransac"         # row detection: ransac, lsq, offset, triangle, hough
    turns: str = "left,1"              # headland turn pattern SIDE[,N]: first turn side, lanes per turn
    pattern: str = ""                  # row navigator: turn pattern in the Field Robot Event's notation (S-1L-2R-F)
    row_spacing_m: float = 0.75        # row navigator: the rows' spacing, m
    reverse: bool = True               # row navigator: may back up on the headland


@dataclass
class LaserConfig:
    """One laser scanner: its URL (see `agnav run --help`) and where it sits on the robot."""

    url: str = ""                      # e.g. tim5xx://192.168.0.1, ust://192.168.0.10, urg:/dev/ttyACM0; "" = none
    x_m: float = 0.0                   # position on the robot (x forward, y left), m
    y_m: float = 0.0
    yaw_deg: float = 0.0               # deg, counter-clockwise
    pitch_deg: float = 0.0             # pitched down from horizontal, deg (the tilted scanner: > 0)
    height_m: float = 0.0              # above the ground, m (the tilted scanner: > 0)


@dataclass
class CalibrationConfig:
    steer_pwm_min: int = 96            # sweep bounds, table PWM units (ref-003 byte)
    steer_pwm_max: int = 171
    steer_neutral_pwm: int = 133
    steer_step: int = 6                # PWM between sweep points
    steer_speed_pwm: int = 40          # raw speed PWM while sweeping the steering
    speed_pwm_min: int = 16
    speed_pwm_max: int = 110
    speed_step: int = 8
    settle_s: float = 1.0              # ignored start of every step, s
    hold_s: float = 3.0                # measured part of every step, s
    max_step_s: float = 6.0            # hard limit on one step, s
    pause_s: float = 1.0               # standstill (zero setpoints) between steps, s
    max_distance_m: float = 4.0        # a step ends early after this distance, m
    wheelbase_m: float = 0.174         # L for phi = atan(L * yaw_rate / v), m
    track_m: float = 0.191             # rear track for yaw rate from two wheel encoders, m
    dead_band_cdeg: int = 50           # |angle| below this counts as straight, cdeg
    dead_band_mm_s: int = 30           # |speed| below this counts as stopped, mm/s


@dataclass
class ArduPilotConfig:
    mode: str = "velocity"             # "velocity" (GUIDED) or "rc" (MANUAL + RC override)
    steer_channel: int = 1
    throttle_channel: int = 3
    trim_us: int = 1500
    half_range_us: int = 400
    reverse_steer: bool = False
    max_speed_m_s: float = 1.0
    max_steer_deg: float = 24.6
    wheelbase_m: float = 0.174


@dataclass
class VizConfig:
    rerun: bool = False                # record every run to an .rrd
    rrd_dir: str = "logs"


@dataclass
class HostConfig:
    link: LinkConfig = dataclasses.field(default_factory=LinkConfig)
    run: RunConfig = dataclasses.field(default_factory=RunConfig)
    robot: RobotConfig = dataclasses.field(default_factory=RobotConfig)
    field: FieldConfig = dataclasses.field(default_factory=FieldConfig)
    laser: LaserConfig = dataclasses.field(default_factory=LaserConfig)
    tilted_laser: LaserConfig = dataclasses.field(default_factory=LaserConfig)
    calibration: CalibrationConfig = dataclasses.field(default_factory=CalibrationConfig)
    ardupilot: ArduPilotConfig = dataclasses.field(default_factory=ArduPilotConfig)
    viz: VizConfig = dataclasses.field(default_factory=VizConfig)
    source: str = ""                   # file it came from ("" = defaults)


def default_config_path() -> Path:
    base = os.environ.get("XDG_CONFIG_HOME") or os.path.join(os.path.expanduser("~"), ".config")
    return Path(base) / "agnav" / "host.toml"


def _fill(obj: Any, table: dict[str, Any], section: str) -> None:
    fields = {f.name: f for f in dataclasses.fields(obj)}
    for k, v in table.items():
        if k not in fields:
            raise ConfigError(f"[{section}] unknown key {k!r}; known: {', '.join(fields)}", (section, k))
        cur = getattr(obj, k)
        if isinstance(cur, bool):
            if not isinstance(v, bool):
                raise ConfigError(f"[{section}] {k}: must be true or false, got {v!r}", (section, k))
        elif isinstance(cur, int):
            if isinstance(v, bool) or not isinstance(v, int):
                raise ConfigError(f"[{section}] {k}: must be an integer, got {v!r}", (section, k))
        elif isinstance(cur, float):
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise ConfigError(f"[{section}] {k}: must be a number, got {v!r}", (section, k))
            v = float(v)
        elif isinstance(cur, str) and not isinstance(v, str):
            raise ConfigError(f"[{section}] {k}: must be a string, got {v!r}", (section, k))
        setattr(obj, k, v)


# ---- value checks --------------------------------------------------------------------------------
Check = Callable[[Any], "str | None"]  # value -> reason it is wrong, or None


def _positive(v: Any) -> str | None:
    if not math.isfinite(v):
        return f"must be a finite number > 0, got {v!r}"
    return None if v > 0 else f"must be > 0, got {v!r}"


def _nonneg(v: Any) -> str | None:
    if not math.isfinite(v):
        return f"must be a finite number >= 0, got {v!r}"
    return None if v >= 0 else f"must be >= 0, got {v!r}"


def _between(lo: float, hi: float, what: str = "") -> Check:
    def check(v: Any) -> str | None:
        if not math.isfinite(v) or not lo <= v <= hi:
            return f"must be {lo:g}..{hi:g}{what}, got {v!r}"
        return None

    return check


def _one_of(*allowed: str) -> Check:
    def check(v: Any) -> str | None:
        return None if v in allowed else f"must be one of {', '.join(repr(a) for a in allowed)}, got {v!r}"

    return check


def _non_empty(v: Any) -> str | None:
    return None if v.strip() else "must not be empty"


def _path_text(v: Any) -> str | None:
    """A file or directory name: not empty, no NUL or other control character (no file system takes them)."""
    if not v.strip():
        return "must not be empty"
    bad = [c for c in v if ord(c) < 32]
    if bad:
        return f"must not hold control characters (found {bad[0]!r}); got {v!r}"
    return None


def _planner(v: Any) -> str | None:
    if not v:
        return None  # firmware layers only
    try:
        from ..planning.registry import canonical_name
    except ImportError:  # the planning area is not in this build: nothing to check against
        return None
    try:
        canonical_name(v)
    except ValueError as e:
        return str(e)
    return None


def _finite(v: Any) -> str | None:
    return None if math.isfinite(v) else f"must be a finite number, got {v!r}"


def _refusal(parse: Callable[[Any], object], error: type[Exception], v: Any) -> str | None:
    """Why ``parse(v)`` refuses ``v`` (its ``error``'s message), or None when it takes it."""
    try:
        parse(v)
    except error as e:
        return str(e)
    return None


def _laser_url(v: Any) -> str | None:
    from ..lasers import LaserUrlError, parse_laser_url

    why = _refusal(parse_laser_url, LaserUrlError, v) if v else None
    return why.replace("--laser ", "", 1) if why else None


def _pattern(v: Any) -> str | None:
    from ..planning.row_navigator import PatternError, parse_pattern

    return _refusal(parse_pattern, PatternError, v)


def _turns(v: Any) -> str | None:
    from ..planning.registry import parse_turn_pattern

    return _refusal(parse_turn_pattern, ValueError, v)


_LASER_RULES: dict[str, Check] = {"url": _laser_url, "x_m": _finite, "y_m": _finite, "yaw_deg": _finite,
                                  "pitch_deg": lambda v: None if math.isfinite(v) and 0 <= v < 90 else
                                  f"must be 0 (horizontal) .. < 90 deg, got {v!r}", "height_m": _nonneg}
_PWM = _between(0, 255, " (table PWM units, one byte)")
_MAVLINK_ID = _between(1, 255, " (a MAVLink id)")

#: section -> key -> check. Keys left out take any value of the right type.
RULES: dict[str, dict[str, Check]] = {
    "link": {
        "device": _non_empty, "baud": _positive, "sysid": _MAVLINK_ID, "compid": _MAVLINK_ID,
        "target_system": _between(0, 255, " (0 = the first heartbeat seen)"), "heartbeat_hz": _positive,
        "link_timeout_s": _positive, "reconnect_delay_s": _positive, "budget_bytes_s": _positive,
        "budget_window_s": _positive, "log_dir": _path_text,
        "key_file": lambda v: None if not v else _path_text(v),
    },
    "run": {
        "control_hz": lambda v: None if math.isfinite(v) and v >= 5.0 else
        f"must be >= 5 (the firmware's link timeout is 500 ms), got {v!r}",
        "planner": _planner, "max_speed_m_s": _positive, "status_hz": _positive, "goal_tolerance_m": _positive,
        "start_x_m": _finite, "start_y_m": _finite, "start_yaw_deg": _finite,
    },
    "robot": {
        "radius_m": _positive, "max_steer_deg": lambda v: None if math.isfinite(v) and 0 <= v < 90 else
        f"must be 0 (the firmware's) .. < 90 deg, got {v!r}", "min_speed_m_s": _nonneg, "max_accel_m_s2": _positive,
        "max_yaw_rate_rad_s": _positive, "footprint_offset_m": _finite, "stop_lag_s": _nonneg,
    },
    "field": {
        "row_side": _one_of("left", "right"), "row_offset_m": lambda v: None if math.isfinite(v) and v >= 0.05 else
        f"must be >= 0.05 m, got {v!r}", "row_half_width_m": _nonneg,
        "row_method": _one_of("offset", "lsq", "triangle", "ransac", "hough"), "turns": _turns,
        "pattern": lambda v: None if not v else _pattern(v),
        "row_spacing_m": lambda v: None if math.isfinite(v) and 0.2 <= v <= 10.0 else
        f"must be a number 0.2-10 m, got {v!r}",
    },
    "laser": _LASER_RULES,
    "tilted_laser": _LASER_RULES,
    "calibration": {
        "steer_pwm_min": _PWM, "steer_pwm_max": _PWM, "steer_neutral_pwm": _PWM, "steer_step": _between(1, 255),
        "steer_speed_pwm": _PWM, "speed_pwm_min": _PWM, "speed_pwm_max": _PWM, "speed_step": _between(1, 255),
        "settle_s": _nonneg, "hold_s": _positive, "max_step_s": _positive, "pause_s": _nonneg,
        "max_distance_m": _positive, "wheelbase_m": _positive, "track_m": _positive, "dead_band_cdeg": _nonneg,
        "dead_band_mm_s": _nonneg,
    },
    "ardupilot": {
        "mode": _one_of("velocity", "rc"), "steer_channel": _between(1, 8, " (RC override channel)"),
        "throttle_channel": _between(1, 8, " (RC override channel)"), "trim_us": _between(800, 2200, " us"),
        "half_range_us": _between(1, 1000, " us"), "max_speed_m_s": _positive,
        "max_steer_deg": lambda v: None if math.isfinite(v) and 0 < v < 90 else f"must be > 0 and < 90, got {v!r}",
        "wheelbase_m": _positive,
    },
    "viz": {"rrd_dir": _path_text},
}

#: (section, low key, high key): low must be < high.
ORDERED_PAIRS = (("calibration", "steer_pwm_min", "steer_pwm_max"), ("calibration", "speed_pwm_min", "speed_pwm_max"),
                 # a sweep step settles first, then measures: with no time left after settling it measures nothing
                 ("calibration", "settle_s", "max_step_s"))


def validate_config(cfg: HostConfig) -> None:
    """Range checks of :data:`RULES` and :data:`ORDERED_PAIRS`; ConfigError ``[section] key: reason``."""
    for section, rules in RULES.items():
        obj = getattr(cfg, section)
        for key, check in rules.items():
            why = check(getattr(obj, key))
            if why:
                raise ConfigError(f"[{section}] {key}: {why}", (section, key))
    for section, lo, hi in ORDERED_PAIRS:
        obj = getattr(cfg, section)
        if getattr(obj, lo) >= getattr(obj, hi):
            raise ConfigError(f"[{section}] {lo}: must be < {hi} ({getattr(obj, lo)} >= {getattr(obj, hi)})", (section, lo))
    c = cfg.calibration
    if not c.steer_pwm_min <= c.steer_neutral_pwm <= c.steer_pwm_max:
        raise ConfigError(f"[calibration] steer_neutral_pwm: must lie in steer_pwm_min..steer_pwm_max "
                          f"({c.steer_pwm_min}..{c.steer_pwm_max}), got {c.steer_neutral_pwm}", ("calibration", "steer_neutral_pwm"))
    tl = cfg.tilted_laser
    if tl.url and not (tl.pitch_deg > 0 and tl.height_m > 0):
        raise ConfigError("[tilted_laser] pitch_deg: the tilted scanner needs its pitch (> 0 deg) and height_m (> 0 m)",
                          ("tilted_laser", "pitch_deg"))
    a = cfg.ardupilot
    if a.steer_channel == a.throttle_channel:
        raise ConfigError(f"[ardupilot] throttle_channel: must differ from steer_channel ({a.steer_channel})",
                          ("ardupilot", "throttle_channel"))


def load_config(path: str | Path | None = None) -> HostConfig:
    """Load the host config (see module docstring); raises ConfigError naming the file and the key."""
    explicit = path or os.environ.get("AGNAV_CONFIG")
    p = Path(explicit) if explicit else default_config_path()
    cfg = HostConfig()
    if p.is_dir():
        raise ConfigError(f"config file {p} is a directory, not a TOML file")
    if not p.is_file():
        if explicit:
            raise ConfigError(f"config file {p} not found")
        return cfg
    try:
        text = p.read_text()
        data = loads_bounded(text)
    except (tomllib.TOMLDecodeError, TomlTooDeep) as e:
        raise ConfigError(f"{p}: {e}") from None
    except (OSError, UnicodeDecodeError) as e:
        raise ConfigError(f"{p}: cannot read: {getattr(e, 'strerror', None) or e}") from None
    try:
        for section, table in data.items():
            if section not in SECTIONS:
                raise ConfigError(f"unknown section [{section}]; known: {', '.join(f'[{s}]' for s in SECTIONS)}", (section,))
            if not isinstance(table, dict):
                raise ConfigError(f"[{section}] must be a table (a [{section}] header with key = value lines), "
                                  f"got {section} = {table!r}", (section,))
            _fill(getattr(cfg, section), table, section)
        validate_config(cfg)
    except ConfigError as e:
        from ..sim.scenario import locate_line

        line = locate_line(text, e.where) if e.where else None
        raise ConfigError(f"{p}:{line}: {e}" if line else f"{p}: {e}", e.where) from None
    cfg.source = str(p)
    return cfg


def _toml_value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)  # a JSON string with ASCII escapes is a TOML basic string
    if isinstance(v, float):
        return repr(v) if math.isfinite(v) else ("nan" if math.isnan(v) else ("inf" if v > 0 else "-inf"))
    return repr(v)


def to_toml(cfg: HostConfig, header: str = "") -> str:
    """``cfg`` as a TOML file that :func:`load_config` reads back to the same values."""
    out = [f"# {line}" for line in header.splitlines()] if header else []
    for section in SECTIONS:
        out.append(f"\n[{section}]" if out else f"[{section}]")
        obj = getattr(cfg, section)
        for f in dataclasses.fields(obj):
            out.append(f"{f.name} = {_toml_value(getattr(obj, f.name))}")
    return "\n".join(out) + "\n"


def config_template() -> str:
    """A complete config file with every default (``agnav config --template`` prints it)."""
    return to_toml(HostConfig(), "AgNav host configuration (all keys optional; units in docs/user_guide.md)")
