"""Host side of the link: the MAVLink endpoint the host planner uses (sim or real radio alike).

It only turns calls into bytes and bytes into state: :meth:`HostEndpoint.feed` takes what the
radio delivered (decoded by pymavlink's parser of the dialect), :meth:`HostEndpoint.take_tx` returns
what to put on the radio. Units on the wire are the firmware's (cdeg, mm/s, mm); helpers take SI
(:mod:`agnav_host.units`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from ..protocol import dialect, new_codec
from ..units import cdeg_to_rad, milli_to_si, rad_to_cdeg, si_to_milli

__all__ = ["HostEndpoint", "Odometry", "BehaviourStatus", "SonarRingFrame"]

MAV_CMD_AGNAV_SET_BEHAVIOURS = 45901


@dataclass(frozen=True)
class Odometry:
    t_us: int  # host receive time
    time_boot_ms: int
    x_m: float
    y_m: float
    heading_rad: float
    speed_m_s: float
    yaw_rate_rad_s: float


@dataclass(frozen=True)
class BehaviourStatus:
    t_us: int
    time_boot_ms: int
    layer: int
    reason: int
    failsafe_flags: int
    steer_cdeg: int
    speed_mm_s: int


@dataclass(frozen=True)
class SonarRingFrame:
    t_us: int
    time_boot_ms: int
    ranges_mm: tuple[int, ...]
    status: tuple[int, ...]
    seq: int


@dataclass
class HostEndpoint:
    """MAVLink endpoint of the host (system 255, component 190 by default)."""

    target_system: int = 1
    target_component: int = 1
    sysid: int = 255
    compid: int = 190
    keep_history: bool = True
    odometry: Odometry | None = None
    status: BehaviourStatus | None = None
    sonar: SonarRingFrame | None = None
    heartbeat_seen_us: int | None = None
    sys_status: Any = None  # the latest SYS_STATUS (health bits, refusal and signing counters)
    odometry_log: list[Odometry] = field(default_factory=list)
    status_log: list[BehaviourStatus] = field(default_factory=list)
    sonar_log: list[SonarRingFrame] = field(default_factory=list)
    acks: list[Any] = field(default_factory=list)
    calib_acks: list[Any] = field(default_factory=list)
    params: dict[str, int] = field(default_factory=dict)
    statustexts: list[tuple[int, str]] = field(default_factory=list)
    rx_counts: dict[str, int] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self._mav = new_codec(self.sysid, self.compid)
        self._d = dialect()
        self._tx = bytearray()
        self._seq = 0

    # ---- sending ---------------------------------------------------------------------------------
    def _send(self, msg: Any) -> None:
        self._tx += msg.pack(self._mav)
        self._mav.seq = (self._mav.seq + 1) % 256

    def take_tx(self) -> bytes:
        out = bytes(self._tx)
        self._tx.clear()
        return out

    def heartbeat(self) -> None:
        d = self._d
        self._send(d.MAVLink_heartbeat_message(d.MAV_TYPE_GCS, d.MAV_AUTOPILOT_INVALID, 0, 0, d.MAV_STATE_ACTIVE, 3))

    def setpoint(self, steer_cdeg: float, speed_mm_s: float) -> None:
        d = self._d
        self._seq = (self._seq + 1) & 0xFFFF
        s = max(-32767, min(32767, int(round(steer_cdeg))))
        v = max(-32767, min(32767, int(round(speed_mm_s))))
        self._send(d.MAVLink_agnav_drive_setpoint_message(self.target_system, self.target_component, s, v, 0, 0,
                                                          d.AGNAV_DRIVE_PHYSICAL, self._seq))

    def setpoint_si(self, steer_rad: float, speed_m_s: float) -> None:
        self.setpoint(rad_to_cdeg(steer_rad), si_to_milli(speed_m_s))

    def command_long(self, command: int, *params: float) -> None:
        p = [float(x) for x in params] + [0.0] * (7 - len(params))
        self._send(self._d.MAVLink_command_long_message(self.target_system, self.target_component, command, 0, *p[:7]))

    def set_behaviours(self, follow_wall: bool, goal_seek: bool = False, avoid: bool = True) -> None:
        self.command_long(MAV_CMD_AGNAV_SET_BEHAVIOURS, int(follow_wall), int(goal_seek), int(avoid))

    def arm(self) -> None:
        self.command_long(self._d.MAV_CMD_COMPONENT_ARM_DISARM, 1)

    def param_set(self, name: str, value: int) -> None:
        d = self._d
        self._send(d.MAVLink_param_set_message(self.target_system, self.target_component, name.encode(), float(value),
                                               d.MAV_PARAM_TYPE_INT32))

    def calib_table(self, table_id: int, pwm: list[int], value: list[int], neutral_pwm: int) -> None:
        n = len(pwm)
        pw = list(pwm) + [0] * (16 - n)
        va = list(value) + [0] * (16 - n)
        self._send(self._d.MAVLink_agnav_calib_table_message(self.target_system, self.target_component, table_id, n, pw, va,
                                                             neutral_pwm, neutral_pwm, neutral_pwm))

    def calib_request(self, table_id: int, action: int) -> None:
        """AGNAV_CALIB_REQUEST: 0 read, 1 save all tables to EEPROM, 2 load defaults."""
        self._send(self._d.MAVLink_agnav_calib_request_message(self.target_system, self.target_component, table_id, action))

    # ---- receiving -------------------------------------------------------------------------------------
    def feed(self, t_us: int, data: bytes) -> list[Any]:
        """Decode what the radio delivered (pymavlink's parser of the dialect: a frame split over two
        deliveries is completed by the next one; bad bytes come back as its bad-data messages) and update
        the state; returns the messages."""
        if not data:
            return []
        msgs = self._mav.parse_buffer(data) or []
        for m in msgs:
            self._handle(t_us, m)
        return msgs

    def _handle(self, t_us: int, m: Any) -> None:
        kind = m.get_type()
        self.rx_counts[kind] = self.rx_counts.get(kind, 0) + 1
        if kind == "AGNAV_ODOMETRY":
            o = Odometry(t_us, m.time_boot_ms, milli_to_si(m.x_mm), milli_to_si(m.y_mm), cdeg_to_rad(m.yaw_cdeg),
                         milli_to_si(m.speed_mm_s), cdeg_to_rad(m.yaw_rate_cdeg_s))
            self.odometry = o
            if self.keep_history:
                self.odometry_log.append(o)
        elif kind == "AGNAV_BEHAVIOUR_STATUS":
            s = BehaviourStatus(t_us, m.time_boot_ms, m.active_layer, m.reason, m.failsafe_flags, m.steer_cdeg, m.speed_mm_s)
            self.status = s
            if self.keep_history:
                self.status_log.append(s)
        elif kind == "AGNAV_SONAR_RING":
            f = SonarRingFrame(t_us, m.time_boot_ms, tuple(m.ranges_mm), tuple(m.status), m.seq)
            self.sonar = f
            if self.keep_history:
                self.sonar_log.append(f)
        elif kind == "HEARTBEAT":
            self.heartbeat_seen_us = t_us
        elif kind == "COMMAND_ACK":
            self.acks.append(m)
        elif kind == "SYS_STATUS":
            self.sys_status = m
        elif kind == "AGNAV_CALIB_ACK":
            self.calib_acks.append(m)
        elif kind == "PARAM_VALUE":
            pid = m.param_id if isinstance(m.param_id, str) else m.param_id.decode()
            self.params[pid] = int(round(m.param_value))
        elif kind == "STATUSTEXT":
            txt = m.text if isinstance(m.text, str) else m.text.decode(errors="replace")
            self.statustexts.append((t_us, txt.rstrip("\x00")))
