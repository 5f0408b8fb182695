"""Typed robot state kept by the host link (SI units, REP-103 frames).

:class:`RobotState` is filled by :class:`~agnav_host.link.endpoint.Endpoint` from the telemetry the
firmware sends (see docs/protocol.md for rates): AGNAV_ODOMETRY -> :attr:`RobotState.pose`,
AGNAV_BEHAVIOUR_STATUS -> :attr:`RobotState.behaviour`, AGNAV_SONAR_RING -> :attr:`RobotState.sonar`,
AGNAV_ENCODER_STATUS -> :attr:`RobotState.encoders`, PARAM_VALUE -> :attr:`RobotState.params`,
STATUSTEXT -> :attr:`RobotState.statustexts`. A stock autopilot (ArduPilot) fills the pose from
LOCAL_POSITION_NED + ATTITUDE instead (NED converted to REP-103 at the edge: y = -y_ned,
yaw = -yaw_ned).

Every record carries ``rx_time_s`` (host monotonic clock at reception) next to the robot's own
``time_boot_s``.
"""

from __future__ import annotations

import math
import threading
from collections import deque
from dataclasses import dataclass, field
from typing import Any

from ..units import cdeg_to_rad, milli_to_si

__all__ = [
    "LAYER_NAMES",
    "REASON_NAMES",
    "FAILSAFE_FLAG_NAMES",
    "SONAR_STATUS_NAMES",
    "PoseState",
    "BehaviourState",
    "SonarState",
    "EncoderState",
    "StatusText",
    "LinkStats",
    "RobotState",
    "flag_names",
]

LAYER_NAMES = {0: "IDLE", 1: "FAILSAFE", 2: "AVOID_OBSTACLE", 3: "MANUAL", 4: "FOLLOW_WALL",
               5: "HOST_COMMAND", 6: "MOVE_TO_GOAL"}
REASON_NAMES = {0: "NONE", 1: "ESTOP", 2: "LINK_LOSS", 3: "SENSOR_FAULT", 4: "WATCHDOG_BOOT",
                5: "OBSTACLE_STOP", 6: "OBSTACLE_BACKOFF", 7: "OBSTACLE_WAIT", 8: "MANUAL_OVERRIDE",
                9: "WALL_LEFT", 10: "WALL_RIGHT", 11: "CANYON_TIMER", 12: "HOST_SETPOINT",
                13: "GOAL_SEEK", 14: "GOAL_REACHED", 15: "NO_COMMAND"}
FAILSAFE_FLAG_NAMES = {1: "ESTOP", 2: "LINK_LOSS", 4: "ENCODER_FAULT", 8: "SONAR_FAULT",
                       16: "WATCHDOG_RESET", 32: "CALIB_DEFAULTED"}
SONAR_STATUS_NAMES = {0: "VALID", 1: "NO_ECHO", 2: "FAULT", 3: "STALE"}
SONAR_SPACING_RAD = math.radians(30.0)  # ring of 12: sensor 0 forward, 30 deg apart CCW


def flag_names(flags: int) -> list[str]:
    """Names of the AGNAV_FAILSAFE_FLAG bits set in ``flags``."""
    return [n for bit, n in FAILSAFE_FLAG_NAMES.items() if flags & bit]


@dataclass(frozen=True)
class PoseState:
    """Dead-reckoned pose (odometry frame), m / rad, and body velocities."""

    time_boot_s: float
    x_m: float
    y_m: float
    yaw_rad: float
    speed_m_s: float
    yaw_rate_rad_s: float
    rx_time_s: float


@dataclass(frozen=True)
class BehaviourState:
    """Active firmware layer, its reason, failsafe flags and the command sent to the actuators."""

    time_boot_s: float
    layer: int
    reason: int
    flags: int
    steer_rad: float
    speed_m_s: float
    rx_time_s: float

    @property
    def layer_name(self) -> str:
        return LAYER_NAMES.get(self.layer, f"LAYER_{self.layer}")

    @property
    def reason_name(self) -> str:
        return REASON_NAMES.get(self.reason, f"REASON_{self.reason}")

    @property
    def flag_names(self) -> list[str]:
        return flag_names(self.flags)


@dataclass(frozen=True)
class SonarState:
    """One sonar-ring frame. ``ranges_m`` per sensor (max range on NO_ECHO, 0 on FAULT/STALE)."""

    time_boot_s: float
    ranges_m: tuple[float, ...]
    status: tuple[int, ...]
    count: int
    seq: int
    rx_time_s: float

    @property
    def bearings_rad(self) -> tuple[float, ...]:
        """Mounting bearing of each sensor slot in the body frame (sensor 0 forward, CCW)."""
        return tuple(i * SONAR_SPACING_RAD for i in range(len(self.ranges_m)))


@dataclass(frozen=True)
class EncoderState:
    """Wheel encoders: raw counts (wrap modulo 2^32), surface speeds m/s, error counters."""

    time_boot_s: float
    counts: tuple[int, ...]
    speeds_m_s: tuple[float, ...]
    errors: tuple[int, ...]
    wheels: int
    rx_time_s: float


@dataclass(frozen=True)
class StatusText:
    rx_time_s: float
    severity: int
    text: str


