"""Host configuration: one TOML file, every key optional (docs/user_guide.md lists them with units).

Looked up in this order: ``--config PATH``, ``$AGNAV_CONFIG``, ``~/.config/agnav/host.toml``
(``$XDG_CONFIG_HOME`` respected); a missing default file means all defaults. Unknown sections or
keys are errors (a typo must not silently fall back to a default). Command-line options override
the file.
"""

from __future__ import annotations

import dataclasses
import os
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

__all__ = ["HostConfig", "LinkConfig", "RunConfig", "CalibrationConfig", "ArduPilotConfig", "VizConfig",
           "ConfigError", "load_config", "default_config_path", "config_template"]


class ConfigError(ValueError):
    pass


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
    link: LinkConfig = field(default_factory=LinkConfig)
    run: RunConfig = field(default_factory=RunConfig)
    calibration: CalibrationConfig = field(default_factory=CalibrationConfig)
    ardupilot: ArduPilotConfig = field(default_factory=ArduPilotConfig)
    viz: VizConfig = field(default_factory=VizConfig)
    source: str = ""                   # file it came from ("" = defaults)


def default_config_path() -> Path:
    base = os.environ.get("XDG_CONFIG_HOME") or os.path.join(os.path.expanduser("~"), ".config")
    return Path(base) / "agnav" / "host.toml"


def _fill(obj: Any, table: dict[str, Any], section: str) -> None:
    fields = {f.name: f for f in dataclasses.fields(obj)}
    for k, v in table.items():
        if k not in fields:
            raise ConfigError(f"[{section}] unknown key {k!r}; known: {', '.join(fields)}")
        cur = getattr(obj, k)
        if isinstance(cur, bool):
            if not isinstance(v, bool):
                raise ConfigError(f"[{section}] {k} must be true or false, got {v!r}")
        elif isinstance(cur, int):
            if isinstance(v, bool) or not isinstance(v, int):
                raise ConfigError(f"[{section}] {k} must be an integer, got {v!r}")
        elif isinstance(cur, float):
            if isinstance(v, bool) or not isinstance(v, (int, float)):
                raise ConfigError(f"[{section}] {k} must be a number, got {v!r}")
            v = float(v)
        elif isinstance(cur, str) and not isinstance(v, str):
            raise ConfigError(f"[{section}] {k} must be a string, got {v!r}")
        setattr(obj, k, v)


def load_config(path: str | Path | None = None) -> HostConfig:
    """Load the host config (see module docstring); raises ConfigError with the offending key."""
    explicit = path or os.environ.get("AGNAV_CONFIG")
    p = Path(explicit) if explicit else default_config_path()
    cfg = HostConfig()
    if not p.is_file():
        if explicit:
            raise ConfigError(f"config file {p} not found")
        return cfg
    try:
        data = tomllib.loads(p.read_text())
    except tomllib.TOMLDecodeError as e:
        raise ConfigError(f"{p}: {e}") from None
    for section, table in data.items():
        if section not in ("link", "run", "calibration", "ardupilot", "viz") or not isinstance(table, dict):
            raise ConfigError(f"{p}: unknown section [{section}]")
        _fill(getattr(cfg, section), table, section)
    if cfg.run.control_hz < 5.0:
        raise ConfigError(f"{p}: [run] control_hz must be >= 5 (the firmware's link timeout is 500 ms)")
    cfg.source = str(p)
    return cfg


def config_template() -> str:
    """A complete config file with every default (``agnav config`` prints it)."""
    out = ["# AgNav host configuration (all keys optional; units in docs/user_guide.md)"]
    cfg = HostConfig()
    for section in ("link", "run", "calibration", "ardupilot", "viz"):
        out.append(f"\n[{section}]")
        for f in dataclasses.fields(getattr(cfg, section)):
            v = getattr(getattr(cfg, section), f.name)
            if isinstance(v, bool):
                s = "true" if v else "false"
            elif isinstance(v, str):
                s = f'"{v}"'
            else:
                s = repr(v)
            out.append(f"{f.name} = {s}")
    return "\n".join(out) + "\n"
