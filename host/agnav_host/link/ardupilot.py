"""Drive a stock ArduPilot Rover with the host planners (``agnav run --autopilot ardupilot``).

Ref 001's greenhouse robot ran a Pixhawk with ArduPilot Rover and a companion computer sending it
MAVLink. Two mappings are offered, chosen by ``mode``:

``rc`` (MANUAL mode, RC_CHANNELS_OVERRIDE)
    ch1 (steering) = trim - steer / max_steer * half_range  (right stick = right turn, so a left /
    positive REP-103 turn gives ch1 < trim; ``reverse_steer`` flips it), ch3 (throttle) = trim +
    speed / max_speed * half_range. Channels 2 and 4-8 are sent as UINT16_MAX ("ignore"); 9-18 as 0.
    :meth:`ArduRover.release` sends 0 on ch1 and ch3 (hand back to the RC radio).

``velocity`` (GUIDED mode, SET_POSITION_TARGET_LOCAL_NED in MAV_FRAME_BODY_NED)
    vx = speed, vy = vz = 0, yaw_rate = -yaw_rate_ccw (NED is clockwise positive); position,
    acceleration and yaw are masked out. Ackermann planners that give a steering angle are
    converted with yaw_rate = v tan(phi) / L.

Stop: zero command, then HOLD mode (4); e-stop: force-disarm (MAV_CMD_COMPONENT_ARM_DISARM 0 with
param2 = 21196). Mode numbers are ArduPilot Rover's: MANUAL 0, HOLD 4, GUIDED 15.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from ..types import DriveCommand
from .endpoint import Endpoint
from .robot import CommandFailed, MAV_RESULT_NAMES

__all__ = ["ArduRover", "ArduRoverConfig", "ROVER_MODES", "rc_from_drive", "velocity_target_from_drive",
           "VELOCITY_TYPE_MASK", "MAV_FRAME_BODY_NED"]

ROVER_MODES = {"MANUAL": 0, "ACRO": 1, "STEERING": 3, "HOLD": 4, "LOITER": 5, "AUTO": 10, "RTL": 11, "GUIDED": 15}
MAV_FRAME_BODY_NED = 8
# ignore x y z (1|2|4), ax ay az (64|128|256), yaw (1024): use vx vy vz and yaw_rate
VELOCITY_TYPE_MASK = 1 | 2 | 4 | 64 | 128 | 256 | 1024
FORCE_DISARM = 21196.0
UINT16_MAX = 65535


@dataclass(frozen=True)
class ArduRoverConfig:
    mode: str = "velocity"          # "velocity" (GUIDED) or "rc" (MANUAL + RC override)
    steer_channel: int = 1          # RCMAP_ROLL on Rover
    throttle_channel: int = 3       # RCMAP_THROTTLE
    trim_us: int = 1500
    half_range_us: int = 400        # full deflection = trim +- this
    reverse_steer: bool = False
    max_steer_rad: float = math.radians(24.6)
    max_speed_m_s: float = 1.0
    wheelbase_m: float = 0.174      # used to turn a steering angle into a yaw rate

    def __post_init__(self) -> None:
        if self.mode not in ("velocity", "rc"):
            raise ValueError(f"ardupilot mode must be 'velocity' or 'rc', got {self.mode!r}")
        for ch in (self.steer_channel, self.throttle_channel):
            if not 1 <= ch <= 8:
                raise ValueError("RC override channels must be 1..8")
        if self.steer_channel == self.throttle_channel:
            raise ValueError("steering and throttle need different channels")


def _yaw_rate(cmd: DriveCommand, wheelbase_m: float) -> float:
    if cmd.steer_rad is not None:
        return cmd.speed_m_s * math.tan(cmd.steer_rad) / wheelbase_m
    return cmd.yaw_rate_rad_s


def _steer(cmd: DriveCommand, wheelbase_m: float) -> float:
    if cmd.steer_rad is not None:
        return cmd.steer_rad
    if abs(cmd.speed_m_s) < 1e-3:
        return 0.0
    return math.atan(wheelbase_m * cmd.yaw_rate_rad_s / cmd.speed_m_s)


def rc_from_drive(cmd: DriveCommand, cfg: ArduRoverConfig) -> list[int]:
    """The 18 RC_CHANNELS_OVERRIDE values for ``cmd`` (see module docstring)."""
    s = max(-1.0, min(1.0, _steer(cmd, cfg.wheelbase_m) / cfg.max_steer_rad))
    v = max(-1.0, min(1.0, cmd.speed_m_s / cfg.max_speed_m_s))
    sign = 1 if cfg.reverse_steer else -1
    ch = [UINT16_MAX] * 8 + [0] * 10
    ch[cfg.steer_channel - 1] = int(round(cfg.trim_us + sign * s * cfg.half_range_us))
    ch[cfg.throttle_channel - 1] = int(round(cfg.trim_us + v * cfg.half_range_us))
    return ch


def velocity_target_from_drive(cmd: DriveCommand, cfg: ArduRoverConfig) -> dict[str, float]:
    """Body-frame NED velocity target fields for ``cmd``."""
    v = max(-cfg.max_speed_m_s, min(cfg.max_speed_m_s, cmd.speed_m_s))
    return {"vx": v, "vy": 0.0, "vz": 0.0, "yaw_rate": -_yaw_rate(DriveCommand(v, cmd.yaw_rate_rad_s, cmd.steer_rad),
                                                                   cfg.wheelbase_m)}


class ArduRover:
    """Same ``drive`` / ``stop`` / ``estop`` interface as :class:`~.robot.AgnavRobot`, for ArduPilot."""

    def __init__(self, ep: Endpoint, cfg: ArduRoverConfig | None = None, timeout_s: float = 1.0, retries: int = 3) -> None:
        self.ep = ep
        self.cfg = cfg or ArduRoverConfig()
        self.timeout_s, self.retries = timeout_s, retries

    @property
    def state(self) -> Any:
        return self.ep.state

    def _tgt(self) -> tuple[int, int]:
        return self.ep.target_system, self.ep.target_component

    def command(self, command: int, *params: float, what: str = "") -> int:
        p = (list(params) + [0.0] * 7)[:7]
        ack = self.ep.request(lambda: self.ep.mav.command_long_encode(*self._tgt(), command, 0, *p), "COMMAND_ACK",
                              lambda m: m.command == command, self.timeout_s, self.retries, what or str(command))
        if ack.result != 0:
            raise CommandFailed(f"{what or command}: {MAV_RESULT_NAMES.get(ack.result, ack.result)}")
        return 0

    def set_mode(self, name: str) -> int:
        mode = ROVER_MODES[name.upper()]
        return self.command(176, 1.0, float(mode), what=f"set mode {name}")  # MAV_CMD_DO_SET_MODE, custom mode

    def arm(self, arm: bool = True) -> int:
        return self.command(400, 1.0 if arm else 0.0, what="arm" if arm else "disarm")

    def start(self) -> None:
        """Mode for the chosen mapping, then arm."""
        self.set_mode("GUIDED" if self.cfg.mode == "velocity" else "MANUAL")
        self.arm(True)

    def drive_command(self, cmd: DriveCommand) -> bool:
        if self.cfg.mode == "rc":
            return self.ep.send(self.ep.mav.rc_channels_override_encode(*self._tgt(), *rc_from_drive(cmd, self.cfg)))
        f = velocity_target_from_drive(cmd, self.cfg)
        return self.ep.send(self.ep.mav.set_position_target_local_ned_encode(
            0, *self._tgt(), MAV_FRAME_BODY_NED, VELOCITY_TYPE_MASK, 0.0, 0.0, 0.0, f["vx"], f["vy"], f["vz"],
            0.0, 0.0, 0.0, 0.0, f["yaw_rate"]))

    def drive(self, steer_rad: float, speed_m_s: float) -> bool:
        return self.drive_command(DriveCommand(speed_m_s=speed_m_s, steer_rad=steer_rad))

    def stop(self) -> bool:
        return self.drive_command(DriveCommand(0.0, 0.0, 0.0))

    def release(self) -> bool:
        """RC mode: hand steering and throttle back to the radio."""
        ch = [UINT16_MAX] * 8 + [0] * 10
        ch[self.cfg.steer_channel - 1] = 0
        ch[self.cfg.throttle_channel - 1] = 0
        return self.ep.send(self.ep.mav.rc_channels_override_encode(*self._tgt(), *ch))

    def estop(self, engage: bool = True) -> int:
        """Stop now: zero command, HOLD, force-disarm. ``engage=False`` re-arms."""
        if not engage:
            return self.arm(True)
        self.stop()
        try:
            self.set_mode("HOLD")
        finally:
            self.command(400, 0.0, FORCE_DISARM, what="force disarm")
        return 0