@dataclass
class LinkStats:
    """Counters of one link session; they survive reconnects."""

    rx_bytes: int = 0
    tx_bytes: int = 0
    rx_msgs: int = 0
    tx_msgs: int = 0
    tx_dropped: int = 0          # sends attempted while the transport was down
    rx_parse_errors: int = 0     # bad CRC / bad signature / garbage
    rx_seq_lost: int = 0         # gaps in the robot's sequence numbers
    reconnects: int = 0          # transport reopened after a failure
    link_losses: int = 0         # robot went silent for longer than the link timeout
    budget_warnings: int = 0     # warnings raised (rate-limited) for a receive rate above the budget
    budget_windows_over: int = 0  # rate checks (every 0.5 s) that found the rate above the budget
    rx_rate_bytes_s: float = 0.0  # sliding-window receive rate
    peak_rx_rate_bytes_s: float = 0.0
    link_up: bool = False        # bytes arrived within the link timeout
    transport_open: bool = False


@dataclass
class RobotState:
    """Latest state of the robot as seen through the link (thread-safe snapshot via :meth:`copy`)."""

    pose: PoseState | None = None
    behaviour: BehaviourState | None = None
    sonar: SonarState | None = None
    encoders: EncoderState | None = None
    heartbeat: Any = None                # last HEARTBEAT of the target
    heartbeat_rx_time_s: float | None = None
    params: dict[str, float] = field(default_factory=dict)
    param_index: dict[int, str] = field(default_factory=dict)
    param_count: int | None = None
    statustexts: deque[StatusText] = field(default_factory=lambda: deque(maxlen=200))
    msg_counts: dict[str, int] = field(default_factory=dict)
    named_values: dict[str, float] = field(default_factory=dict)
    lock: threading.RLock = field(default_factory=threading.RLock, repr=False, compare=False)

    def copy(self) -> "RobotState":
        with self.lock:
            return RobotState(self.pose, self.behaviour, self.sonar, self.encoders, self.heartbeat,
                              self.heartbeat_rx_time_s, dict(self.params), dict(self.param_index),
                              self.param_count, deque(self.statustexts, maxlen=200), dict(self.msg_counts),
                              dict(self.named_values))

    # ---- updating from messages ---------------------------------------------------------------
    def update(self, msg: Any, now_s: float, target_system: int | None = None) -> None:
        """Fold one decoded message into the state (messages of other systems update counters only)."""
        t = msg.get_type()
        with self.lock:
            self.msg_counts[t] = self.msg_counts.get(t, 0) + 1
            if target_system not in (None, 0) and msg.get_srcSystem() != target_system:
                return
            if t == "AGNAV_ODOMETRY":
                self.pose = PoseState(milli_to_si(msg.time_boot_ms), milli_to_si(msg.x_mm), milli_to_si(msg.y_mm),
                                      cdeg_to_rad(msg.yaw_cdeg), milli_to_si(msg.speed_mm_s),
                                      cdeg_to_rad(msg.yaw_rate_cdeg_s), now_s)
            elif t == "AGNAV_BEHAVIOUR_STATUS":
                self.behaviour = BehaviourState(milli_to_si(msg.time_boot_ms), msg.active_layer, msg.reason,
                                                msg.failsafe_flags, cdeg_to_rad(msg.steer_cdeg),
                                                milli_to_si(msg.speed_mm_s), now_s)
            elif t == "AGNAV_SONAR_RING":
                n = 12
                self.sonar = SonarState(milli_to_si(msg.time_boot_ms), tuple(milli_to_si(r) for r in msg.ranges_mm[:n]),
                                        tuple(msg.status[:n]), msg.count, msg.seq, now_s)
            elif t == "AGNAV_ENCODER_STATUS":
                k = max(0, min(4, msg.count_wheels))
                self.encoders = EncoderState(milli_to_si(msg.time_boot_ms), tuple(msg.count[:k]),
                                             tuple(milli_to_si(s) for s in msg.speed_mm_s[:k]), tuple(msg.errors[:k]),
                                             k, now_s)
            elif t == "HEARTBEAT":
                self.heartbeat = msg
                self.heartbeat_rx_time_s = now_s
            elif t == "PARAM_VALUE":
                name = _text(msg.param_id)
                self.params[name] = float(msg.param_value)
                if 0 <= msg.param_index < 65535:
                    self.param_index[msg.param_index] = name
                self.param_count = msg.param_count
            elif t == "STATUSTEXT":
                self.statustexts.append(StatusText(now_s, msg.severity, _text(msg.text)))
            elif t == "NAMED_VALUE_INT" or t == "NAMED_VALUE_FLOAT":
                self.named_values[_text(msg.name)] = float(msg.value)
            elif t == "LOCAL_POSITION_NED":  # stock autopilot (ArduPilot): NED -> REP-103
                yaw = self.pose.yaw_rad if self.pose else 0.0
                rate = self.pose.yaw_rate_rad_s if self.pose else 0.0
                c, s = math.cos(yaw), math.sin(yaw)
                vx, vy = msg.vx, -msg.vy
                self.pose = PoseState(milli_to_si(msg.time_boot_ms), msg.x, -msg.y, yaw, c * vx + s * vy, rate, now_s)
            elif t == "ATTITUDE":
                p = self.pose or PoseState(milli_to_si(msg.time_boot_ms), 0.0, 0.0, 0.0, 0.0, 0.0, now_s)
                self.pose = PoseState(p.time_boot_s, p.x_m, p.y_m, -msg.yaw, p.speed_m_s, -msg.yawspeed, now_s)


def _text(v: Any) -> str:
    if isinstance(v, (bytes, bytearray)):
        v = v.decode("ascii", "replace")
    return str(v).split("\x00", 1)[0]
